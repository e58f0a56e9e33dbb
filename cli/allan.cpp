// fogctl allan: the Allan deviation of a run's holds (and of its compensated output with a
// model), with the noise terms of IEEE Std 952 Annex C read off the curve.
#include "allan.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fogbench/model/allan.hpp"
#include "table.hpp"

namespace fogbench::cli {
namespace {

namespace allan = model::allan;
using nlohmann::json;

json estimate_json(const std::optional<allan::NoiseEstimate>& e, const std::string& note) {
  json j = json::object();
  if (e)
    j = {{"value", e->value}, {"ci_low", e->ci_low}, {"ci_high", e->ci_high},
         {"from_tau_s", e->from_tau_s}, {"to_tau_s", e->to_tau_s}, {"edf", e->edf}, {"share", e->share}};
  else
    j = {{"value", nullptr}};
  if (!note.empty()) j["note"] = note;
  return j;
}

json fit_json(const allan::AvarFit& f) {
  if (!f.ok) return nullptr;
  return {{"white_dph2_s", f.white}, {"white_se", f.white_se}, {"flicker_dph2", f.flicker},
          {"flicker_se", f.flicker_se}, {"walk_dph2_per_s", f.walk}, {"walk_se", f.walk_se}};
}

std::string cell(const std::optional<allan::NoiseEstimate>& e, int digits) {
  if (!e) return "-";
  return fixed(e->value, digits) + " (" + fixed(e->ci_low, digits) + ".." + fixed(e->ci_high, digits) + ")";
}

}  // namespace

std::expected<std::vector<AllanSeries>, std::string> allan_series(const model::RunData& run, const model::Model* m,
                                                                  std::size_t min_samples, bool whole_run) {
  std::vector<AllanSeries> series;
  int hold = 0;
  for (const auto& s : allan::even_stretches(run, min_samples, whole_run)) {
    AllanSeries x{whole_run || !run.has_phase() ? "run" : "hold " + std::to_string(++hold), s, {}};
    x.rate_dph.assign(run.gyro_dph.begin() + static_cast<std::ptrdiff_t>(s.begin),
                      run.gyro_dph.begin() + static_cast<std::ptrdiff_t>(s.end));
    series.push_back(std::move(x));
  }
  if (m) {
    auto predicted = model::predict(*m, run);
    if (!predicted) return std::unexpected(predicted.error().message);
    // The compensated output over the whole run: every phase, since compensation is meant to
    // remove the ramps' drift. The longest even stretch is analysed.
    model::RunData comp = run;
    for (std::size_t i = 0; i < comp.size(); ++i) comp.gyro_dph[i] -= (*predicted)[i];
    std::optional<allan::Stretch> longest;
    for (const auto& s : allan::even_stretches(comp, min_samples, true))
      if (!longest || s.end - s.begin > longest->end - longest->begin) longest = s;
    if (longest) {
      AllanSeries x{"compensated", *longest, {}};
      x.rate_dph.assign(comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->begin),
                        comp.gyro_dph.begin() + static_cast<std::ptrdiff_t>(longest->end));
      series.push_back(std::move(x));
    }
  }
  return series;
}

