// fogctl cert --check without a daemon: a certificate (JSON or the printable HTML that embeds
// it) whose SHA-256 matches its canonical JSON is intact (exit 0); one digit changed is altered
// (exit 1); a file without a certificate is unreadable (exit 2). The HTML's print stylesheet
// fits A4 and Letter.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "cert.hpp"
#include "fogbench/model/sha256.hpp"

using namespace fogbench;
using namespace fogbench::cli;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

struct Dir {
  fs::path path = fs::temp_directory_path() / ("fogctl-cert-" + std::to_string(::getpid()));
  Dir() { fs::create_directories(path); }
  ~Dir() { fs::remove_all(path); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path / name, std::ios::binary) << text;
    return (path / name).string();
  }
};

// A certificate of the daemon's shape (certificate.hpp), hashed as the daemon hashes it.
json sample_cert() {
  json c = {{"format", "fogbench.certificate"}, {"format_version", 1}, {"serial", "FOG-1"}, {"station_id", "line </script> 2"},
            {"issued_at", "2026-11-25T09:00:00Z"}, {"verdict", "pass"},
            {"model", {{"id", 1}, {"version", 1}, {"method", "paper"}, {"terms", "d(T1)@40 + grad@40"}, {"sigma_a_dph", 0.05},
                       {"coefficients", {{{"term", "mu0"}, {"value", -8.0123}, {"sigma", 0.01}, {"unit", "deg/h"}, {"lag_s", 0}}}}}},
            {"verdicts", json::array()}, {"runs", json::array()}, {"allan", json::array()},
            {"software", {{"version", "0.1.0"}, {"git_hash", "abc"}}}};
  c["sha256"] = model::sha256_hex(c.dump());
  return c;
}

struct Result {
  int code;
  std::string out, err;
};
Result check(const std::string& file) {
  CertOptions o;
  o.check = file;
  o.daemon.socket = "/nonexistent/fogbench-test.sock";  // no daemon: the store is not asked
  std::ostringstream out, err;
  const int code = run_cert(o, out, err);
  return {code, out.str(), err.str()};
}

}  // namespace

TEST_CASE("fogctl cert --check: intact, altered by one digit, unreadable", "[cli][cert]") {
  Dir d;
  const json c = sample_cert();
  auto ok = check(d.write("c.json", c.dump()));
  CHECK(ok.code == 0);
  CHECK(ok.out.find("intact") != std::string::npos);
  CHECK(ok.out.find("not asked") != std::string::npos);

  std::string text = c.dump();
  const auto at = text.find("-8.0123");
  REQUIRE(at != std::string::npos);
  text[at + 6] = '4';  // -8.0124
  auto bad = check(d.write("altered.json", text));
  CHECK(bad.code == 1);
  CHECK(bad.out.find("ALTERED") != std::string::npos);

  // Whitespace does not matter (the hash is over the canonical form), content does.
  CHECK(check(d.write("pretty.json", c.dump(2))).code == 0);

  CHECK(check(d.write("empty.json", "")).code == 2);
  CHECK(check(d.write("other.json", R"({"a":1})")).code == 2);
  CHECK(check(d.write("nohash.json", R"({"format":"fogbench.certificate"})")).code == 2);
  CHECK(check((d.path / "missing.json").string()).code == 2);
}

TEST_CASE("fogctl cert: the HTML embeds the canonical JSON, survives </script> in a value, and prints on A4 and Letter", "[cli][cert]") {
  Dir d;
  const json c = sample_cert();
  const std::string html = certificate_html(c);
  CHECK(html.find("@page") != std::string::npos);
  CHECK(html.find("max-width:170mm") != std::string::npos);
  CHECK(html.find("@media print") != std::string::npos);
  // The value's "</script>" is kept out of the page's markup.
  CHECK(html.find("line </script> 2") == std::string::npos);
  auto back = certificate_from_text(html);
  REQUIRE(back.has_value());
  CHECK(*back == c);
  CHECK(check(d.write("c.html", html)).code == 0);

  // The visible table shows the value too; the check is over the embedded JSON.
  std::string edited = html;
  const auto at = edited.find("-8.0123", edited.find("application/json"));
  REQUIRE(at != std::string::npos);
  edited[at + 3] = '9';
  CHECK(check(d.write("edited.html", edited)).code == 1);
  CHECK(check(d.write("plain.html", "<html><body>no certificate</body></html>")).code == 2);
  CHECK(check(d.write("cut.html", html.substr(0, html.find("</script>")))).code == 2);
}
