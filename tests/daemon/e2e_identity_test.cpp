// Issue 13 through the built executables on the live mock bench: a run's identity recorded by
// fogbenchd (station.id, `run start --operator`, software, hashes, power-on), shown by `fogctl
// run get` and written atop `fogctl run export`'s CSV where the importer reads it back; and
// `fogctl coefficients SERIAL`, the serial's current model fetched from the daemon, giving the
// same output as the model's file.
#include "live_bench.hpp"

#include <sys/wait.h>

#include "fogbench/model/sha256.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/identity.hpp"

using namespace fogbench;
using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

struct Out {
  int code = -1;
  std::string out, err;
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Out fogctl(const LiveBench& bench, const std::string& args) {
  const auto out = bench.dir / "fogctl.out", err = bench.dir / "fogctl.err";
  const std::string cmd = "cd '" + bench.dir.string() + "' && env -u FOGBENCH_TOKEN '" + (kBin / "fogctl").string() +
                          "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int st = std::system(cmd.c_str());
  Out o;
  o.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  o.out = slurp(out);
  o.err = slurp(err);
  return o;
}

std::string sock(const LiveBench& bench) { return "--socket '" + bench.socket().string() + "'"; }

}  // namespace

TEST_CASE("e2e identity: run start --operator, run get, the CSV export's identity read back, coefficients SERIAL") {
  require_sim();
  require_fogctl();
  LiveBench bench(100.0, {{"station", {{"id", "line-2"}}}}, true);
  INFO("test dir " << bench.dir);

  // A bad operator: exit 2 naming the field, nothing started (checked by fogctl, and by the daemon).
  auto bad = fogctl(bench, "run start " + sock(bench) + " --profile short --unit SIM-0001 --operator \"$(printf 'Ada\\001')\"");
  CHECK(bad.code == 2);
  CHECK(bad.err.find("operator") != std::string::npos);
  LineClient c(bench.socket());
  REQUIRE(c.ok());
  json raw = c.call({{"cmd", "run.start"}, {"profile", "short"}, {"units", {"SIM-0001"}}, {"operator", std::string(65, 'x')}});
  REQUIRE(raw.contains("error"));
  CHECK(raw["error"]["code"] == "bad_request");
  CHECK(raw["error"]["message"].get<std::string>().starts_with("operator:"));
  CHECK(c.call({{"cmd", "run.list"}})["result"]["runs"].empty());

  auto start = fogctl(bench, "run start " + sock(bench) + " --profile short --unit SIM-0001 --operator 'Ada Lovelace' --json");
  INFO(start.err);
  REQUIRE(start.code == 0);
  const auto run = json::parse(start.out)["run_id"].get<std::int64_t>();
  json done = bench.wait_state(c, run, {"completed", "aborted", "failed", "interrupted"}, 600s);
  REQUIRE(done.contains("result"));
  REQUIRE(done["result"]["run"]["state"] == "completed");
  REQUIRE(done["result"]["models"].size() == 1);

  // run get --json: the identity, its hashes those of what the run stored.
  auto gj = fogctl(bench, "run get " + std::to_string(run) + " --json " + sock(bench));
  REQUIRE(gj.code == 0);
  const json g = json::parse(gj.out);
  const json& id = g["identity"];
  CHECK(id["station_id"] == "line-2");
  CHECK(id["operator"] == "Ada Lovelace");
  CHECK(id["operator_source"] == "client");
  CHECK(id["git_hash"].get<std::string>().size() >= 7);
  CHECK(id["profile_sha256"] == model::sha256_hex(g["profile_text"].get<std::string>()));
  CHECK(id["config_sha256"] == model::sha256_hex(g["config"].dump()));
  REQUIRE(id["units"].size() == 1);
  CHECK(id["units"][0]["serial"] == "SIM-0001");
  // The table says the same.
  auto gt = fogctl(bench, "run get " + std::to_string(run) + " " + sock(bench));
  REQUIRE(gt.code == 0);
  CHECK(gt.out.find("station line-2, operator Ada Lovelace (client)") != std::string::npos);
  CHECK(gt.out.find("profile sha256 " + id["profile_sha256"].get<std::string>()) != std::string::npos);

  // The export's comments read back to the same identity, and the data still parses.
  auto ex = fogctl(bench, "run export " + std::to_string(run) + " -o run.csv " + sock(bench));
  REQUIRE(ex.code == 0);
  const std::string csv = slurp(bench.dir / "run.csv");
  CHECK(csv.starts_with("# run: " + std::to_string(run) + "\n"));
  auto back = storage::identity_from_fields(storage::read_comment_fields(csv));
  REQUIRE(back.has_value());
  CHECK(back->station_id == "line-2");
  CHECK(back->operator_name == "Ada Lovelace");
  CHECK(back->config_sha256 == id["config_sha256"]);
  CHECK(back->profile_sha256 == id["profile_sha256"]);
  CHECK(back->git_hash == id["git_hash"]);
  REQUIRE(back->units.size() == 1);
  CHECK(back->units[0].serial == "SIM-0001");
  CHECK(storage::parse_csv(csv, {}).has_value());

  // coefficients SERIAL: the current model from the daemon, the same output as its file.
  REQUIRE(fogctl(bench, "model get SIM-0001 -o model.json " + sock(bench)).code == 0);
  auto from_file = fogctl(bench, "coefficients model.json --format c");
  REQUIRE(from_file.code == 0);
  auto from_serial = fogctl(bench, "coefficients SIM-0001 --format c " + sock(bench));
  INFO(from_serial.err);
  REQUIRE(from_serial.code == 0);
  CHECK(from_serial.out == from_file.out);
  CHECK(from_serial.out.find("fogcomp") != std::string::npos);
  // A serial without a model: exit 2 naming it.
  auto none = fogctl(bench, "coefficients SIM-0002 " + sock(bench));
  CHECK(none.code == 2);
  CHECK(none.err.find("SIM-0002") != std::string::npos);

  // The certificate: a verify run of SIM-0001 issues it; fogctl cert writes it as HTML and
  // JSON, --check finds both valid (signed with the station key, which the daemon gives) and
  // issued by the store; one digit altered: exit 1.
  auto vstart = fogctl(bench, "run start " + sock(bench) + " --profile short --unit SIM-0001 --purpose verify --json");
  REQUIRE(vstart.code == 0);
  const auto vrun = json::parse(vstart.out)["run_id"].get<std::int64_t>();
  json vdone = bench.wait_state(c, vrun, {"completed", "aborted", "failed", "interrupted"}, 600s);
  REQUIRE(vdone["result"]["run"]["state"] == "completed");
  REQUIRE(vdone["result"]["verifications"].size() == 1);
  auto html = fogctl(bench, "cert SIM-0001 -o cert.html " + sock(bench));
  INFO(html.err);
  REQUIRE(html.code == 0);
  auto cj = fogctl(bench, "cert SIM-0001 -o cert.json " + sock(bench));
  REQUIRE(cj.code == 0);
  const std::string page = slurp(bench.dir / "cert.html");
  CHECK(page.find("@page") != std::string::npos);
  CHECK(page.find("application/json") != std::string::npos);
  const json cert = json::parse(slurp(bench.dir / "cert.json"));
  CHECK(cert["serial"] == "SIM-0001");
  CHECK(cert["runs"].size() == 2);
  auto ok_html = fogctl(bench, "cert --check cert.html " + sock(bench));
  CHECK(ok_html.code == 0);
  CHECK(ok_html.out.find("VALID") != std::string::npos);
  CHECK(ok_html.out.find("visible page matches") != std::string::npos);
  CHECK(ok_html.out.find("issued by the station's store") != std::string::npos);
  auto ok_json = fogctl(bench, "cert --check cert.json --json " + sock(bench));
  REQUIRE(ok_json.code == 0);
  CHECK(json::parse(ok_json.out)["known_to_store"] == true);
  // Alter one digit of the first coefficient's value in the JSON text.
  std::string text = slurp(bench.dir / "cert.json");
  const auto at = text.find("\"value\":", text.find("\"coefficients\""));
  REQUIRE(at != std::string::npos);
  auto digit = text.find_first_of("0123456789", at);
  text[digit] = text[digit] == '9' ? '8' : static_cast<char>(text[digit] + 1);
  std::ofstream(bench.dir / "edited.json") << text;
  auto altered = fogctl(bench, "cert --check edited.json " + sock(bench));
  CHECK(altered.code == 1);
  CHECK(altered.out.find("ALTERED") != std::string::npos);
  CHECK(fogctl(bench, "cert --check nothing-here.json").code == 2);
  auto nomodel = fogctl(bench, "cert SIM-0002 " + sock(bench));
  CHECK(nomodel.code == 2);
  CHECK(nomodel.err.find("SIM-0002") != std::string::npos);

  // The station key (issue 24): made at the first start beside the store, 0600, its public key
  // beside it and from fogctl cert --public-key; with it a certificate checks offline.
  const auto key_file = bench.dir / "station.key";
  REQUIRE(std::filesystem::exists(key_file));
  CHECK((std::filesystem::status(key_file).permissions() & std::filesystem::perms::all) == std::filesystem::perms(0600));
  REQUIRE(std::filesystem::exists(bench.dir / "station.pub"));
  auto pub = fogctl(bench, "cert --public-key -o exported.pub " + sock(bench));
  INFO(pub.err);
  REQUIRE(pub.code == 0);
  CHECK(slurp(bench.dir / "exported.pub") == slurp(bench.dir / "station.pub"));
  CHECK(pub.err.find(cert["signed_by"]["key_id"].get<std::string>()) != std::string::npos);
  const std::string offline = " --key exported.pub --socket " + (bench.dir / "no-daemon.sock").string();
  auto off_html = fogctl(bench, "cert --check cert.html" + offline);
  CHECK(off_html.code == 0);
  CHECK(off_html.out.find("not asked") != std::string::npos);
  CHECK(fogctl(bench, "cert --check cert.json" + offline).code == 0);
  // A forgery: the verdict changed, its SHA-256 recomputed: a bad signature (it was "intact").
  json forged = cert;
  forged["verdict"] = forged["verdict"] == "pass" ? "not passed" : "pass";
  forged["sha256"] = signing::content_sha256(forged);
  std::ofstream(bench.dir / "forged.json") << forged.dump();
  auto bad_sig = fogctl(bench, "cert --check forged.json" + offline);
  CHECK(bad_sig.code == 1);
  CHECK(bad_sig.out.find("BAD SIGNATURE") != std::string::npos);
  // No key and no daemon: cannot tell.
  CHECK(fogctl(bench, "cert --check cert.json --socket " + (bench.dir / "no-daemon.sock").string()).code == 2);

  // A key file others may read: fogbenchd refuses to start, exit 2 naming it.
  CHECK(bench.daemon->stop(30s) == 0);
  std::filesystem::permissions(key_file, std::filesystem::perms(0644));
  Process again({(kBin / "fogbenchd").string(), "--config", (bench.dir / "fogbenchd.json").string(), "--time-scale",
                 std::to_string(bench.time_scale)},
                bench.dir / "fogbenchd-loose-key.log");
  CHECK(again.wait(60s) == 2);
  const std::string log = slurp(bench.dir / "fogbenchd-loose-key.log");
  INFO(log);
  CHECK(log.find(key_file.string()) != std::string::npos);
  CHECK(log.find("0644") != std::string::npos);
}