int run_allan(const AllanOptions& o, std::ostream& out, std::ostream& err) {
  if (o.min_samples < 7) {
    err << "fogctl allan: --min-samples " << o.min_samples << " is under 7 (three octave taus need 7 samples)\n";
    return kExitError;
  }
  auto run = load_run(o.run, o.input);
  if (!run) {
    err << "fogctl allan: " << run.error() << "\n";
    return kExitError;
  }
  std::optional<model::Model> m;
  if (!o.model.empty()) {
    auto loaded = load_model(o.model);
    if (!loaded) {
      err << "fogctl allan: " << loaded.error() << "\n";
      return kExitError;
    }
    m = std::move(*loaded);
  }
  auto made = allan_series(*run, m ? &*m : nullptr, o.min_samples, o.whole_run);
  if (!made) {
    err << "fogctl allan: " << o.model << " on " << o.run << ": " << made.error() << "\n";
    return kExitError;
  }
  const std::vector<AllanSeries>& series = *made;
  if (series.empty()) {
    err << "fogctl allan: " << o.run << ": no stretch of " << o.min_samples << " or more evenly spaced, unflagged "
        << (run->has_phase() && !o.whole_run ? "hold " : "") << "samples"
        << (run->has_phase() && !o.whole_run ? " (--whole-run analyses every phase)" : "") << "\n";
    return kExitError;
  }

  json results = json::array();
  Table t({"series", "from s", "to s", "samples", "ARW deg/sqrt(h)", "bias instab. deg/h", "RRW deg/h/sqrt(h)"});
  // Where each figure was read: its tau, the EDF of sigma^2 there and the term's share of it.
  Table where({"series", "figure", "tau s", "EDF", "share %"});
  std::vector<std::string> notes;
  for (const auto& x : series) {
    const auto sizes = allan::octave_cluster_sizes(x.rate_dph.size());
    auto curve = allan::overlapping_adev(x.rate_dph, x.stretch.tau0_s, sizes);
    if (!curve) {  // cannot happen for stretches of finite, evenly spaced samples; said if it does
      err << "fogctl allan: " << x.what << ": " << curve.error() << "\n";
      return kExitError;
    }
    const auto terms = allan::noise_terms(*curve);
    const double from_s = run->time_s[x.stretch.begin], to_s = run->time_s[x.stretch.end - 1];
    t.add({x.what, fixed(from_s, 0), fixed(to_s, 0), std::to_string(x.rate_dph.size()),
           cell(terms.arw_deg_per_sqrt_h, 5), cell(terms.bias_instability_dph, 4), cell(terms.rrw_dph_per_sqrt_h, 4)});
    for (const auto& [name, note] : {std::pair{"ARW", terms.arw_note}, std::pair{"bias instability", terms.bias_instability_note},
                                     std::pair{"RRW", terms.rrw_note}})
      if (!note.empty()) notes.push_back(x.what + ": " + name + ": " + note);
    for (const auto& [name, e] : {std::pair{"ARW", &terms.arw_deg_per_sqrt_h}, std::pair{"bias instability", &terms.bias_instability_dph},
                                  std::pair{"RRW", &terms.rrw_dph_per_sqrt_h}})
      if (*e) where.add({x.what, name, fixed((*e)->from_tau_s, 0), fixed((*e)->edf, 1), fixed(100.0 * (*e)->share, 0)});
    json pts = json::array();
    for (const auto& p : *curve)
      pts.push_back({{"tau_s", p.tau_s}, {"adev_dph", p.adev_dph}, {"ci_low_dph", p.ci_low_dph},
                     {"ci_high_dph", p.ci_high_dph}, {"terms", p.terms}});
    results.push_back({{"series", x.what}, {"from_s", from_s}, {"to_s", to_s}, {"samples", x.rate_dph.size()},
                       {"tau0_s", x.stretch.tau0_s}, {"curve", pts},
                       {"arw_deg_per_sqrt_h", estimate_json(terms.arw_deg_per_sqrt_h, terms.arw_note)},
                       {"bias_instability_dph", estimate_json(terms.bias_instability_dph, terms.bias_instability_note)},
                       {"rrw_dph_per_sqrt_h", estimate_json(terms.rrw_dph_per_sqrt_h, terms.rrw_note)},
                       {"fit", fit_json(terms.fit)}});
  }
  if (o.json) {
    out << json{{"run", o.run}, {"series", results},
                {"method", "overlapping Allan deviation at octave taus; sigma^2 = A/tau + F + C tau fitted (EDF-weighted, "
                           "non-negative); each noise term read at one tau with its chi-square 1-sigma interval from the "
                           "EDF there (IEEE Std 952-1997 Annex C, NIST SP 1065 Table 5)"}}
               .dump()
        << "\n";
  } else {
    out << "Allan deviation of " << o.run << " (IEEE 952 Annex C; 1-sigma chi-square intervals in brackets)\n\n" << t.str();
    for (const auto& n : notes) out << "  " << n << "\n";
    out << "\nwhere each figure is read (equivalent degrees of freedom of sigma^2 there, NIST SP 1065 Table 5)\n\n"
        << where.str();
  }
  return kExitOk;
}

void add_allan_command(CLI::App& app, int& code) {
  static AllanOptions o;
  auto* a = app.add_subcommand("allan", "Allan deviation of a run's holds (and its compensated output): angle random walk, bias instability, rate random walk");
  a->add_option("run", o.run, "The run's CSV file")->required();
  a->add_option("--model", o.model, "Also analyse the run compensated with this model (JSON file)");
  a->add_option("--min-samples", o.min_samples, "Shortest stretch analysed, samples (default 600)");
  a->add_flag("--whole-run", o.whole_run, "Analyse every phase, not only the holds");
  a->add_flag("--json", o.json, "Print one JSON object with the curves");
  add_run_input(a, o.input);
  a->callback([&] {
    std::ostringstream text;
    code = run_allan(o, text, std::cerr);
    // Each hold's notes within the terminal's width, as verify's; JSON as it is.
    std::cout << (o.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });
}

}  // namespace fogbench::cli
