// fogctl report: a self-contained HTML file that renders in headless Chromium without a
// console error, draws each of its figures, and prints (PDF) with the legends' values. Fails
// when Chromium or pdftotext is absent (Debian packages chromium, poppler-utils).
#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <unistd.h>

#include "common.hpp"
#include "fogbench/model/allan.hpp"
#include "offline.hpp"
#include "table.hpp"
#include "workbench.hpp"
#include "temp_dir.hpp"

using namespace fogbench::cli;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;
using fogbench::cli::testing::slurp;

std::string chromium() {
  for (const char* c : {"chromium", "chromium-browser", "google-chrome"}) {
    const std::string cmd = std::string("command -v ") + c + " >/dev/null 2>&1";
    if (std::system(cmd.c_str()) == 0) return c;
  }
  return {};
}

// Runs headless Chromium on a file with a fresh profile; returns its exit status.
int run_chromium(const std::string& exe, const Dir& dir, const std::string& args, const std::string& html,
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
  Dir dir;
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
  // The figures: per run the profile, the drift, the residual, the residual along the lineage,
  // the ACF and the CCF of the prewhitened residual, the residual against T1 and the drift-vs-T1
  // loop and the Allan deviation (2 x 9), then the candidates and the lineage: 20 plots, each a
  // canvas; the page counts what it drew.
  const std::vector<std::string> ids{"cand", "lineage"};
  std::vector<std::string> all = ids;
  for (const char* k : {"0", "1"})
    for (const char* p : {"temp", "drift", "resid", "lres", "acf", "ccf", "rvt", "loop", "allan"}) all.push_back(std::string(p) + k);
  REQUIRE(all.size() == 20);
  CHECK(count(html, "<div class=\"plot\"") == 20);
  CHECK(d.find("data-plots=\"20\"") != std::string::npos);
  CHECK(count(d, "<canvas") == 20);
  // Each plot drew something: coloured pixels (series, not the grey grid) in its plotting area,
  // counted by the page into data-ink after each draw. A line across the plot is over 500.
  for (const auto& id : all) {
    INFO(id);
    std::smatch mm;
    REQUIRE(std::regex_search(d, mm, std::regex("<div class=\"plot\" id=\"" + id + "\" data-ink=\"([0-9]+)\"")));
    CHECK(std::stoul(mm[1].str()) > 500u);
  }
  // The lineage plot: x is the lineage step (not time), y the compensated std with its unit,
  // and each step named by its terms.
  CHECK(html.find("\"id\":\"lineage\",\"kind\":\"step\"") != std::string::npos);
  CHECK(html.find("\"xlabel\":\"lineage step\"") != std::string::npos);
  CHECK(html.find("\"ylabel\":\"compensated std, deg/h\"") != std::string::npos);
  // Console errors are logged as CONSOLE lines with "Uncaught" or "Error".
  CHECK(l.find("Uncaught") == std::string::npos);
  CHECK_FALSE(std::regex_search(l, std::regex("CONSOLE.*(Error|error)")));

  // Printed (print-to-PDF): the print stylesheet shows each plot's legend with its values
  // (uPlot's own legend shows values only under the mouse). On screen they are hidden, so
  // their text in the PDF's text layer comes from @media print.
  const std::string pdf = dir.file("report.pdf");
  REQUIRE(run_chromium(exe, dir, "--no-pdf-header-footer --print-to-pdf=" + pdf, r.output, dir.file("po"), dir.file("pe")) == 0);
  REQUIRE(fs::exists(pdf));
  if (std::system("command -v pdftotext >/dev/null 2>&1") != 0)
    FAIL("pdftotext not found (Debian package: poppler-utils): the printed report cannot be checked");
  const std::string txt = dir.file("report.txt");
  REQUIRE(std::system(("pdftotext " + pdf + " " + txt).c_str()) == 0);
  std::string printed = std::regex_replace(slurp(txt), std::regex("\\s+"), " ");
  INFO(printed.substr(0, 4000));
  CHECK(printed.find("compensated std step 0") != std::string::npos);             // the lineage plot's legend
  CHECK(printed.find("step 1: + T1^2") != std::string::npos);                     // ... naming each step's terms
  CHECK(printed.find("largest |r|") != std::string::npos);                        // ACF and CCF: their key numbers
  CHECK(printed.find("lags outside the 99% band") != std::string::npos);
  CHECK(printed.find("heating - cooling at equal T1") != std::string::npos);      // the loop
  CHECK(printed.find("correlation with T1 r =") != std::string::npos);            // the scatter
  CHECK(count(printed, "mean ") >= 20u);                                          // every time series: mean, std, ...
  // A screenshot for people (kept only if FOGBENCH_REPORT_SHOT names a path to copy it to).
  const std::string shot = dir.file("report.png");
  REQUIRE(run_chromium(exe, dir, "--hide-scrollbars --window-size=1280,2600 --screenshot=" + shot, r.output, dir.file("o"), dir.file("e")) == 0);
  REQUIRE(fs::exists(shot));
  CHECK(fs::file_size(shot) > 50000u);  // a blank page compresses to under 10 KB
  if (const char* keep = std::getenv("FOGBENCH_REPORT_SHOT")) fs::copy_file(shot, keep, fs::copy_options::overwrite_existing);
}

