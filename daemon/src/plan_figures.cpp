// What a plan's limits measure on one unit's run (plan_figures.hpp).
#include "plan_figures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "fogbench/model/allan.hpp"
#include "fogbench/model/scale_factor.hpp"

namespace fogbench::daemon::plan_figures {

std::string short_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::optional<double> peak_excursion_dph(const model::Model& m, const model::RunData& run) {
  auto pred = model::predict(m, run);
  if (!pred) return std::nullopt;
  std::vector<double> comp;
  for (std::size_t i = 0; i < run.gyro_dph.size() && i < pred->size(); ++i)
    if (!run.flagged(i) && std::isfinite(run.gyro_dph[i]) && std::isfinite((*pred)[i]))
      comp.push_back(run.gyro_dph[i] - (*pred)[i]);
  if (comp.empty()) return std::nullopt;
  double mean = 0.0;
  for (double c : comp) mean += c;
  mean /= static_cast<double>(comp.size());
  double peak = 0.0;
  for (double c : comp) peak = std::max(peak, std::abs(c - mean));
  return peak;
}

AllanFigures allan_figures(const model::RunData& run) {
  AllanFigures f;
  std::vector<double> rate;
  for (std::size_t i = 0; i < run.gyro_dph.size(); ++i)
    if (!run.flagged(i) && std::isfinite(run.gyro_dph[i])) rate.push_back(run.gyro_dph[i]);
  auto curve = model::allan::overlapping_adev(rate, 1.0, model::allan::octave_cluster_sizes(rate.size()));
  if (!curve) {
    f.note = curve.error();
    return f;
  }
  auto terms = model::allan::noise_terms(*curve);
  if (terms.arw_deg_per_sqrt_h) f.arw = terms.arw_deg_per_sqrt_h->value;
  if (terms.bias_instability_dph) f.bias_instability = terms.bias_instability_dph->value;
  f.note = terms.arw_note.empty() ? terms.bias_instability_note : terms.arw_note;
  return f;
}

SfFigures sf_figures(const model::RunData& run) {
  SfFigures out;
  const auto fail_all = [&out](const std::string& why) {
    out.tc_note = out.nonlinearity_note = out.asymmetry_note = why;
    return out;
  };
  auto rec = model::sf::rate_record(run);
  if (!rec) return fail_all("no scale-factor fit: " + rec.error());
  auto f = model::sf::fit(*rec, {});
  if (!f) return fail_all("the scale-factor fit failed: " + f.error());
  const std::string over = " over " + std::to_string(f->plateaus.size()) + " plateaus";
  if (!f->tc_ppm_per_c.value) {
    out.tc_note = "the temperature sensitivity is not identified: " + f->tc_ppm_per_c.not_identified;
  } else {
    out.abs_tc_ppm_per_c = std::abs(*f->tc_ppm_per_c.value);
    out.tc_note = "tc = " + short_number(*f->tc_ppm_per_c.value) + " +- " + short_number(f->tc_ppm_per_c.se) +
                  " ppm/degC (1 sigma)" + over;
  }
  const model::sf::Plateau* worst_nl = nullptr;
  const model::sf::Plateau* worst_asym = nullptr;
  for (const auto& p : f->plateaus) {
    if (!worst_nl || p.nonlinearity_ppm > worst_nl->nonlinearity_ppm) worst_nl = &p;
    if (!worst_asym || std::abs(p.asymmetry_ppm) > std::abs(worst_asym->asymmetry_ppm)) worst_asym = &p;
  }
  const auto at = [](const model::sf::Plateau& p) {
    return "plateau " + std::to_string(p.id) + " (coil " + short_number(p.coil_c) + " degC)";
  };
  if (worst_nl) {
    out.nonlinearity_ppm = worst_nl->nonlinearity_ppm;
    out.nonlinearity_note = "the worst of " + std::to_string(f->plateaus.size()) + " plateaus: " + at(*worst_nl);
  }
  if (worst_asym) {
    out.abs_asymmetry_ppm = std::abs(worst_asym->asymmetry_ppm);
    out.asymmetry_note = "the worst of " + std::to_string(f->plateaus.size()) + " plateaus: " +
                         short_number(worst_asym->asymmetry_ppm) + " ppm at " + at(*worst_asym);
  }
  return out;
}

}  // namespace fogbench::daemon::plan_figures
