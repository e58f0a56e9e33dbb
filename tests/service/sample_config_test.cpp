// The sample configuration (systemd/fogbenchd.json.example.in, installed as
// share/doc/fogbench/fogbenchd.json.example) as fogbenchd --check-config reads it: valid as
// shipped, with its `web` section off (loopback, a token file beside the configuration), and
// valid once the panel is switched on and the token file made; the web section's errors name
// the field (docs/web.md, docs/daemon.md).
#include "../daemon/live_bench.hpp"

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

using namespace fogbench::daemon::test;
using namespace fogbench::daemon::test::live;

namespace {

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (auto at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
}

// The sample as an install writes it, its data directory the source tree's.
json sample() {
  const std::filesystem::path src = FOGBENCH_SOURCE_DIR;
  std::string text = read_all(src / "systemd/fogbenchd.json.example.in");
  replace_all(text, "@CMAKE_INSTALL_FULL_DATADIR@/fogbench/profiles", (src / "profiles").string());
  replace_all(text, "@CMAKE_INSTALL_FULL_DATADIR@/fogbench/maps", (src / "drivers/maps").string());
  REQUIRE(text.find('@') == std::string::npos);  // every placeholder is one of those
  return json::parse(text);
}

struct Check {
  int status;
  std::string out;
};

Check check_config(const std::filesystem::path& dir, const json& config) {
  std::ofstream(dir / "fogbenchd.json") << config.dump(2);
  const std::string cmd = "'" + (kBin / "fogbenchd").string() + "' --check-config '" + (dir / "fogbenchd.json").string() +
                          "' >'" + (dir / "out").string() + "' 2>&1";
  const int s = std::system(cmd.c_str());
  return {WIFEXITED(s) ? WEXITSTATUS(s) : -1, read_all(dir / "out")};
}

}  // namespace

