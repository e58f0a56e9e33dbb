// fogctl report: one self-contained HTML file (opens offline) with the temperature profile,
// measured against predicted drift, the residual with failing intervals shaded, the residual
// against the top candidates, the diagnosis, the lineage of the error and a qualification
// summary in the terms of IEEE Std 952. Plots are drawn by the vendored uPlot, inline.
#include <cctype>
#include <map>
#include <cmath>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>

#include "fogbench/model/noise.hpp"
#include "fogbench/model/workbench.hpp"
#include "progress.hpp"
#include "report_plots.hpp"
#include "report_allan.hpp"
#include "report_runs.hpp"
#include "report_scale_factor.hpp"
#include "scale_factor.hpp"
#include "run_identity.hpp"
#include "table.hpp"
#include "workbench.hpp"
#include "html.hpp"

namespace fogbench::cli {
namespace vendor {
extern const char* const kUplotVersion;
extern const char* const kUplotJs;
extern const char* const kUplotCss;
}  // namespace vendor

namespace wb = model::workbench;
using nlohmann::json;

namespace {

// JSON inside a <script>: "</" would end the script element.
std::string script_json(const json& j) {
  std::string s = j.dump();
  std::string o;
  o.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<' && i + 1 < s.size() && s[i + 1] == '/') o += "<\\";
    else o += s[i];
  }
  return o;
}


const char* const kColours[] = {"#3d6fb6", "#d9822b", "#2e7d32", "#8e44ad", "#b3261e", "#16a085"};



// The candidate's fitted contribution to the drift on a run: coef * term(t - lag), demeaned.
std::vector<double> contribution(const wb::Candidate& c, const model::RunData& run, double tref_c) {
  auto t = model::parse_term(c.expr);
  auto s = model::run_signals(run, tref_c);
  if (!t || !s) return {};
  auto x = model::evaluate(*t->expr, s->view());
  if (!x) return {};
  const std::size_t n = x->size(), lag = static_cast<std::size_t>(c.lag_s);
  std::vector<double> y(n);
  double m = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    y[i] = c.coef * (*x)[i >= lag ? i - lag : 0];
    m += y[i];
  }
  for (double& v : y) v -= m / static_cast<double>(n);
  return y;
}

