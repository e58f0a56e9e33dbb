// The report's analysis plots of one run: see report_runs.hpp.
#include "report_runs.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <set>

#include "fogbench/model/stats.hpp"
#include "report_plots.hpp"

namespace fogbench::cli::report_html {

namespace wb = model::workbench;

namespace {

const char* const kPalette[] = {"#3d6fb6", "#d9822b", "#2e7d32", "#8e44ad", "#b3261e", "#16a085", "#7f8c8d", "#c0392b"};

std::string g3(double v) {
  if (!std::isfinite(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// The run's sample period, s (1 s on the bench; the lags' unit).
double period_s(const std::vector<double>& t) {
  if (t.size() < 2) return 1.0;
  const double dt = (t.back() - t.front()) / static_cast<double>(t.size() - 1);
  return dt > 0.0 ? dt : 1.0;
}

std::vector<double> demeaned(const std::vector<double>& x) {
  double s = 0.0;
  std::size_t n = 0;
  for (double v : x)
    if (std::isfinite(v)) s += v, ++n;
  std::vector<double> y = x;
  const double m = n ? s / static_cast<double>(n) : 0.0;
  for (double& v : y) v -= m;
  return y;
}

std::size_t finite_count(const std::vector<double>& x) {
  return static_cast<std::size_t>(std::count_if(x.begin(), x.end(), [](double v) { return std::isfinite(v); }));
}

// "largest |r| 0.31 at lag 12 s; 5 of 60 lags outside the 99% band +-0.035".
std::string lag_keys(const std::vector<double>& r, const std::vector<double>& lag_s, double band) {
  std::size_t best = 0;
  int outside = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (std::abs(r[i]) > std::abs(r[best])) best = i;
    outside += std::abs(r[i]) > band;
  }
  if (r.empty()) return "no lag";
  return "largest |r| " + g3(r[best]) + " at lag " + g3(lag_s[best]) + " s; " + std::to_string(outside) + " of " +
         std::to_string(r.size()) + " lags outside the " + g3(100.0 * kBandLevel) + "% band +-" + g3(band) + " (about " +
         g3((1.0 - kBandLevel) * static_cast<double>(r.size())) + " if white)";
}

plots::Series band_series(const std::string& name, double v, std::size_t n) {
  plots::Series s;
  s.name = name;
  s.y.assign(n, v);
  s.stroke = "#b3261e";
  s.width = 1;
  s.dash = {6, 4};
  s.robust = false;
  return s;
}

}  // namespace

std::vector<Step> lineage_steps(const model::Model& m, const model::RunData& fit_run, const std::vector<std::string>& added,
                                std::vector<std::unique_ptr<model::Model>>& owned, std::vector<std::string>& notes) {
  std::vector<const model::Model*> chain;
  for (const model::Model* p = &m; p; p = p->parent.get()) chain.push_back(p);
  std::reverse(chain.begin(), chain.end());
  std::vector<Step> steps;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    std::string label = std::to_string(i) + ": ";
    if (i == 0) {
      label += chain[i]->terms_string() + " (root)";
    } else {
      std::set<std::string> before;
      for (const auto& ft : chain[i - 1]->terms) before.insert(ft.name());
      std::string plus;
      for (const auto& ft : chain[i]->terms)
        if (!before.count(ft.name())) plus += (plus.empty() ? "+ " : " + ") + model::to_string(ft.term, true);
      label += plus.empty() ? chain[i]->terms_string() + " (refitted)" : plus;
    }
    steps.push_back({chain[i], label, true});
  }
  const model::Model* last = &m;
  for (const auto& a : added) {
    auto r = wb::add_term(*last, fit_run, a);
    if (!r) {
      notes.push_back("diagnose's step + " + a + " could not be refitted: " + r.error().message);
      break;
    }
    owned.push_back(std::make_unique<model::Model>(std::move(r->model)));
    last = owned.back().get();
    steps.push_back({last, std::to_string(steps.size()) + ": + " + r->added + " (diagnose's step, not saved)", false});
  }
  return steps;
}

std::string analysis_plots(const RunContext& c, const std::vector<Step>& steps, nlohmann::json& specs, std::size_t max_points) {
  std::string html;
  const auto& cmp = c.cmp;
  const double dt = period_s(cmp.time_s);

  // The residual before and after each added term: the 61 s average (the noise would hide
  // the fall), one series per model of the lineage.
  if (steps.size() > 1) {
    plots::Plot p;
    p.id = "lres" + c.key;
    p.title = "Residual (measured - predicted, 61 s average) before and after each added term: " + c.run.name;
    p.xlabel = "time, s";
    p.ylabel = "residual, deg/h";
    p.x = cmp.time_s;
    for (std::size_t i = 0; i < steps.size(); ++i) {
      plots::Series s;
      s.name = steps[i].label;
      s.stroke = kPalette[i % std::size(kPalette)];
      s.width = i + 1 == steps.size() ? 2.0 : 1.3;
      if (!steps[i].saved) s.dash = {5, 3};
      auto ci = wb::compare(*steps[i].model, c.run);
      if (!ci) {
        s.y.assign(cmp.time_s.size(), std::numeric_limits<double>::quiet_NaN());
        s.keys = "does not run here: " + ci.error().message;
      } else {
        s.y = ci->residual_smooth_dph;
        s.keys = "compensated std " + g3(ci->verification.run.comp_std) + " deg/h (" + g3(100.0 * ci->verification.run.ratio) +
                 "% of raw); 61 s average: " + plots::keys_text(plots::keys(s.y), "deg/h");
      }
      p.series.push_back(std::move(s));
    }
    html += plots::render(p, specs, max_points);
  }

  // ACF of the prewhitened residual and CCF with each regressor, both through the model's AR
  // filter (as MATLAB's resid): white when the model is adequate, then inside the band.
  const std::vector<double> a = model::ar_filter(demeaned(cmp.residual_dph), c.m.ar);
  const std::size_t n = finite_count(a);
  const double band = model::confidence_band(n, kBandLevel);
  const std::string band_name = g3(100.0 * kBandLevel) + "% band (+-" + g3(model::normal_quantile(0.5 + 0.5 * kBandLevel)) + "/sqrt(N))";
  {
    const std::vector<double> full = model::ccf(a, a, kAcfLags);
    plots::Plot p;
    p.id = "acf" + c.key;
    p.kind = "lag";
    p.robust = false;
    p.title = "ACF of the prewhitened residual, N = " + std::to_string(n) + ", " + band_name + ": " + c.run.name;
    p.xlabel = "lag, s";
    p.ylabel = "autocorrelation";
    plots::Series s;
    s.name = "ACF";
    s.stroke = kPalette[0];
    s.points = true;
    for (int k = 1; k <= kAcfLags; ++k) {
      p.x.push_back(k * dt);
      s.y.push_back(full[static_cast<std::size_t>(kAcfLags + k)]);
    }
    s.keys = lag_keys(s.y, p.x, band);
    p.series.push_back(std::move(s));
    p.series.push_back(band_series("+band", band, p.x.size()));
    p.series.push_back(band_series("-band", -band, p.x.size()));
    html += plots::render(p, specs, max_points);
  }
  {
    plots::Plot p;
    p.id = "ccf" + c.key;
    p.kind = "lag";
    p.robust = false;
    p.title = "CCF of the prewhitened residual with each regressor (positive lag: the regressor leads), " + band_name + ": " + c.run.name;
    p.xlabel = "lag, s";
    p.ylabel = "cross-correlation";
    for (int k = -kCcfLags; k <= kCcfLags; ++k) p.x.push_back(k * dt);
    auto sig = model::run_signals(c.run, c.m.tref_c);
    std::size_t i = 0;
    for (const auto& ft : c.m.terms) {
      plots::Series s;
      s.name = ft.name() + " (in the model at " + std::to_string(ft.term.lag.seconds) + " s)";
      s.stroke = kPalette[i++ % std::size(kPalette)];
      auto x = sig ? model::evaluate(*ft.term.expr, sig->view()) : std::expected<std::vector<double>, std::string>(std::unexpected(sig.error().message));
      if (!x) {
        s.y.assign(p.x.size(), std::numeric_limits<double>::quiet_NaN());
        s.keys = "not evaluated: " + x.error();
      } else {
        s.y = model::ccf(a, model::ar_filter(demeaned(*x), c.m.ar), kCcfLags);
        s.keys = lag_keys(s.y, p.x, band);
      }
      p.series.push_back(std::move(s));
    }
    p.series.push_back(band_series("+band", band, p.x.size()));
    p.series.push_back(band_series("-band", -band, p.x.size()));
    if (!c.m.terms.empty()) html += plots::render(p, specs, max_points);
  }

  // The residual against T1: a trend or a curve is a temperature effect the model lacks.
  {
    plots::Plot p;
    p.id = "rvt" + c.key;
    p.kind = "xy";
    p.title = "Residual against the coil temperature T1: " + c.run.name;
    p.xlabel = "T1 (coil centre), degC";
    p.ylabel = "residual, deg/h";
    plots::Series raw, avg;
    raw.name = "residual";
    raw.x = avg.x = cmp.t1_c;
    raw.y = cmp.residual_dph;
    raw.stroke = "#aab4c0";
    raw.line = false;
    raw.points = true;
    avg.name = "residual, 61 s average";
    avg.y = cmp.residual_smooth_dph;
    avg.stroke = "#1f4e8c";
    avg.line = false;
    avg.points = true;
    const double r = model::ccf(cmp.residual_dph, cmp.t1_c, 0)[0];
    raw.keys = "correlation with T1 r = " + g3(r) + "; " + plots::keys_text(plots::keys(raw.y), "deg/h");
    avg.keys = "correlation with T1 r = " + g3(model::ccf(avg.y, cmp.t1_c, 0)[0]) + "; " + plots::keys_text(plots::keys(avg.y), "deg/h");
    p.series = {std::move(raw), std::move(avg)};
    html += plots::render(p, specs, max_points);
  }

  // Drift against T1 in time order, heating and cooling apart: hysteresis shows as a loop.
  {
    const std::vector<double> y = wb::moving_average(cmp.measured_dph, 61);
    const plots::Loop l = plots::split_by_direction(cmp.t1_c, y, static_cast<int>(std::lround(30.0 / dt)));
    plots::Plot p;
    p.id = "loop" + c.key;
    p.kind = "xy";
    p.title = "Measured drift (61 s average) against T1, heating and cooling apart: " + c.run.name;
    p.xlabel = "T1 (coil centre), degC";
    p.ylabel = "drift, deg/h";
    auto add = [&](const std::string& name, const std::vector<double>& x, const std::vector<double>& yy, const char* colour, std::string keys) {
      plots::Series s;
      s.name = name;
      s.x = x;
      s.y = yy;
      s.stroke = colour;
      s.width = 1.6;
      s.keys = std::move(keys) + "; " + plots::keys_text(plots::keys(yy), "deg/h");
      p.series.push_back(std::move(s));
    };
    std::string hys = "heating - cooling at equal T1";
    if (c.qual)
      hys += ": " + g3(c.qual->hysteresis_dph) + " deg/h raw, " + g3(c.qual->hysteresis_comp_dph) + " deg/h compensated";
    add("heating (T1 rising)", l.heat_x, l.heat_y, "#b3261e", hys);
    add("cooling (T1 falling)", l.cool_x, l.cool_y, "#3d6fb6", hys);
    add("holding", l.hold_x, l.hold_y, "#7f8c8d", "T1 within 0.05 degC over 60 s");
    add("predicted by the model (61 s average)", cmp.t1_c, wb::moving_average(cmp.predicted_dph, 61), "#d9822b", "the model's loop");
    p.series.back().dash = {5, 3};
    p.series.back().width = 1.2;
    html += plots::render(p, specs, max_points);
  }
  return html;
}

}  // namespace fogbench::cli::report_html