TEST_CASE("the sample configuration's web section: off and loopback as shipped, --check-config accepts it, and on with its token file") {
  REQUIRE(std::filesystem::exists(kBin / "fogbenchd"));
  char tmpl[] = "/tmp/fogbench-sample-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  const json shipped = sample();

  // As shipped: the panel off, on loopback, its control token in a file beside the configuration.
  REQUIRE(shipped.contains("web"));
  CHECK(shipped["web"]["enabled"] == false);
  CHECK(shipped["web"]["listen"].get<std::string>().starts_with("127.0.0.1:"));
  CHECK(shipped["web"]["token_file"] == "web.token");
  CHECK_FALSE(shipped["web"].contains("allow_remote"));
  auto r = check_config(dir, shipped);
  INFO(r.out);
  CHECK(r.status == 0);  // the token file is not read while the panel is off: it need not exist yet

  // Switched on: the token file must exist and hold a token of 16 characters or more.
  json on = shipped;
  on["web"]["enabled"] = true;
  r = check_config(dir, on);
  CHECK(r.status == 2);
  CHECK_THAT(r.out, Catch::Contains("web.token_file (line ") && Catch::Contains("): cannot be read") && Catch::Contains("web.token"));
  std::ofstream(dir / "web.token") << "short\n";
  r = check_config(dir, on);
  CHECK(r.status == 2);
  CHECK_THAT(r.out, Catch::Contains("web.token_file (line ") && Catch::Contains("): the token is shorter than 16 characters"));
  std::ofstream(dir / "web.token") << "0123456789abcdef0123\n";
  r = check_config(dir, on);
  INFO(r.out);
  CHECK(r.status == 0);

  // Off is still checked: a non-loopback address without allow_remote, an unknown field.
  json remote = shipped;
  remote["web"]["listen"] = "0.0.0.0:8080";
  r = check_config(dir, remote);
  CHECK(r.status == 2);
  CHECK_THAT(r.out, Catch::Contains("web.listen (line ") && Catch::Contains("): 0.0.0.0 is not a loopback address"));
  json typo = shipped;
  typo["web"]["enable"] = true;
  r = check_config(dir, typo);
  CHECK(r.status == 2);
  CHECK_THAT(r.out, Catch::Contains("web.enable (line ") && Catch::Contains("): unknown field"));
  json bad = shipped;
  bad["web"]["enabled"] = "yes";
  CHECK_THAT(check_config(dir, bad).out, Catch::Contains("web.enabled (line ") && Catch::Contains("): expected true or false"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("the web side's token_file is its control token, apart from socket.tcp's, and enabled false serves nothing") {
  require_sim();
  char tmpl[] = "/tmp/fogbench-webtok-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  std::ofstream(dir / "web.token") << "web-only-token-0123456789\n";
  {
    LiveBench bench(20.0, {{"web", {{"listen", "127.0.0.1:0"}, {"token_file", (dir / "web.token").string()}}}});
    REQUIRE(bench.ready_daemon["web_port"].is_number_integer());
    const auto port = bench.ready_daemon["web_port"].get<std::uint16_t>();
    // A control request over POST /api: refused without the token, taken with the file's.
    auto post = [&](const json& body) {
      LineClient h(port);
      REQUIRE(h.ok());
      const std::string b = body.dump();
      h.send_raw("POST /api HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: " + std::to_string(b.size()) +
                 "\r\n\r\n" + b);
      std::string all;
      while (auto l = h.line(10s)) all += *l + "\n";
      return all;
    };
    CHECK_THAT(post({{"id", 1}, {"cmd", "run.abort"}, {"reason", "x"}}), Catch::StartsWith("HTTP/1.1 403"));
    CHECK_THAT(post({{"id", 2}, {"cmd", "run.abort"}, {"reason", "x"}, {"token", "web-only-token-0123456789"}}),
               !Catch::StartsWith("HTTP/1.1 403"));
  }
  {
    LiveBench bench(20.0, {{"web", {{"listen", "127.0.0.1:0"}, {"enabled", false}}}});
    CHECK(bench.ready_daemon["web_port"].is_null());
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("serial devices the shipped unit does not allow are named by --check-config, and --device-allow prints their drop-in") {
  REQUIRE(std::filesystem::exists(kBin / "fogbenchd"));
  char tmpl[] = "/tmp/fogbench-devallow-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  json c = sample();
  // The sample reaches its chamber and module over TCP: nothing to allow.
  auto tcp = check_config(dir, c);
  CHECK(tcp.status == 0);
  CHECK(tcp.out.find("note:") == std::string::npos);
  const auto dropin_of = [&](const json& config) {
    std::ofstream(dir / "fogbenchd.json") << config.dump(2);
    const std::string cmd = "'" + (kBin / "fogbenchd").string() + "' --device-allow '" + (dir / "fogbenchd.json").string() +
                            "' >'" + (dir / "out").string() + "' 2>&1";
    const int s = std::system(cmd.c_str());
    return Check{WIFEXITED(s) ? WEXITSTATUS(s) : -1, read_all(dir / "out")};
  };
  auto none = dropin_of(c);
  CHECK(none.status == 0);
  CHECK_THAT(none.out, Catch::Contains("names no serial device"));
  // The chamber over Modbus RTU on a USB-ACM adapter, the module on a ttyUSB one.
  c["drivers"]["chamber"]["modbus"] = {{"transport", "rtu"}, {"device", "/dev/ttyACM0"}, {"baud", 9600}, {"unit_id", 1}};
  c["drivers"]["thermistors"]["modbus"] = {{"transport", "rtu"}, {"device", "/dev/ttyUSB3"}, {"unit_id", 2}};
  auto rtu = check_config(dir, c);
  INFO(rtu.out);
  CHECK(rtu.status == 0);
  CHECK_THAT(rtu.out, Catch::Contains("note: drivers.chamber.modbus.device /dev/ttyACM0: the shipped unit allows only /dev/ttyUSB*"));
  CHECK(rtu.out.find("/dev/ttyUSB3") == std::string::npos);  // allowed as shipped: not named
  auto dropin = dropin_of(c);
  INFO(dropin.out);
  CHECK(dropin.status == 0);
  CHECK_THAT(dropin.out, Catch::Contains("[Service]\nDeviceAllow=/dev/ttyACM0 rw\nDeviceAllow=/dev/ttyUSB3 rw\n"));
  // A broken file: exit 2 naming the key, no drop-in.
  c["drivers"]["chamber"]["modbus"]["device"] = "";
  auto bad = dropin_of(c);
  CHECK(bad.status == 2);
  CHECK_THAT(bad.out, Catch::Contains("drivers.chamber.modbus.device"));
  CHECK(bad.out.find("[Service]") == std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("fogbenchd --check-config names a store folder on a read-only filesystem (a bind mount made read-only in a mount namespace of its own)") {
  REQUIRE(std::filesystem::exists(kBin / "fogbenchd"));
  char tmpl[] = "/tmp/fogbench-rofs-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  const std::filesystem::path ro = dir / "ro";
  std::filesystem::create_directories(ro);
  json config = sample();
  config["storage"]["path"] = (ro / "fogbench.db").string();
  auto writable = check_config(dir, config);
  INFO(writable.out);
  CHECK(writable.status == 0);  // the same folder, writable: valid
  // The folder made read-only for this one command: unshare gives it a mount namespace, so the
  // bind mount ends with it. Without the rights or the tools (not root, no unshare): SKIPPED.
  const std::string cmd = "unshare -m sh -c \"mount --bind '" + ro.string() + "' '" + ro.string() + "' && mount -o remount,bind,ro '" +
                          ro.string() + "' || exit 77; exec '" + (kBin / "fogbenchd").string() + "' --check-config '" +
                          (dir / "fogbenchd.json").string() + "'\" >'" + (dir / "out").string() + "' 2>&1";
  const int s = std::system(cmd.c_str());
  const int status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  const std::string out = read_all(dir / "out");
  if (status == 77 || (status != 0 && status != 2)) {
    std::cerr << "SKIPPED: cannot make a read-only bind mount here (root and util-linux's unshare are needed): " << out << "\n";
    std::filesystem::remove_all(dir);
    std::exit(77);
  }
  INFO(out);
  CHECK(status == 2);
  CHECK_THAT(out, Catch::Contains("storage.path (line ") && Catch::Contains(ro.string() + " (the folder of fogbench.db) is on a read-only filesystem"));
  std::filesystem::remove_all(dir);
}
