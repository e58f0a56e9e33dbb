// fogctl report: a self-contained HTML file that renders in headless Chromium without a
// console error and holds its figures. Skipped with a warning when Chromium is absent
// (Debian package: chromium).
#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <unistd.h>

#include "offline.hpp"
#include "workbench.hpp"

using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

struct ReportDir {
  fs::path path;
  ReportDir() {
    static int counter = 0;
    path = fs::temp_directory_path() / ("fogctl-report-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fs::create_directories(path);
  }
  ~ReportDir() { fs::remove_all(path); }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::string chromium() {
  for (const char* c : {"chromium", "chromium-browser", "google-chrome"}) {
    const std::string cmd = std::string("command -v ") + c + " >/dev/null 2>&1";
    if (std::system(cmd.c_str()) == 0) return c;
  }
  return {};
}

// Runs headless Chromium on a file with a fresh profile; returns its exit status.
int run_chromium(const std::string& exe, const ReportDir& dir, const std::string& args, const std::string& html,
                 const std::string& out, const std::string& err) {
  const std::string profile = dir.file("chrome-profile-" + std::to_string(std::rand()));
  const std::string cmd = "timeout 120 " + exe +
                          " --headless --no-sandbox --disable-gpu --disable-background-networking --disable-component-update"
                          " --disable-sync --no-first-run --user-data-dir=" + profile + " " + args + " file://" + html + " >" +
                          out + " 2>" + err;
  return std::system(cmd.c_str());
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST_CASE("fogctl report: self-contained HTML that renders its figures in headless Chromium") {
  ReportDir dir;
  const std::string e1 = dir.file("e1.csv"), e2 = dir.file("e2.csv"), m = dir.file("m.json"), m2 = dir.file("m2.json");
  for (auto [profile, path, seed] : {std::tuple{"exp1", e1, 5}, std::tuple{"exp2", e2, 6}}) {
    SimulateOptions s;
    s.profile = profile;
    s.output = path;
    s.seed = static_cast<std::uint64_t>(seed);
    s.effects = {"0.007*T1^2"};
    s.coil = "lumped";  // T1^2 is the one effect missing, so adding it ends the lineage
    s.quiet = true;
    std::ostringstream o, e;
    REQUIRE(run_simulate(s, o, e) == kExitOk);
  }
  {
    FitCommandOptions f;
    f.run = e1;
    f.output = m;
    std::ostringstream o, e;
    REQUIRE(run_fit(f, o, e) == kExitOk);
    FitAddOptions a;
    a.model = m;
    a.add = "T1^2";
    a.run = e1;
    a.output = m2;
    REQUIRE(run_fit_add(a, o, e) == kExitOk);
  }
  ReportOptions r;
  r.model = m2;  // a lineage of two: the lineage plot is drawn
  r.runs = {e1, e2};
  r.output = dir.file("report.html");
  std::ostringstream out, err;
  REQUIRE(run_report(r, out, err) == kExitOk);
  INFO(err.str());
  const std::string html = slurp(r.output);
  // Self-contained: the vendored uPlot inline, byte for byte, and nothing fetched.
  const std::string js = slurp(std::string(FOGBENCH_SOURCE_DIR) + "/cli/report/vendor/uPlot.iife.min.js");
  REQUIRE(!js.empty());
  CHECK(html.find(js) != std::string::npos);
  CHECK(html.find("src=\"http") == std::string::npos);
  CHECK(html.find("<link") == std::string::npos);
  CHECK(html.find("Qualification summary") != std::string::npos);
  CHECK(html.find("Lineage of the error") != std::string::npos);
  // Decimated: exp1 has 5400 samples per series, plotted with at most 3000 points.
  CHECK(html.size() < 1500u * 1024u);

  const std::string exe = chromium();
  // scripts/deps installs chromium: without it the rendering is not checked, so the test fails.
  if (exe.empty()) FAIL("chromium not found (Debian package: chromium): the report cannot be rendered");
  const std::string dom = dir.file("dom.html"), log = dir.file("chrome.log");
  REQUIRE(run_chromium(exe, dir, "--enable-logging=stderr --v=0 --dump-dom", r.output, dom, log) == 0);
  const std::string d = slurp(dom), l = slurp(log);
  INFO(l);
  // The figures: per run the profile, the drift and the residual (2 x 3), the candidates and
  // the lineage: 8 plots, each a canvas; the page counts what it drew.
  CHECK(d.find("data-plots=\"8\"") != std::string::npos);
  CHECK(count(d, "<canvas") == 8);
  // Console errors are logged as CONSOLE lines with "Uncaught" or "Error".
  CHECK(l.find("Uncaught") == std::string::npos);
  CHECK_FALSE(std::regex_search(l, std::regex("CONSOLE.*(Error|error)")));
  // A screenshot for people (kept only if FOGBENCH_REPORT_SHOT names a path to copy it to).
  const std::string shot = dir.file("report.png");
  REQUIRE(run_chromium(exe, dir, "--hide-scrollbars --window-size=1280,2600 --screenshot=" + shot, r.output, dir.file("o"), dir.file("e")) == 0);
  REQUIRE(fs::exists(shot));
  CHECK(fs::file_size(shot) > 50000u);  // a blank page compresses to under 10 KB
  if (const char* keep = std::getenv("FOGBENCH_REPORT_SHOT")) fs::copy_file(shot, keep, fs::copy_options::overwrite_existing);
}
