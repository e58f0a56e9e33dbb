// fogctl on a live mock bench without friction (issue 15): a run followed with stderr in a
// file (no carriage returns, a line per phase), `run watch --raw` as NDJSON, `run get`'s events
// as a table, --unit by serial, and --run N on compare.
#include "../daemon/live_bench.hpp"

#include <sys/wait.h>

#include <fstream>
#include <sstream>
#include <thread>

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

std::string fogctl_cmd(const LiveBench& bench, const std::string& args) {
  return "env -u FOGBENCH_TOKEN -u FOGCTL_PROGRESS '" + (kBin / "fogctl").string() + "' " + args + " --socket '" +
         bench.socket().string() + "'";
}

Out fogctl(const LiveBench& bench, const std::string& args, const std::string& tag = "fogctl") {
  const auto out = bench.dir / (tag + ".out"), err = bench.dir / (tag + ".err");
  const int st = std::system((fogctl_cmd(bench, args) + " >'" + out.string() + "' 2>'" + err.string() + "' </dev/null").c_str());
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, slurp(out), slurp(err)};
}

}  // namespace

TEST_CASE("e2e fogctl: a run followed into files, as NDJSON with --raw, its events as a table, --unit by serial") {
  require_sim();
  require_fogctl();
  LiveBench bench(60.0, json::object(), true);
  auto start = fogctl(bench, "run start --profile short --unit SIM-0001 --unit SIM-0002 --json");
  INFO(start.err);
  REQUIRE(start.code == 0);
  const auto run = json::parse(start.out)["run_id"].get<std::int64_t>();
  const std::string id = std::to_string(run);
  // --raw in the background, the progress in the foreground: both follow the run to its end.
  const auto raw = bench.dir / "raw.ndjson", raw_rc = bench.dir / "raw.rc";
  REQUIRE(std::system(("(" + fogctl_cmd(bench, "run watch " + id + " --raw") + " >'" + raw.string() + "' 2>/dev/null </dev/null; echo $? >'" +
                       raw_rc.string() + "') &")
                          .c_str()) == 0);
  auto watched = fogctl(bench, "run watch " + id, "watch");
  INFO(watched.err);
  CHECK(watched.code != 2);
  // stderr is a file: no redraws, a line per phase change (the short profile has five steps)
  // and the end of the run on a line of its own.
  CHECK(watched.err.find('\r') == std::string::npos);
  CHECK_THAT(watched.err, Catch::Contains("run " + id + ": completed"));
  const auto lines = std::count(watched.err.begin(), watched.err.end(), '\n');
  CHECK(lines >= 3);
  CHECK(lines < 60);  // a line a minute at most besides the phases: the run is 30 s of wall time
  for (int i = 0; i < 600 && !std::filesystem::exists(raw_rc); ++i) std::this_thread::sleep_for(100ms);
  REQUIRE(std::filesystem::exists(raw_rc));
  std::istringstream nd(slurp(raw));
  std::size_t samples = 0, events = 0;
  for (std::string l; std::getline(nd, l);) {
    const json m = json::parse(l);  // every line one JSON object
    REQUIRE(m["run_id"] == run);
    samples += m["type"] == "sample";
    events += m["type"] == "event";
  }
  CHECK(samples > 10);
  CHECK(events >= 1);

  auto got = fogctl(bench, "run get " + id);
  REQUIRE(got.code == 0);
  const auto ev = got.out.substr(got.out.find("events:"));
  CHECK_THAT(ev, Catch::Contains("state"));
  CHECK(ev.find("{\"") == std::string::npos);  // words, not raw JSON

  const auto by_serial_csv = bench.dir / "unit2.csv", by_index_csv = bench.dir / "unit1.csv";
  auto by_serial = fogctl(bench, "run export " + id + " --unit SIM-0002 -o '" + by_serial_csv.string() + "'");
  INFO(by_serial.err);
  CHECK(by_serial.code == 0);
  auto by_index = fogctl(bench, "run export " + id + " --unit 1 -o '" + by_index_csv.string() + "'");
  CHECK(by_index.code == 0);
  const std::string unit2 = slurp(by_serial_csv);
  CHECK(unit2.size() > 1000);  // the run's samples of SIM-0002
  CHECK(unit2 == slurp(by_index_csv));
  auto first = fogctl(bench, "run export " + id + " --unit SIM-0001");  // to stdout
  CHECK(first.code == 0);
  CHECK(first.out != unit2);
  auto nobody = fogctl(bench, "run export " + id + " --unit SIM-9999");
  CHECK(nobody.code == 2);
  CHECK_THAT(nobody.err, Catch::Contains("SIM-0001") && Catch::Contains("SIM-0002"));

  // compare --run N: the stored run, and the unit's current model when there is one.
  const bool has_model = fogctl(bench, "model get SIM-0001").code == 0;
  auto cmp = fogctl(bench, "compare --run " + id + " --unit SIM-0001");
  INFO(cmp.err);
  if (has_model) CHECK((cmp.code == 0 || cmp.code == 1));
  else CHECK(cmp.code == 2);
  CHECK(cmp.err.find("which runs") == std::string::npos);
}