constexpr const char* kStyle = R"css(
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:24px auto;max-width:1180px;color:#1d2430;padding:0 16px}
h1{font-size:1.5em;margin-bottom:4px}h2{font-size:1.2em;margin-top:32px;border-bottom:1px solid #d0d6de;padding-bottom:4px}
h3{font-size:1.02em;margin:18px 0 6px}.sub{color:#5a6472}
table{border-collapse:collapse;margin:8px 0 12px;font-size:.88em}th,td{padding:3px 9px;border-bottom:1px solid #e3e7ec;text-align:right}
th{background:#f3f5f8;text-align:center}td:first-child,th:first-child{text-align:left}
td.w{text-align:left}tr.hit td{background:#fff1e6;font-weight:600}tr.fail td{color:#b3261e}
.verdict{display:inline-block;padding:4px 12px;border-radius:4px;font-weight:700;color:#fff}
.pass{background:#2e7d32}.failv{background:#b3261e}.note{color:#5a6472;font-size:.88em;max-width:1000px}
.plot{margin:6px 0 14px}.summary{background:#f3f5f8;border-left:4px solid #3d6fb6;padding:8px 12px;max-width:1100px}
)css";


// Who, where and with what each run was recorded: the identity comments atop its CSV (a
// fogctl run export), one line per run; nothing for a file without them.
std::string identity_header(const std::vector<std::string>& paths) {
  std::string html;
  for (const auto& p : paths) {
    const auto fields = csv_file_identity(p);
    auto get = [&](const char* key) {
      for (const auto& [k, v] : fields)
        if (k == key) return v.empty() ? std::string("-") : v;
      return std::string("-");
    };
    if (get("software_version") == "-") continue;
    html += "<div class=\"sub\">" + html_escape(p) + ": run " + html_escape(get("run")) + " of " + html_escape(get("serial")) + ", station " +
            html_escape(get("station_id")) + ", operator " + html_escape(get("operator")) + ", fogbench " + html_escape(get("software_version")) +
            " (" + html_escape(get("git_hash").substr(0, 12)) + "), profile " + html_escape(get("profile")) + " (sha256 " +
            html_escape(get("profile_sha256").substr(0, 12)) + "), config sha256 " + html_escape(get("config_sha256").substr(0, 12)) +
            ", powered on " + html_escape(get("powered_on_at")) + "</div>";
  }
  return html;
}

// The serials' verdicts as the station decided them (the `verdict` comments of a run export):
// the one verdict, shown before this report's own analysis so the two are never confused.
std::string station_verdicts(const std::vector<std::string>& paths) {
  std::string html;
  for (const auto& p : paths) {
    std::map<std::string, std::string> f;
    for (const auto& [k, v] : csv_file_identity(p)) f[k] = v;
    if (!f.contains("verdict")) continue;
    const std::string v = f["verdict"];
    std::string shown = v;
    for (char& ch : shown) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    html += "<p><b>The serial's verdict</b> (" + html_escape(f["serial"]) + ", run " + html_escape(f["run"]) +
            ", recorded by the station): <span class=\"verdict " + std::string(v == "pass" ? "pass" : "failv") + "\">" +
            html_escape(shown) + "</span> decided by " + html_escape(f["verdict_by"]) + " on " + html_escape(f["verdict_decided_at"]) +
            " (<code>fogctl cert " + html_escape(f["serial"]) + "</code>)" +
            // A three-axis unit's verdict is the worst of its axes': each axis' own.
            (f.contains("verdict_axes") ? ", by axis: " + html_escape(f["verdict_axes"]) : std::string()) + "</p>";
  }
  if (!html.empty())
    html += "<p class=\"note\">The qualification below is this report's analysis of these files (its threshold, the "
            "runs given), not the serial's verdict: the verdict above is the one the certificate and the plant carry.</p>";
  return html;
}

}  // namespace

int run_report(const ReportOptions& o, std::ostream& out, std::ostream& err) {
  if (o.model.empty() || o.runs.empty()) {  // both optional on the command line, with --run N
    err << "fogctl report: " << (o.model.empty() ? "--model MODEL.json is required (or --run N: the unit's current model)" : "which runs? give CSV files, or --run N")
        << "\n";
    return kExitError;
  }
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl report: " << m.error() << "\n";
    return kExitError;
  }
  if (!(o.threshold > 0.0 && o.threshold < 1.0)) {
    err << "fogctl report: --threshold must be between 0 and 1 (a ratio of std), got " << o.threshold << "\n";
    return kExitError;
  }
  // Progress on stderr (issue 28: a report on a 3-day run took 122 s in silence): a line per
  // stage in a file or a pipe, one line redrawn on a terminal.
  Progress progress(err, progress_redraws());
  progress.set_width(progress_width());
  std::vector<model::RunData> runs;
  for (const auto& p : o.runs) {
    progress.update("read " + p, "report: reading " + display_name(p) + " (" + std::to_string(runs.size() + 1) + " of " +
                                     std::to_string(o.runs.size()) + ")");
    auto r = load_run(p, with_model_axis(o.input, *m));  // the model's axis of a three-axis run
    if (!r) {
      err << "fogctl report: " << r.error() << "\n";
      return kExitError;
    }
    runs.push_back(std::move(*r));
  }
  // The scale factor's rate sequence is read before the long analysis, so a bad file fails at once.
  std::optional<model::sf::Result> sfr;
  if (!o.scale_factor.empty()) {
    auto f = fit_rate_file(o.scale_factor, model::sf::Options{});
    if (!f) {
      err << "fogctl report: --scale-factor " << f.error() << "\n";
      return kExitError;
    }
    sfr = std::move(*f);
  }
  const std::span<const model::RunData> held = std::span<const model::RunData>(runs).subspan(1);
  wb::DiagnoseOptions dopt;
  dopt.threads = 0;  // the candidates on both cores: the same answer, sooner
  std::size_t samples = 0;
  for (const auto& r : runs) samples += r.time_s.size();
  progress.update("diagnose", "report: diagnose, the model refitted on " + runs.front().name + " and its candidates tried (" +
                                  std::to_string(samples) + " samples in " + std::to_string(runs.size()) + " runs)");
  auto d = wb::diagnose(*m, runs.front(), held, dopt);
  if (!d) {
    err << "fogctl report: " << d.error().message << "\n";
    return kExitError;
  }
  // Every run but the first is independent of the fit (std::vector<bool> is not contiguous).
  const std::unique_ptr<bool[]> held_flags(new bool[runs.size()]);
  for (std::size_t i = 0; i < runs.size(); ++i) held_flags[i] = i > 0;
  const wb::Qualification q = wb::qualify(*m, runs, std::span<const bool>(held_flags.get(), runs.size()), o.threshold);
  progress.update("plots", "report: Table 1, the lineage and the plots");
  const wb::Lineage lin = wb::lineage(*m, runs);

  json specs = json::array();  // the plots, drawn by plots::kPlotScript
  std::string body;
  body += "<h1>fogbench report: model " + html_escape(m->terms_string()) + "</h1>";
  body += "<div class=\"sub\">" + html_escape(display_name(o.model)) + " (" + std::string(to_string(m->method)) + " method, fitted on " +
          html_escape(m->fitted_on.name) + (m->created_at.empty() ? "" : ", " + html_escape(m->created_at)) + "); runs: ";
  for (std::size_t i = 0; i < runs.size(); ++i) body += (i ? ", " : "") + html_escape(runs[i].name) + (i ? " (held out)" : " (fit run)");
  body += "</div>";
  body += identity_header(o.runs);

  // Qualification summary.
  // Two questions, one answer each, and how they relate: qualification (does the compensated
  // output meet the limits on every run?) and adequacy (is what the model leaves the gyro's own
  // noise, with no effect left to add?). Both use the one noise rule (model::NoiseRule).
  const model::NoiseRule rule;
  body += "<h2>Qualification summary (IEEE Std 952 thermal sensitivities)</h2>";
  body += station_verdicts(o.runs);
  body += std::string("<p><b>Qualification:</b> <span class=\"verdict ") + (q.pass ? "pass\">PASS" : q.marginal ? "failv\">MARGINAL" : "failv\">FAIL") +
          "</span> compensated std under " + fixed(100.0 * q.threshold, 0) + "% of the raw std on every run, within " +
          fixed(rule.max_noise_factor, 2) + " x the gyro's noise std (its floor read off the holds) and no failing interval of " +
          fixed(rule.max_fail_s, 0) + " s or more</p>";
  body += std::string("<p><b>Model adequacy:</b> <span class=\"verdict ") + (d->adequate ? "pass\">ADEQUATE" : "failv\">NOT ADEQUATE") +
          "</span> " +
          (d->adequate ? std::string("what the model leaves is the gyro's own noise on every run, and no effect of the search improves it")
                       : html_escape(d->reasons.empty() ? std::string("see the diagnosis") : d->reasons.front())) +
          "</p><p class=\"note\">" +
          (q.pass && !d->adequate
               ? "The compensation meets the qualification limits, but the model misses something the diagnosis names: the verdict "
                 "stands for these runs, and the model can be improved (a profile with other rates or temperatures may fail it)."
               : !q.pass && d->adequate
                     ? "The model is the best the data support, yet the compensated output does not meet the limits: the gyro, not "
                       "the model, is what fails."
                     : q.pass ? "The verdict and the model agree: the compensation meets the limits and nothing is left to add."
                              : "Both answers are no: see the reasons below and the diagnosis.") +
          "</p>";
  for (const auto& x : q.runs)
    for (const auto& why : x.reasons) body += "<p class=\"note\">" + html_escape(x.run) + ": " + html_escape(why) + "</p>";
  {
    HtmlTable t({"sensitivity", "term", "value", "1 sigma", "unit", "source"});
    t.row({"bias", "mu0", fixed(q.mu0_dph, 3), fixed(q.mu0_se_dph, 3), "deg/h", "the model"});
    // IEEE Std 952's three thermal sensitivities always appear: from the model when it has
    // the term, else from diagnose's refit of the model with it (so a missing one shows its size).
    const std::pair<const char*, const char*> ieee[] = {
        {"T1", "temperature (per degC)"}, {"d(T1)", "temperature rate (per degC/min)"}, {"grad", "temperature gradient (per degC)"}};
    std::vector<bool> shown(q.sensitivities.size(), false);
    for (const auto& [key, what] : ieee) {
      bool found = false;
      for (std::size_t i = 0; i < q.sensitivities.size(); ++i) {
        const auto& x = q.sensitivities[i];
        if (x.term.substr(0, x.term.find('@')) != key) continue;
        t.row({what, x.term, sig(x.coef), sig(x.se_in_unit), x.unit, "the model"});
        shown[i] = found = true;
      }
      if (found) continue;
      for (const auto& c : d->candidates)
        if (c.expr == key && c.evaluated) {
          t.row({what, c.term, sig(c.coef), sig(c.se_dph_per_unit), c.unit, std::string("refit with it (not in the model") + (c.detected ? ", detected)" : ", not needed)")});
          found = true;
        }
      if (!found) t.row({what, key, "-", "-", "", "not estimated"});
    }
    for (std::size_t i = 0; i < q.sensitivities.size(); ++i)
      if (!shown[i]) {
        const auto& x = q.sensitivities[i];
        t.row({"other", x.term, sig(x.coef), sig(x.se_in_unit), x.unit, "the model"});
      }
    body += t.str();
    HtmlTable r({"run", "role", "raw std, deg/h", "compensated std, deg/h", "comp/raw", "heating - cooling at equal T1, deg/h", "the same compensated, deg/h",
                 "peak excursion on ramps, deg/h", "verdict"});
    for (const auto& x : q.runs)
      r.row({x.run, x.held_out ? "independent" : "fit", fixed(x.meas_std_dph, 3), fixed(x.comp_std_dph, 3), pct(x.ratio),
             fixed(x.hysteresis_dph, 3), fixed(x.hysteresis_comp_dph, 3), fixed(x.peak_ramp_excursion_dph, 3),
             x.pass ? "pass" : x.verdict == model::Verdict::marginal ? "MARGINAL" : "FAIL"},
            x.pass ? "" : "fail");
    body += r.str();
    body += "<p class=\"note\">Heating minus cooling: mean output in 1 degC bins of T1 visited by both heating and cooling "
            "(at least 30 s each), weighted by the fewer samples. Peak excursion: largest |61 s average of the output - mu0| "
            "during ramps. Sensitivities: the model's coefficients with their standard errors from the prewhitened regression.</p>";
  }

  if (sfr) body += report_html::scale_factor_section(*sfr, o.scale_factor, "t1_c", specs, o.max_points);

  // Diagnosis.
  body += "<h2>Diagnosis</h2><div class=\"summary\">" + html_escape(d->summary) + "</div>";
  {
    std::vector<std::string> head{"#", "term", "effect", "lag, s", "rms fit, deg/h", "fall", "delta BIC", "p"};
    for (const auto& h : d->held_out_runs) head.push_back("rms " + h);
    head.push_back("verdict");
    HtmlTable t(head);
    int rank = 0;
    for (const auto& c : d->candidates) {
      if (!c.evaluated) continue;
      std::vector<std::string> row{std::to_string(++rank), c.term, c.effect, std::to_string(c.lag_s),
                                   fixed(c.rms_before_dph, 3) + " → " + fixed(c.rms_after_dph, 3), pct(c.fall), fixed(c.delta_bic, 1),
                                   c.p_value < 1e-4 ? "<1e-4" : fixed(c.p_value, 4)};
      for (const auto& h : c.held_out) row.push_back(h.scored ? fixed(h.rms_before_dph, 3) + " → " + fixed(h.rms_after_dph, 3) : "skipped");
      row.push_back(!c.detected ? "-" : rank == 1 ? "MISSING" : "helps too");
      t.row(row, rank == 1 && c.detected ? "hit" : "");
    }
    body += t.str();
    std::string notes;
    for (const auto& c : d->candidates)
      if (!c.evaluated) notes += "<li>" + html_escape(c.term) + ": " + html_escape(c.skipped) + "</li>";
    if (!notes.empty()) body += "<p class=\"note\">Skipped:</p><ul class=\"note\">" + notes + "</ul>";
    if (!d->steps.empty()) {
      for (const auto& c : d->candidates)
        if (c.expr == d->steps.front().expr) {
          body += "<p class=\"note\"><b>Why " + html_escape(c.expr) + ":</b> " + html_escape(c.explanation) + "</p>";
          break;
        }
    }
    body += "<p class=\"note\">Rule: " + html_escape(d->rule) + ".</p>";
    HtmlTable c({"coefficient", "value", "1 sigma", "unit"});
    for (const auto& x : d->coefs) c.row({x.term, sig(x.coef), sig(x.se_in_unit), x.unit});
    body += "<h3>Coefficients of the model refitted on " + html_escape(d->fit_run) + "</h3>" + c.str();
    for (const auto& p : d->collinear_coefs)
      body += "<p class=\"note\">Collinear: " + html_escape(p.a) + " and " + html_escape(p.b) + " (r = " + fixed(p.r, 3) + "): " + html_escape(p.why) + "</p>";
    const auto& w = d->whiteness;
    body += "<p class=\"note\">Residual prewhitened by the model's AR filter: Ljung-Box Q " + fixed(w.lb.q, 1) + " on " +
            std::to_string(w.lb.dof) + " dof, p " + fixed(w.lb.p_value, 4) + (w.white() ? " (white)" : " (not white)") + ".</p>";
    HtmlTable x({"regressor", "peak cross-correlation", "at lag, s", "lags outside ±2/√N"});
    for (const auto& cc : d->ccf)
      x.row({cc.term, fixed(cc.peak_r, 3), std::to_string(cc.peak_lag_s), std::to_string(cc.outside) + " of " + std::to_string(cc.r.size())});
    body += "<h3>Cross-correlation of the prewhitened residual with each regressor</h3>" + x.str();
  }

  // Drift that is not thermal: the evidence of each finding (figure and plot).
  if (d->time_drift.found || !d->periodic.empty()) {
    body += "<h2>Drift that is not thermal</h2>";
    const auto& td = d->time_drift;
    if (td.found) {
      body += "<p>" + html_escape(td.message) + ".</p>";
      HtmlTable t({"run", "slope, deg/h per h", "1 sigma"});
      for (const auto& r : td.runs) t.row({r.run, fixed(r.slope_dph_per_h, 4), fixed(r.se_dph_per_h, 4)});
      body += t.str();
      for (const auto& sr : td.series) {
        plots::Plot p;
        p.id = "trend_" + std::to_string(&sr - td.series.data());
        p.title = "Residual of the model on " + sr.run + " (61 s average) and the line in time fitted to it";
        p.xlabel = "time, s";
        p.ylabel = "deg/h";
        p.x = sr.time_s;
        plots::Series r;
        r.name = "residual, 61 s average";
        r.y = sr.residual_dph;
        r.stroke = "#8a949f";
        r.keys = plots::keys_text(plots::keys(r.y), "deg/h");
        p.series.push_back(std::move(r));
        plots::Series l;
        l.name = "line in time";
        l.y = sr.fitted_dph;
        l.stroke = kColours[0];
        l.width = 2;
        l.keys = plots::keys_text(plots::keys(l.y), "deg/h");
        p.series.push_back(std::move(l));
        body += plots::render(p, specs, o.max_points);
      }
    }
    for (const auto& pd : d->periodic) {
      body += "<p>" + html_escape(pd.message) + ".</p>";
      plots::Plot p;
      p.id = "periodic_" + std::to_string(&pd - d->periodic.data());
      p.kind = "xy";
      p.log = true;
      p.robust = false;
      p.title = "Amplitude spectrum of the residual on " + pd.run + " against the gyro's noise (peak at " + fixed(pd.period_s, 0) + " s)";
      p.xlabel = "period, s";
      p.ylabel = "deg/h";
      plots::Series a;
      a.name = "residual";
      a.x = pd.spectrum_period_s;
      a.y = pd.spectrum_amp_dph;
      a.stroke = kColours[0];
      a.keys = "peak " + fixed(pd.amplitude_dph, 3) + " deg/h at " + fixed(pd.period_s, 0) + " s";
      p.series.push_back(std::move(a));
      plots::Series nz;
      nz.name = "the gyro's noise (floor)";
      nz.x = pd.spectrum_period_s;
      nz.y = pd.noise_amp_dph;
      nz.stroke = "#8a949f";
      nz.dash = {4, 4};
      p.series.push_back(std::move(nz));
      body += plots::render(p, specs, o.max_points);
    }
  }

  // The residual against the top candidates on the fit run.
  {
    auto c0 = wb::compare(*m, runs.front());
    plots::Plot p;
    p.id = "cand";
    p.title = "Residual on " + runs.front().name + " against the top candidates (each: its refitted contribution, mean removed)";
    p.xlabel = "time, s";
    p.ylabel = "deg/h";
    if (c0) {
      p.x = c0->time_s;
      plots::Series r;
      r.name = "residual, 61 s average";
      r.y = c0->residual_smooth_dph;
      r.stroke = "#8a949f";
      r.keys = plots::keys_text(plots::keys(r.y), "deg/h");
      p.series.push_back(std::move(r));
      for (const auto& c : d->candidates) {
        if (!c.evaluated || p.series.size() > 3) continue;
        plots::Series s;
        s.y = contribution(c, runs.front(), m->tref_c);
        if (s.y.empty()) continue;
        s.name = c.term + " × " + sig(c.coef) + " " + c.unit;
        s.stroke = kColours[p.series.size() % std::size(kColours)];
        s.width = 2;
        s.keys = "compensated std with it " + fixed(c.rms_before_dph, 3) + " → " + fixed(c.rms_after_dph, 3) + " deg/h; " +
                 plots::keys_text(plots::keys(s.y), "deg/h");
        p.series.push_back(std::move(s));
      }
    }
    body += "<h2>Residual against the top candidates</h2>";
    if (p.series.size() > 1) body += plots::render(p, specs, o.max_points);
    else body += "<p class=\"note\">No candidate could be evaluated.</p>";
  }

  // Lineage: the models of the chain, then diagnose's steps refitted on the fit run.
  std::vector<std::unique_ptr<model::Model>> owned;
  std::vector<std::string> step_notes;
  std::vector<std::string> added;
  for (const auto& st : d->steps) added.push_back(st.added);
  const std::vector<report_html::Step> steps = report_html::lineage_steps(*m, runs.front(), added, owned, step_notes);
  body += "<h2>Lineage of the error</h2>";
  {
    std::vector<std::string> head{"#", "terms"};
    for (const auto& r : runs) head.push_back(r.name + ", deg/h");
    head.push_back("note");
    HtmlTable t(head);
    plots::Plot p;
    p.id = "lineage";
    p.kind = "step";
    p.robust = false;
    p.y_from_zero = true;
    p.title = "Compensated std of each model of the lineage on each run (step 0 = the root)";
    p.xlabel = "lineage step";
    p.ylabel = "compensated std, deg/h";
    for (std::size_t r = 0; r < runs.size(); ++r) {
      plots::Series s;
      s.name = runs[r].name + (r ? " (held out)" : " (fit run)");
      s.stroke = kColours[r % std::size(kColours)];
      s.width = 2;
      s.points = true;
      p.series.push_back(std::move(s));
    }
    for (std::size_t i = 0; i < steps.size(); ++i) {
      const model::Model& sm = *steps[i].model;
      p.x.push_back(static_cast<double>(i));
      p.x_names.push_back(steps[i].label.substr(steps[i].label.find(": ") + 2) + " = " + sm.terms_string());
      std::vector<std::string> row{std::to_string(i), sm.terms_string()};
      for (std::size_t r = 0; r < runs.size(); ++r) {
        auto v = model::verify(sm, runs[r]);
        const double y = v ? v->run.comp_std : std::nan("");
        p.series[r].y.push_back(y);
        row.push_back(v ? fixed(y, 3) : "-");
      }
      row.push_back(steps[i].saved ? sm.note : "diagnose's step, refitted here, not saved: fogctl fit --add \"" + added[i - (steps.size() - owned.size())] + "\"");
      t.row(row);
    }
    for (auto& s : p.series) {
      std::string k;
      for (std::size_t i = 0; i < s.y.size(); ++i) k += (i ? ", " : "") + std::string("step ") + std::to_string(i) + " " + fixed(s.y[i], 3);
      s.keys = "compensated std " + k + " deg/h";
    }
    body += t.str();
    for (const auto& n : step_notes) body += "<p class=\"note\">" + html_escape(n) + "</p>";
    if (steps.size() > 1) body += plots::render(p, specs, o.max_points);
  }

  // Per run: profile, drift, residual.
  for (std::size_t k = 0; k < runs.size(); ++k) {
    auto c = wb::compare(*m, runs[k]);
    if (!c) {
      err << "fogctl report: " << c.error().message << "\n";
      return kExitError;
    }
    const auto& v = c->verification;
    body += "<h2>Run " + html_escape(runs[k].name) + (k ? " (held out)" : " (fit run)") + "</h2>";
    body += "<p class=\"note\">" + std::to_string(v.run.n) + " samples; raw std " + fixed(v.run.meas_std, 3) + " deg/h, compensated " +
            fixed(v.run.comp_std, 3) + " deg/h (" + pct(v.run.ratio) + "); " + std::to_string(c->failures.size()) +
            " failing interval(s) beyond " + fixed(c->threshold_dph, 3) + " deg/h. Plotted: at most " + std::to_string(o.max_points) +
            " of " + std::to_string(runs[k].size()) + " samples per series (minimum and maximum of each bucket). Y-ranges are robust: "
            "a few extreme samples do not set them, they are marked at the edge and counted in the title.</p>";
    const std::string key = std::to_string(k);
    {
      plots::Plot p;
      p.id = "temp" + key;
      p.title = "Temperature profile: " + runs[k].name;
      p.xlabel = "time, s";
      p.ylabel = "temperature, degC";
      p.x = c->time_s;
      std::vector<std::pair<std::string, const std::vector<double>*>> temps{{"T1 (coil centre)", &c->t1_c}, {"T2 (outer wall)", &c->t2_c}};
      if (!c->ta_c.empty()) temps.emplace_back("Ta (chamber air)", &c->ta_c);
      for (const auto& [name, y] : temps) {
        plots::Series s;
        s.name = name;
        s.y = *y;
        s.stroke = kColours[p.series.size()];
        s.keys = plots::keys_text(plots::keys(s.y), "degC");
        p.series.push_back(std::move(s));
      }
      body += plots::render(p, specs, o.max_points);
    }
    {
      plots::Plot p;
      p.id = "drift" + key;
      p.title = "Measured and predicted drift: " + runs[k].name;
      p.xlabel = "time, s";
      p.ylabel = "drift, deg/h";
      p.x = c->time_s;
      p.series.resize(2);
      p.series[0].name = "measured";
      p.series[0].y = c->measured_dph;
      p.series[0].stroke = "#aab4c0";
      p.series[0].width = 1;
      p.series[1].name = "predicted";
      p.series[1].y = c->predicted_dph;
      p.series[1].stroke = "#d9822b";
      p.series[1].width = 2;
      for (auto& s : p.series) s.keys = plots::keys_text(plots::keys(s.y), "deg/h");
      body += plots::render(p, specs, o.max_points);
    }
    {
      plots::Plot p;
      p.id = "resid" + key;
      p.title = "Residual (measured - predicted), failing intervals shaded: " + runs[k].name;
      p.xlabel = "time, s";
      p.ylabel = "residual, deg/h";
      p.x = c->time_s;
      for (const auto& f : c->failures) p.failures.push_back(wb::to_json(f));
      p.series.resize(4);
      p.series[0].name = "residual";
      p.series[0].y = c->residual_dph;
      p.series[0].stroke = "#c3cad3";
      p.series[0].width = 1;
      p.series[0].keys = plots::keys_text(plots::keys(c->residual_dph), "deg/h");
      p.series[1].name = "residual, 61 s average";
      p.series[1].y = c->residual_smooth_dph;
      p.series[1].stroke = "#1f4e8c";
      p.series[1].width = 2;
      p.series[1].keys = plots::keys_text(plots::keys(c->residual_smooth_dph), "deg/h") + "; " + std::to_string(c->failures.size()) +
                         " failing interval(s)";
      for (int i : {2, 3}) {
        auto& s = p.series[static_cast<std::size_t>(i)];
        s.name = i == 2 ? "+k sigma_a" : "-k sigma_a";
        s.y.assign(c->time_s.size(), i == 2 ? c->threshold_dph : -c->threshold_dph);
        s.stroke = "#b3261e";
        s.width = 1;
        s.dash = {6, 4};
        s.robust = false;
      }
      p.series[2].keys = "failing beyond +-" + fixed(c->threshold_dph, 3) + " deg/h (k sigma_a) for 60 s or more";
      body += plots::render(p, specs, o.max_points);
    }
    const wb::QualRun* qr = k < q.runs.size() ? &q.runs[k] : nullptr;
    body += report_html::analysis_plots({*m, runs[k], *c, qr, key}, steps, specs, o.max_points);
    body += report_html::allan_section(*m, runs[k], key, specs, o.max_points);
    HtmlTable t({"part", "samples", "est mean", "meas mean", "est std", "meas std", "comp std", "comp/raw"});
    auto row = [&](const std::string& name, const model::Table1& x) {
      t.row({name, std::to_string(x.n), fixed(x.est_mean, 3), fixed(x.meas_mean, 3), fixed(x.est_std, 3), fixed(x.meas_std, 3),
             fixed(x.comp_std, 3), pct(x.ratio)});
    };
    row("whole run", v.run);
    for (const auto& p : v.phases) row(std::string(to_string(p.phase)), p.stats);
    for (const auto& st : c->steps) row("step " + std::to_string(st.step) + " (" + std::string(to_string(st.phase)) + ")", st.stats);
    body += t.str();
    if (!c->failures.empty()) {
      HtmlTable f({"phase", "step", "start, s", "duration, s", "mean error, deg/h", "peak error, deg/h", "T1, degC", "T2, degC",
                   "dT1/dt, degC/min", "grad, degC"});
      for (const auto& x : c->failures)
        f.row({std::string(to_string(x.phase)), x.step < 0 ? "-" : std::to_string(x.step), fixed(x.start_s, 0), fixed(x.duration_s, 0),
               fixed(x.mean_err_dph, 3), fixed(x.peak_err_dph, 3), fixed(x.t1_c, 2), fixed(x.t2_c, 2), fixed(x.rate_c_per_min, 3),
               fixed(x.grad_c, 3)});
      body += "<h3>Where the model fails</h3>" + f.str();
    }
  }
  body += std::string("<p class=\"note\">Plots: uPlot ") + vendor::kUplotVersion + " (MIT), embedded. Generated by fogctl " FOGBENCH_VERSION ".</p>";

  std::string html = "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>fogbench report: " + html_escape(m->terms_string()) +
                     "</title><style>" + std::string(vendor::kUplotCss) + "</style><style>" + kStyle + plots::kPlotStyle +
                     "</style></head><body>" + body + "<script>" + std::string(vendor::kUplotJs) + "</script><script>const DATA=" +
                     script_json(json{{"plots", specs}}) + ";</script><script>" + plots::kPlotScript + "</script></body></html>\n";
  progress.update("write", "report: writing " + o.output);
  progress.finish();
  if (auto w = write_text(o.output, html); !w) {
    err << "fogctl report: " << w.error() << "\n";
    return kExitError;
  }
  out << "report written to " << o.output << " (" << html.size() / 1024 << " KiB; " << (d->adequate ? "model adequate" : d->reasons.empty() ? std::string("model not adequate") : d->reasons.front())
      << "; qualification " << (q.pass ? "PASS" : q.marginal ? "MARGINAL" : "FAIL")
      << (sfr ? "; scale factor temperature sensitivity " + coefficient_text(sfr->tc_ppm_per_c, 3, "ppm/degC") : std::string()) << ")\n";
  // The report is written either way; its exit code is the qualification's, as verify's is.
  return q.pass ? kExitOk : q.marginal ? kExitMarginal : kExitFailed;
}

}  // namespace fogbench::cli