TEST_CASE("fogctl report: the Allan section of each run has model::allan's figures for each hold and the compensated output") {
  Dir dir;
  const std::string e1 = dir.file("e1.csv"), m = dir.file("m.json");
  {
    SimulateOptions s;
    s.profile = "exp1";
    s.output = e1;
    s.seed = 11;
    s.coil = "lumped";
    s.quiet = true;
    std::ostringstream o, e;
    REQUIRE(run_simulate(s, o, e) == kExitOk);
    FitCommandOptions f;
    f.run = e1;
    f.output = m;
    REQUIRE(run_fit(f, o, e) == kExitOk);
  }
  ReportOptions r;
  r.model = m;
  r.runs = {e1};
  r.output = dir.file("report.html");
  std::ostringstream out, err;
  REQUIRE(run_report(r, out, err) == kExitOk);
  const std::string html = slurp(r.output);
  REQUIRE(html.find("Allan deviation (IEEE Std 952 Annex C)") != std::string::npos);

  // The same series computed here with model::allan alone: each hold of at least 600 even,
  // unflagged samples, then the longest such stretch of the run compensated with the model.
  auto run = load_run(e1, {});
  REQUIRE(run.has_value());
  auto model = load_model(m);
  REQUIRE(model.has_value());
  namespace allan = fogbench::model::allan;
  std::vector<std::pair<std::string, std::vector<double>>> series;
  int hold = 0;
  for (const auto& s : allan::even_stretches(*run, 600))
    series.push_back({"hold " + std::to_string(++hold), std::vector<double>(run->gyro_dph.begin() + static_cast<std::ptrdiff_t>(s.begin),
                                                                             run->gyro_dph.begin() + static_cast<std::ptrdiff_t>(s.end))});
  REQUIRE(hold >= 2);  // exp1: holds of 10 and 20 min
  auto mu = fogbench::model::predict(*model, *run);
  REQUIRE(mu.has_value());
  fogbench::model::RunData comp = *run;
  for (std::size_t i = 0; i < comp.size(); ++i) comp.gyro_dph[i] -= (*mu)[i];
  std::optional<allan::Stretch> longest;
  for (const auto& s : allan::even_stretches(comp, 600, true))
    if (!longest || s.end - s.begin > longest->end - longest->begin) longest = s;
  REQUIRE(longest);
  series.push_back({"compensated", std::vector<double>(comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->begin),
                                                       comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->end))});

  auto cell = [](const std::optional<allan::NoiseEstimate>& e, int digits) {
    // The figure, its 1-sigma interval, then the interval's evidence: tau, EDF, share of sigma^2.
    return e ? fixed(e->value, digits) + " (" + fixed(e->ci_low, digits) + ".." + fixed(e->ci_high, digits) + ") at tau " +
                   fixed(e->from_tau_s, 0) + " s, EDF " + fixed(e->edf, 1) + ", " + fixed(100.0 * e->share, 0) + " %"
             : std::string("-");
  };
  const auto table_at = html.find("<table class=\"allan\"");
  REQUIRE(table_at != std::string::npos);
  const std::string table = html.substr(table_at, html.find("</table>", table_at) - table_at);
  std::size_t at = 0;
  bool compensated_arw = false;
  for (const auto& [what, rate] : series) {
    INFO(what);
    auto curve = allan::overlapping_adev(rate, 1.0, allan::octave_cluster_sizes(rate.size()));
    REQUIRE(curve.has_value());
    const auto t = allan::noise_terms(*curve);
    const std::string row = ">" + what + "</td>";
    at = table.find(row, at);
    REQUIRE(at != std::string::npos);
    const std::string tr = table.substr(at, table.find("</tr>", at) - at);
    INFO(tr);
    CHECK(tr.find("<td>" + std::to_string(rate.size()) + "</td>") != std::string::npos);
    CHECK(tr.find("<td>" + cell(t.arw_deg_per_sqrt_h, 5) + "</td>") != std::string::npos);
    CHECK(tr.find("<td>" + cell(t.bias_instability_dph, 4) + "</td>") != std::string::npos);
    CHECK(tr.find("<td>" + cell(t.rrw_dph_per_sqrt_h, 4) + "</td>") != std::string::npos);
    if (what == "compensated") compensated_arw = t.arw_deg_per_sqrt_h.has_value();
  }
  CHECK(compensated_arw);  // the simulated gyro's white noise shows: the -1/2 slope is read
  // The plot: log-log, the curves and both reference slopes.
  CHECK(html.find("\"id\":\"allan0\",\"kind\":\"xy\",\"log\":true") != std::string::npos);
  CHECK(html.find("\"label\":\"slope -1/2: ARW of compensated\"") != std::string::npos);
  CHECK(html.find("\"label\":\"slope +1/2") != std::string::npos);
  CHECK(html.find("\"xlabel\":\"tau, s\"") != std::string::npos);
}
