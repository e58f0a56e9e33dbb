// The report's scale-factor section (report_scale_factor.hpp).
#include "report_scale_factor.hpp"

#include <algorithm>
#include <cmath>

#include "html.hpp"
#include "report_plots.hpp"
#include "scale_factor.hpp"
#include "table.hpp"

namespace fogbench::cli::report_html {

namespace sf = model::sf;

namespace {

const char* const kSfColours[] = {"#3d6fb6", "#d9822b", "#2e7d32", "#8e44ad", "#b3261e", "#16a085", "#7f8c8d"};

// The scale factor against SF0, ppm (the deviation the table and the plot show).
double dsf_ppm(const sf::Result& r, double scale_factor) { return 1e6 * (scale_factor / r.sf0 - 1.0); }

}  // namespace

std::string scale_factor_section(const sf::Result& r, const std::string& source, const std::string& coil_column, nlohmann::json& specs,
                                 std::size_t max_points) {
  std::string html = "<h2>Scale factor over temperature (IEEE Std 952)</h2>";
  html += "<p class=\"note\">From the rate sequence in " + html_escape(source) + ": the least-squares line of the gyro's output against the "
          "commanded rate (both deg/s) per plateau, the first " + fixed(r.options.settle_s, 1) + " s of each rate step dropped (" +
          std::to_string(r.n_samples_dropped) + " samples); the coil temperature is " + html_escape(coil_column) +
          ". dSF: the scale factor against SF0 " + fixed(r.sf0, 9) + ", ppm; NL: nonlinearity, ppm of full-scale output; asym: asymmetry, "
          "ppm (docs/scale-factor.md).</p>";
  {
    HtmlTable t({"figure", "value"});
    t.row({"temperature sensitivity", coefficient_text(r.tc_ppm_per_c, 3, "ppm/degC")});
    t.row({"temperature-rate dependence", coefficient_text(r.temp_rate_ppm_per_c_per_min, 3, "ppm per degC/min")});
    t.row({"model form SF0 (T0 " + fixed(r.options.t0_c, 1) + " degC)", fixed(r.model_sf0, 9) + " (deg/s)/(deg/s)"});
    t.row({"model form k1", coefficient_text(r.k1_ppm_per_c, 3, "ppm/degC")});
    t.row({"model form k2", coefficient_text(r.k2_ppm_per_c2, 5, "ppm/degC^2")});
    t.row({"plateaus' rms about the model form", fixed(r.model_rms_ppm, 2) + " ppm"});
    html += "<p>The firmware's model form: SF(T) = SF0 (1 + k1 (T - T0) + k2 (T - T0)^2), T the coil temperature (" + html_escape(coil_column) +
            "), degC.</p>" + t.str();
  }
  {
    HtmlTable t({"plateau", coil_column + ", degC", "rate, degC/min", "bias, deg/h", "SF", "dSF, ppm", "NL, ppm", "asym, ppm", "steps", "samples"});
    for (const auto& p : r.plateaus)
      t.row({std::to_string(p.id), fixed(p.coil_c, 2), fixed(p.temp_rate_c_per_min, 3), fixed(p.bias_dph, 3) + (p.bias_from_zero_rate ? "" : " (line)"),
             fixed(p.scale_factor, 9), fixed(dsf_ppm(r, p.scale_factor), 2), fixed(p.nonlinearity_ppm, 2), fixed(p.asymmetry_ppm, 2),
             std::to_string(p.steps.size()), std::to_string(p.n_used)});
    html += t.str();
    // One note for every plateau whose coil temperature moved over its steps (0.1 degC is
    // 1.5 ppm at 15 ppm/degC), as fogctl scale-factor says it per plateau.
    std::string moved;
    for (const auto& p : r.plateaus)
      if (p.coil_span_c > 0.1) moved += (moved.empty() ? "" : ", ") + std::to_string(p.id) + " (" + fixed(p.coil_span_c, 2) + " degC)";
    if (!moved.empty())
      html += "<p class=\"note\">The coil temperature moved over the steps of plateau(s) " + moved +
              ": their NL and asymmetry include the scale factor's change with temperature over the sequence.</p>";
  }
  // The plateaus' scale factors against their temperature, and the model form through them.
  {
    plots::Plot p;
    p.id = "sf_temp";
    p.kind = "xy";
    p.robust = false;
    p.title = "Scale factor against the coil temperature: each plateau, and the model form";
    p.xlabel = coil_column + ", degC";
    p.ylabel = "dSF, ppm";
    plots::Series m;
    m.name = "plateaus";
    m.stroke = kSfColours[0];
    m.line = false;
    double lo = 0.0, hi = 0.0;
    for (const auto& pl : r.plateaus) {
      m.x.push_back(pl.coil_c);
      m.y.push_back(dsf_ppm(r, pl.scale_factor));
      lo = m.x.size() == 1 ? pl.coil_c : std::min(lo, pl.coil_c);
      hi = m.x.size() == 1 ? pl.coil_c : std::max(hi, pl.coil_c);
    }
    m.keys = std::to_string(m.x.size()) + " plateaus from " + fixed(lo, 1) + " to " + fixed(hi, 1) + " degC";
    p.series.push_back(std::move(m));
    plots::Series f;
    f.name = "model form";
    f.stroke = kSfColours[1];
    f.width = 2;
    f.keys = "k1 " + coefficient_text(r.k1_ppm_per_c, 3, "ppm/degC");
    constexpr int kCurvePoints = 60;
    for (int i = 0; i <= kCurvePoints; ++i) {
      const double t = lo + (hi - lo) * i / kCurvePoints;
      f.x.push_back(t);
      f.y.push_back(dsf_ppm(r, sf::model_scale_factor(r, t)));
    }
    p.series.push_back(std::move(f));
    html += plots::render(p, specs, max_points);
  }
  // Each plateau's nonlinearity: the step means' residuals against the input rate.
  {
    plots::Plot p;
    p.id = "sf_nl";
    p.kind = "xy";
    p.robust = false;
    p.title = "Nonlinearity: each step's residual from its plateau's least-squares line";
    p.xlabel = "input rate, deg/s";
    p.ylabel = "residual, ppm of full-scale output";
    for (const auto& pl : r.plateaus) {
      plots::Series s;
      s.name = "plateau " + std::to_string(pl.id) + " (" + fixed(pl.coil_c, 1) + " degC)";
      s.stroke = kSfColours[p.series.size() % std::size(kSfColours)];
      s.line = false;
      std::vector<const sf::Step*> by_rate;
      for (const auto& st : pl.steps) by_rate.push_back(&st);
      std::ranges::sort(by_rate, {}, &sf::Step::rate_in_dps);
      for (const auto* st : by_rate) {
        s.x.push_back(st->rate_in_dps);
        s.y.push_back(st->residual_ppm_fso);
      }
      s.keys = "NL " + fixed(pl.nonlinearity_ppm, 2) + " ppm, asym " + fixed(pl.asymmetry_ppm, 2) + " ppm";
      p.series.push_back(std::move(s));
    }
    html += plots::render(p, specs, max_points);
  }
  return html;
}

}  // namespace fogbench::cli::report_html
