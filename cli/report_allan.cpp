// The report's Allan section (report_allan.hpp).
#include "report_allan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "allan.hpp"
#include "report_plots.hpp"
#include "table.hpp"
#include "html.hpp"

namespace fogbench::cli::report_html {

namespace allan = model::allan;

namespace {

const char* const kColours[] = {"#3d6fb6", "#d9822b", "#2e7d32", "#8e44ad", "#16a085", "#7f8c8d"};
constexpr const char* kCompensatedColour = "#b3261e";

std::string sig3(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// A reference line of slope `half` (-1/2 or +1/2) over [tau_lo, tau_hi] s through sigma0 at tau0.
plots::Series slope_line(const std::string& name, double half, double tau0, double sigma0, double tau_lo, double tau_hi,
                         const std::string& keys) {
  plots::Series s;
  s.name = name;
  s.stroke = "#5a6472";
  s.width = 1.5;
  s.dash = {6, 4};
  s.robust = false;
  s.keys = keys;
  for (double t : {tau_lo, tau_hi}) {
    s.x.push_back(t);
    s.y.push_back(sigma0 * std::pow(t / tau0, half));
  }
  return s;
}

}  // namespace

std::string allan_cell(const std::optional<allan::NoiseEstimate>& e, int digits) {
  if (!e) return "-";
  return fixed(e->value, digits) + " (" + fixed(e->ci_low, digits) + ".." + fixed(e->ci_high, digits) + ")";
}

// The cell with the interval's evidence: the tau it is read at, the EDF of sigma^2 there and
// the term's share of sigma^2 (what makes the 1-sigma interval as wide as it is).
static std::string allan_cell_with_evidence(const std::optional<allan::NoiseEstimate>& e, int digits) {
  if (!e) return "-";
  return allan_cell(e, digits) + " at tau " + fixed(e->from_tau_s, 0) + " s, EDF " + fixed(e->edf, 1) + ", " +
         fixed(100.0 * e->share, 0) + " %";
}

std::string allan_section(const model::Model& m, const model::RunData& run, const std::string& key, nlohmann::json& specs,
                          std::size_t max_points) {
  std::string html = "<h3>Allan deviation (IEEE Std 952 Annex C): " + html_escape(run.name) + "</h3>";
  auto series = allan_series(run, &m, kAllanMinSamples, false);
  if (!series) return html + "<p class=\"note\">No Allan deviation: " + html_escape(series.error()) + "</p>";
  if (series->empty())
    return html + "<p class=\"note\">No stretch of " + std::to_string(kAllanMinSamples) +
           " or more evenly spaced, unflagged samples in a hold or of the compensated output.</p>";

  plots::Plot p;
  p.id = "allan" + key;
  p.kind = "xy";
  p.log = true;
  p.robust = false;
  p.title = "Overlapping Allan deviation of each hold and of the compensated output: " + run.name;
  p.xlabel = "tau, s";
  p.ylabel = "Allan deviation, deg/h";
  std::string rows = "<table class=\"allan\" data-run=\"" + html_escape(run.name) +
                     "\"><tr><th>series</th><th>from, s</th><th>to, s</th><th>samples</th><th>ARW, deg/sqrt(h)</th>"
                     "<th>bias instability, deg/h</th><th>RRW, deg/h/sqrt(h)</th></tr>";
  std::vector<std::string> notes;
  // The slopes are drawn through the compensated output's estimates (else the first series'
  // that shows the term), and as bare references through its curve's ends when none does.
  const AllanSeries* ref = &series->back();
  std::optional<allan::NoiseEstimate> arw, rrw;
  std::string arw_of, rrw_of;
  double tau_lo = 0.0, tau_hi = 0.0;
  std::vector<allan::AdevPoint> ref_curve;
  std::size_t colour = 0;
  for (const auto& x : *series) {
    auto curve = allan::overlapping_adev(x.rate_dph, x.stretch.tau0_s, allan::octave_cluster_sizes(x.rate_dph.size()));
    if (!curve || curve->empty()) {
      notes.push_back(x.what + ": " + (curve ? std::string("too short for a curve") : curve.error()));
      continue;
    }
    const auto t = allan::noise_terms(*curve);
    const double from_s = run.time_s[x.stretch.begin], to_s = run.time_s[x.stretch.end - 1];
    const bool comp = x.what == "compensated";
    rows += std::string("<tr") + (comp ? " class=\"hit\"" : "") + "><td class=\"w\">" + html_escape(x.what) + "</td><td>" + fixed(from_s, 0) +
            "</td><td>" + fixed(to_s, 0) + "</td><td>" + std::to_string(x.rate_dph.size()) + "</td><td>" +
            allan_cell_with_evidence(t.arw_deg_per_sqrt_h, 5) + "</td><td>" + allan_cell_with_evidence(t.bias_instability_dph, 4) +
            "</td><td>" + allan_cell_with_evidence(t.rrw_dph_per_sqrt_h, 4) + "</td></tr>";
    for (const auto& [name, note] : {std::pair{"ARW", t.arw_note}, std::pair{"bias instability", t.bias_instability_note},
                                     std::pair{"RRW", t.rrw_note}})
      if (!note.empty()) notes.push_back(x.what + ": " + name + ": " + note);
    plots::Series s;
    s.name = x.what;
    s.stroke = comp ? kCompensatedColour : kColours[colour++ % std::size(kColours)];
    s.width = comp ? 2.2 : 1.4;
    s.points = true;
    s.robust = false;
    for (const auto& pt : *curve) {
      s.x.push_back(pt.tau_s);
      s.y.push_back(pt.adev_dph);
    }
    s.keys = "sigma(" + sig3(curve->front().tau_s) + " s) " + sig3(curve->front().adev_dph) + " deg/h, minimum " +
             sig3(std::min_element(curve->begin(), curve->end(), [](auto& a, auto& b) { return a.adev_dph < b.adev_dph; })->adev_dph) +
             " deg/h; ARW " + allan_cell(t.arw_deg_per_sqrt_h, 5) + ", B " + allan_cell(t.bias_instability_dph, 4) + ", RRW " +
             allan_cell(t.rrw_dph_per_sqrt_h, 4);
    p.series.push_back(std::move(s));
    tau_lo = tau_lo == 0.0 ? curve->front().tau_s : std::min(tau_lo, curve->front().tau_s);
    tau_hi = std::max(tau_hi, curve->back().tau_s);
    if (&x == ref) ref_curve = *curve;
    if (t.arw_deg_per_sqrt_h && (!arw || comp)) {
      arw = t.arw_deg_per_sqrt_h;
      arw_of = x.what;
    }
    if (t.rrw_dph_per_sqrt_h && (!rrw || comp)) {
      rrw = t.rrw_dph_per_sqrt_h;
      rrw_of = x.what;
    }
  }
  rows += "</table>";
  if (p.series.empty()) return html + rows;
  if (ref_curve.empty()) {  // the compensated series gave no curve: the last one that did
    const auto& last = p.series.back();
    for (std::size_t i = 0; i < last.x.size(); ++i) ref_curve.push_back({0, last.x[i], last.y[i], 0, 0, 0});
  }
  // sigma(tau) = N * 60 / sqrt(tau / 1 s) deg/h, N in deg/sqrt(h); sigma(tau) = K / 60 * sqrt(tau / 3 s), K in deg/h/sqrt(h).
  if (arw)
    p.series.push_back(slope_line("slope -1/2: ARW of " + arw_of, -0.5, 1.0, arw->value * 60.0, tau_lo, tau_hi,
                                  "angle random walk N = " + sig3(arw->value) + " deg/sqrt(h), sigma(1 s) = 60 N deg/h"));
  else
    p.series.push_back(slope_line("slope -1/2 (reference)", -0.5, ref_curve.front().tau_s, ref_curve.front().adev_dph, tau_lo, tau_hi,
                                  "reference slope -1/2 through the first point (no angle random walk read)"));
  if (rrw)
    p.series.push_back(slope_line("slope +1/2: RRW of " + rrw_of, 0.5, 3.0, rrw->value / 60.0, tau_lo, tau_hi,
                                  "rate random walk K = " + sig3(rrw->value) + " deg/h/sqrt(h), sigma(3 s) = K / 60 deg/h"));
  else
    p.series.push_back(slope_line("slope +1/2 (reference)", 0.5, ref_curve.back().tau_s, ref_curve.back().adev_dph, tau_lo, tau_hi,
                                  "reference slope +1/2 through the last point (no rate random walk read)"));
  html += plots::render(p, specs, max_points);
  html += rows;
  html += "<p class=\"note\">Overlapping Allan deviation at octave taus of each hold (evenly spaced, unflagged, at least " +
          std::to_string(kAllanMinSamples) +
          " samples) and of the longest such stretch of the output compensated with the model. sigma^2(tau) = A/tau + F + C tau "
          "(white, flicker and random-walk rate) is fitted to the whole curve; each figure is read at one tau where its term is "
          "at least half of sigma^2 (never the longest tau alone), the one with the narrowest interval. In brackets: its "
          "1-sigma interval from the chi-square of sigma^2 at that tau (equivalent degrees of freedom of the noise mix there, "
          "IEEE 952 Annex C, NIST SP 1065), then the tau, the EDF and the term's share of sigma^2 at that tau. "
          "fogctl allan prints the same figures.</p>";
  if (!notes.empty()) {
    html += "<ul class=\"note\">";
    for (const auto& n : notes) html += "<li>" + html_escape(n) + "</li>";
    html += "</ul>";
  }
  return html;
}

}  // namespace fogbench::cli::report_html
