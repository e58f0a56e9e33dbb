// simulate, fit and verify: the model core from the command line.
#include "offline.hpp"

#include <CLI/CLI.hpp>
#include <array>
#include <charconv>
#include <sstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "fogbench/model/json.hpp"
#include "fogbench/storage/csv.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "quality.hpp"
#include "scale_factor.hpp"
#include "simulate_profile.hpp"
#include "table.hpp"
#include "workbench.hpp"

namespace fogbench::cli {

namespace {
// A term as the term language writes it with its coefficient: "0.05*T1@30" (shortest digits
// that read back the same double).
std::string term_with_coef(const model::Term& t) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, t.coef);
  return std::string(buf, res.ptr) + "*" + model::to_string(t);
}

// "; own drift y: 0.05*T1": each axis's own extra drift, as `simulate` says it.
std::string axis_effects_text(const std::array<std::string, 3>& axis_effect) {
  std::string s;
  for (std::size_t k = 0; k < 3; ++k)
    if (!axis_effect[k].empty())
      s += std::string(s.empty() ? "; own drift " : ", ") + std::string(model::to_string(static_cast<model::Axis>(k))) + ": " + axis_effect[k];
  return s;
}
}  // namespace

int run_simulate(const SimulateOptions& o, std::ostream& out, std::ostream& err) {
  auto profile = load_profile(o.profile);
  if (!profile) {
    err << "fogctl simulate: " << profile.error() << "\n";
    return kExitError;
  }
  sim::SimConfig cfg;
  cfg.seed = o.seed;
  cfg.units[0].serial = o.serial;
  auto& coil = cfg.units[0].coil;
  auto coil_model = sim::parse_coil_model(o.coil);
  auto t1_at = sim::parse_placement(o.t1_at), t2_at = sim::parse_placement(o.t2_at);
  for (const auto& [opt, error] : {std::pair{"--coil", coil_model ? "" : coil_model.error()}, std::pair{"--t1-at", t1_at ? "" : t1_at.error()},
                                   std::pair{"--t2-at", t2_at ? "" : t2_at.error()}}) {
    if (!error.empty()) {
      err << "fogctl simulate: " << opt << ": " << error << "\n";
      return kExitError;
    }
  }
  coil.model = *coil_model;
  coil.distributed.t1_at = *t1_at;
  coil.distributed.t2_at = *t2_at;
  std::optional<sim::RateSequence> rates;
  if (!o.rate_sequence.empty()) {
    auto seq = sim::parse_rate_sequence(o.rate_sequence, o.rate_step_s);
    if (!seq) {
      err << "fogctl simulate: --rate-sequence: " << seq.error() << "\n";
      return kExitError;
    }
    rates = *seq;
  }
  auto& gyro = cfg.units[0].gyro;
  // ARW N deg/sqrt(h) is a white rate noise of N x 60 deg/h in a 1 s sample (sigma(tau) = N / sqrt(tau_h)).
  if (o.arw_deg_per_sqrt_h) gyro.sigma_a_dph = 60.0 * *o.arw_deg_per_sqrt_h;
  if (o.bias_instability_dph) gyro.bias_instability_dph = *o.bias_instability_dph;
  if (o.rrw_dph_per_sqrt_h) gyro.rrw_dph_per_sqrt_h = *o.rrw_dph_per_sqrt_h;
  gyro.ageing_dph_per_h = o.ageing_dph_per_h;
  if (o.periodic_period_s.has_value() != o.periodic_amplitude_dph.has_value()) {
    err << "fogctl simulate: a periodic disturbance needs both --periodic-period (s) and --periodic-amplitude (deg/h)\n";
    return kExitError;
  }
  if (o.periodic_period_s) {
    gyro.periodic_period_s = *o.periodic_period_s;
    gyro.periodic_amplitude_dph = *o.periodic_amplitude_dph;
  }
  for (const auto& e : o.effects) cfg.units[0].effects += (cfg.units[0].effects.empty() ? "" : " + ") + e;
  if (!cfg.units[0].effects.empty()) {
    if (auto l = model::parse_terms(cfg.units[0].effects); !l) {
      err << "fogctl simulate: --effect: " << l.error().pretty() << "\n";
      return kExitError;
    }
  }
  // A three-axis unit is simulated as three gyros on one coil in the world: the coil's physics
  // is deterministic, so axes 1 and 2 (the world's units 1 and 2) see exactly unit 0's true
  // temperatures, and each draws its own noise; the CSV keeps unit 0's thermistors.
  if (o.axes != 1 && o.axes != 3) {
    err << "fogctl simulate: --axes: expected 1 or 3, found " << o.axes << "\n";
    return kExitError;
  }
  if (o.axes == 3 && rates) {
    err << "fogctl simulate: --axes 3 with --rate-sequence: the rate-sequence CSV carries one axis (its axis 0 on the table)\n";
    return kExitError;
  }
  if (o.axes == 1 && !o.axis_effects.empty()) {
    err << "fogctl simulate: --axis-effect needs --axes 3 (a one-axis gyro's drift is --effect)\n";
    return kExitError;
  }
  if (o.axis_thermistors && o.axes != 3) {
    err << "fogctl simulate: --axis-thermistors needs --axes 3 (a one-axis gyro has one coil)\n";
    return kExitError;
  }
  if (o.axis_thermistors && rates) {
    err << "fogctl simulate: --axis-thermistors with --rate-sequence: the rate-sequence CSV carries one axis\n";
    return kExitError;
  }
  const auto parsed_axis_effects = sim::parse_axis_effects(o.axis_effects, o.axis_thermistors);
  if (!parsed_axis_effects) {
    err << "fogctl simulate: " << parsed_axis_effects.error() << "\n";
    return kExitError;
  }
  const std::array<std::string, 3>& axis_effect = parsed_axis_effects->text;  // x, y, z: each axis's own extra drift
  // An axis's cross-axis terms (another axis's coil) are evaluated after the run, on the axes'
  // recorded thermistors; the rest is the world's drift of that axis.
  std::array<std::vector<model::Term>, 3> cross_terms;
  if (o.axes == 3) {
    const sim::UnitParams housing = cfg.units[0];
    cfg.units.assign(3, housing);
    for (std::size_t k = 0; k < 3; ++k) {
      if (k > 0) cfg.units[k].serial = housing.serial + "-" + std::string(model::to_string(static_cast<model::Axis>(k)));
      if (o.axis_thermistors && k > 0) cfg.units[k].coil = sim::deeper_in_housing(cfg.units[k].coil, k);
      std::string own;
      for (const auto& t : parsed_axis_effects->terms[k]) {
        if (model::uses_axis_thermistor(*t.expr)) cross_terms[k].push_back(t);
        else own += (own.empty() ? "" : " + ") + term_with_coef(t);
      }
      if (!own.empty()) cfg.units[k].effects += (cfg.units[k].effects.empty() ? "" : " + ") + own;
    }
  }
  // Redrawn on a terminal; in a file a line a minute (progress.hpp).
  std::optional<Progress> bar;
  if (!o.quiet && !o.json) bar.emplace(err, progress_redraws());
  auto progress = [&](double t, double total) {
    if (bar)
      bar->update("simulating", "simulating " + profile->source_name + ": " +
                                    std::to_string(static_cast<int>(100.0 * t / std::max(1.0, total))) + "%");
  };
  auto r = simulate_profile(*profile, cfg, progress);
  bar.reset();  // ends the redrawn line
  if (!r) {
    err << "fogctl simulate: " << r.error() << "\n";
    return kExitError;
  }
  if (o.axes == 3) {
    if (o.axis_thermistors) {
      model::RunData& x = r->units[0];
      x.axis_t1_c = {x.t1_c, r->units[1].t1_c, r->units[2].t1_c};
      x.axis_t2_c = {x.t2_c, r->units[1].t2_c, r->units[2].t2_c};
      // As the recording reads them: x's thermistors and chamber reading, each axis's own.
      sim::AxisCoilTemps axes;
      for (std::size_t k = 0; k < 3; ++k) {
        axes.t1_c[k] = x.axis_t1_c[k];
        axes.t2_c[k] = x.axis_t2_c[k];
      }
      for (std::size_t k = 0; k < 3; ++k) {
        if (cross_terms[k].empty()) continue;
        sim::DriftLaw cross;  // the cross-axis terms alone: no mu0
        cross.tref_c = cfg.units[k].gyro.tref_c;
        cross.terms = cross_terms[k];
        auto d = sim::drift_series(cross, x.t1_c, x.t2_c, x.chamber_c, axes);
        if (!d) {
          err << "fogctl simulate: --axis-effect " << model::to_string(static_cast<model::Axis>(k)) << "=...: " << d.error() << "\n";
          return kExitError;
        }
        auto& out_dph = r->units[k].gyro_dph;
        for (std::size_t i = 0; i < out_dph.size() && i < d->size(); ++i) out_dph[i] += (*d)[i];
      }
    }
    r->units[0].gyro_y_dph = std::move(r->units[1].gyro_dph);
    r->units[0].gyro_z_dph = std::move(r->units[2].gyro_dph);
    r->units.resize(1);
  }
  const model::RunData& run = r->units.front();
  if (rates) {
    const std::string csv = rate_sequence_csv(*r, o.sf_truth, *rates);
    if (o.output.empty()) {
      out << csv;
      return kExitOk;
    }
    if (auto w = write_text(o.output, csv); !w) {
      err << "fogctl simulate: " << w.error() << "\n";
      return kExitError;
    }
  } else if (!o.output.empty()) {
    if (auto w = storage::write_csv_file(o.output, run); !w) {
      err << "fogctl simulate: " << w.error().message << "\n";
      return kExitError;
    }
  } else {
    out << storage::to_csv(run);
    return kExitOk;
  }
  if (o.json) {
    nlohmann::json summary{{"profile", profile->source_name}, {"seed", o.seed}, {"samples", run.size()},
                          {"settle_s", r->settle_s}, {"effects", cfg.units[0].effects}, {"coil", o.coil}, {"output", o.output},
                          {"rate_sequence", o.rate_sequence}};
    if (o.axes == 3) {
      summary["axes"] = 3;
      std::array<std::string, 3> drift;  // each axis's whole extra drift: the world's and the cross-axis terms
      for (std::size_t k = 0; k < 3; ++k) {
        drift[k] = cfg.units[k].effects;
        for (const auto& t : cross_terms[k]) drift[k] += (drift[k].empty() ? "" : " + ") + term_with_coef(t);
      }
      summary["axis_effects"] = {{"x", drift[0]}, {"y", drift[1]}, {"z", drift[2]}};
      summary["axis_thermistors"] = o.axis_thermistors;
    }
    out << summary.dump() << "\n";
  } else {
    out << "simulated " << profile->source_name << " (" << o.coil << " coil, seed " << o.seed << (cfg.units[0].effects.empty() ? "" : ", effect " + cfg.units[0].effects)
        << (rates ? ", rate sequence " + o.rate_sequence + " deg/s, " + fixed(o.rate_step_s, 0) + " s each" : "")
        << (o.axes == 3 ? ", three axes" + axis_effects_text(axis_effect) : std::string()) << "): " << run.size() << " samples after a " << static_cast<long>(r->settle_s) << " s settle -> " << o.output << "\n";
  }
  return kExitOk;
}

namespace {

std::string describe_model(const model::Model& m) {
  std::string s;
  s += "model (" + std::string(to_string(m.method)) + " method) fitted on " + m.fitted_on.name +
       (m.axis ? ", axis " + std::string(to_string(*m.axis)) : std::string()) + ": " +
       std::to_string(m.fitted_on.n_samples) + " samples, " + std::to_string(static_cast<long>(m.fitted_on.duration_s)) + " s\n\n";
  Table t({"term", "lag_s", "coef", "se (1 sigma)", "unit"});
  t.add({"mu0", "", fixed(m.mu0_dph, 3), fixed(m.mu0_se_dph, 3), "deg/h"});
  for (const auto& ft : m.terms)
    t.add({ft.name(), std::to_string(ft.term.lag.seconds) + (ft.term.lag.automatic ? " (auto)" : ""), fixed(ft.coef, 4),
           fixed(ft.se_dph_per_unit, 4), coef_unit(*ft.term.expr)});
  s += t.str();
  s += "\nnoise: AR(" + std::to_string(m.ar.size()) + ")";
  for (std::size_t i = 0; i < m.ar.size(); ++i) s += "  k" + std::to_string(i + 1) + " " + fixed(m.ar[i], 4);
  s += "  sigma_a " + fixed(m.sigma_a_dph, 4) + " deg/h\n";
  s += "fit:   " + std::to_string(m.fit.n_used) + " samples used, " + std::to_string(m.fit.n_outliers) + " outliers (3 sigma), " +
       std::to_string(m.fit.n_flagged) + " flagged samples skipped";
  if (m.method == model::Method::paper)
    s += "; opening hold " + std::to_string(m.fit.n_hold) + " s, " + (m.fit.stationary ? "stationary" : "NOT stationary");
  else
    s += "; " + std::to_string(m.fit.iterations) + " iterations" + (m.fit.converged ? "" : " (NOT converged)");
  s += "\n       residual whiteness over the whole run (prewhitened, 20 lags): Ljung-Box Q " + fixed(m.fit.ljung_box_q, 1) + ", p " +
       fixed(m.fit.ljung_box_p, 3) +
       (m.fit.ljung_box_p < 0.01 ? "  (not white: a missing effect, or the gyro's slow noise; fogctl diagnose judges it against the gyro's own noise)"
                                 : "") +
       "\n";
  if (!m.fit.lag_note.empty()) s += "lags:  " + m.fit.lag_note + "\n";
  // The paper's two betas are close to collinear on steady ramps: say so when it shows.
  for (std::size_t a = 1; a < m.fit.coef_corr.size(); ++a)
    for (std::size_t b = a + 1; b < m.fit.coef_corr.size(); ++b)
      if (std::abs(m.fit.coef_corr[a][b]) > 0.9)
        s += "note:  the coefficients of " + m.terms[a - 1].name() + " and " + m.terms[b - 1].name() +
             " are correlated (r = " + fixed(m.fit.coef_corr[a][b], 2) +
             "): this run barely tells them apart, only their combination is well determined\n";
  return s;
}

}  // namespace

int run_fit(const FitCommandOptions& o, std::ostream& out, std::ostream& err) {
  if (o.run.empty()) {
    err << "fogctl fit: which run? give a CSV file, or --run N for a run stored by fogbenchd\n";
    return kExitError;
  }
  auto terms = model::parse_terms(o.terms);
  if (!terms) {
    err << "fogctl fit: --terms: " << terms.error().pretty() << "\n";
    return kExitError;
  }
  model::FitOptions fo;
  const std::string method = o.method.empty() ? (terms->paper ? "paper" : "joint") : o.method;
  auto m = model::method_from_string(method);
  if (!m) {
    err << "fogctl fit: --method: expected paper or joint, found '" << method << "'\n";
    return kExitError;
  }
  fo.method = *m;
  fo.max_lag_s = o.max_lag_s;
  fo.causal_lags = !o.any_lag;
  fo.tref_c = o.tref_c;
  fo.ar_order = o.ar_order;
  // Checked before the run is read, in the options' names as typed.
  if (auto ok = fo.validate(); !ok) {
    err << "fogctl fit: " << as_typed(ok.error(), {{"ar_order", "--ar-order"}, {"max_lag_s", "--max-lag"}, {"tref_c", "--tref"}})
        << "\n";
    return kExitError;
  }
  // The fit reads neither the profile step nor, unless a term uses Ta, the chamber's air.
  RunInput input = o.input;
  input.skip.push_back("step");
  bool uses_ta = false;
  for (const auto& t : terms->terms) uses_ta = uses_ta || model::uses_signal(*t.expr, model::Signal::Ta);
  // The quality check reads the air (a thermistor's lag is judged against it) unless it is off.
  if (!uses_ta && input.quality == "off") input.skip.push_back("chamber_c");
  input.retry = "fogctl fit " + command_form(o.run).arg + (o.terms == "paper" ? "" : " --terms \"" + o.terms + "\"") +
                (o.method.empty() ? "" : " --method " + o.method);
  QualityLog quality;
  auto run = load_run(o.run, input, &quality);
  if (!run) {
    err << "fogctl fit: " << run.error() << "\n";
    return kExitError;
  }
  // Read for the quality check only: the fit sees the run as it did without it.
  if (!uses_ta) run->chamber_c.clear();
  auto model = model::fit(*run, *terms, fo);
  if (!model) {
    err << "fogctl fit: " << o.run << ": " << model.error().message << "\n";
    return kExitError;
  }
  model->created_at = now_iso8601();
  const nlohmann::json j = model::to_json(*model);
  if (!o.output.empty()) {
    if (auto w = write_text(o.output, j.dump(2) + "\n"); !w) {
      err << "fogctl fit: " << w.error() << "\n";
      return kExitError;
    }
  }
  // Coefficients this run does not determine are said, never left silent.
  const auto unidentified = identification_lines(*model, *run);
  if (o.json) {
    nlohmann::json shown = j;
    shown["data_quality"] = quality.flags;
    shown["identification"] = unidentified;
    out << shown.dump() << "\n";
  } else {
    out << describe_model(*model);
    for (const auto& e : model::lags_at_edge(*model)) out << "\nwarning: " << e << "\n";
    for (const auto& l : quality.lines) out << "\nwarning: " << l << "\n";
    for (const auto& w : unidentified) out << "\nwarning: not identified: " << w << "\n";
    if (!o.output.empty()) out << "\nmodel written to " << o.output << "\n";
  }
  return kExitOk;
}

int run_verify(const VerifyOptions& o, std::ostream& out, std::ostream& err) {
  if (o.model.empty() || o.runs.empty()) {
    err << "fogctl verify: " << (o.model.empty() ? "--model MODEL.json is required" : "which runs? give CSV files, or --run N")
        << "\n";
    return kExitError;
  }
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl verify: " << m.error() << "\n";
    return kExitError;
  }
  if (!(o.threshold > 0.0 && o.threshold < 1.0)) {
    err << "fogctl verify: --threshold must be between 0 and 1 (a ratio of std), got " << o.threshold << "\n";
    return kExitError;
  }
  nlohmann::json results = nlohmann::json::array();
  Table t({"run", "est mean", "meas mean", "est std", "meas std", "comp std", "comp/raw", "verdict"});
  Table ph({"run", "phase", "samples", "meas std", "comp std", "comp/raw"});
  bool all_pass = true, any_fail = false;
  std::vector<std::string> reasons;
  model::VerifyOptions vo;
  vo.threshold = o.threshold;
  vo.noise_test = !o.no_noise_test;
  vo.noise.max_noise_factor = o.noise_factor;
  vo.noise.max_fail_s = o.max_fail_s;
  if (auto ok = vo.validate(); !ok) {
    err << "fogctl verify: " << as_typed(ok.error(), {{"the noise factor", "--noise-factor"}, {"the longest failing interval", "--max-fail"}, {"threshold", "--threshold"}}) << "\n";
    return kExitError;
  }
  QualityLog quality;
  // Two 3-day runs take seconds: a line per run and stage once it has taken a while.
  QuietStartProgress progress(err);
  const std::string of_n = " of " + std::to_string(o.runs.size()) + ")";
  for (std::size_t k = 0; k < o.runs.size(); ++k) {
    const std::string& path = o.runs[k];
    const std::string name = display_name(path);  // "run 2 SIM-0001" for --run 2
    progress.update("read " + path, "verify: reading " + name + " (" + std::to_string(k + 1) + of_n);
    auto run = load_run(path, with_model_axis(o.input, *m), &quality);
    if (!run) {
      progress.finish();
      err << "fogctl verify: " << run.error() << "\n";
      return kExitError;
    }
    progress.update("verify " + path, "verify: compensating " + name + " (" + std::to_string(k + 1) + of_n);
    auto v = model::verify(*m, *run, vo);
    if (!v) {
      progress.finish();
      err << "fogctl verify: " << name << ": " << v.error().message << "\n";
      return kExitError;
    }
    all_pass = all_pass && v->pass;
    any_fail = any_fail || v->verdict == model::Verdict::fail;
    for (const auto& why : v->reasons) reasons.push_back(name + ": " + why);
    nlohmann::json j = model::to_json(*v);
    j["run"] = name;
    results.push_back(j);
    t.add({name, fixed(v->run.est_mean), fixed(v->run.meas_mean), fixed(v->run.est_std), fixed(v->run.meas_std),
           fixed(v->run.comp_std), fixed(100.0 * v->run.ratio, 1) + "%",
           v->verdict == model::Verdict::pass ? "pass" : v->verdict == model::Verdict::marginal ? "MARGINAL" : "FAIL"});
    for (const auto& p : v->phases)
      ph.add({name, std::string(to_string(p.phase)), std::to_string(p.stats.n), fixed(p.stats.meas_std),
              fixed(p.stats.comp_std), fixed(100.0 * p.stats.ratio, 1) + "%"});
  }
  progress.finish();
  if (o.json) {
    if (results.size() == 1) {
      auto one = results[0];
      one["data_quality"] = quality.flags;
      out << one.dump() << "\n";
    } else {
      out << nlohmann::json{{"runs", results}, {"pass", all_pass}, {"verdict", all_pass ? "pass" : any_fail ? "fail" : "marginal"},
                            {"threshold", o.threshold}, {"data_quality", quality.flags}}.dump() << "\n";
    }
  } else {
    out << "Table 1 (deg/h): " << model_label(o.model) << " (" << m->terms_string() << ")"
        << (m->axis ? ", axis " + std::string(to_string(*m->axis)) : std::string()) << ", pass when comp/raw < "
        << fixed(100.0 * o.threshold, 0) << "%";
    if (vo.noise_test)
      out << ", comp std within " << fixed(vo.noise.max_noise_factor, 2) << " x the gyro's noise std and no failing interval of "
          << fixed(vo.noise.max_fail_s, 0) << " s or more (else MARGINAL)";
    out << "\n\n" << t.str() << "\nper phase:\n" << ph.str();
    for (const auto& why : reasons) out << "not passed: " << why << "\n";
    for (const auto& l : quality.lines) out << "warning: " << l << "\n";
  }
  return all_pass ? kExitOk : any_fail ? kExitFailed : kExitMarginal;
}

void add_offline_commands(CLI::App& app, int& code) {
  static SimulateOptions sim;
  auto* s = app.add_subcommand("simulate", "Simulate a thermal run of a gyro on the mock bench's physics, to CSV");
  s->add_option("--profile", sim.profile, "exp1, exp2, exp3, qualification or a profile file")->required();
  s->add_option("--effect", sim.effects, "Extra drift in the term language with its coefficient, e.g. \"0.05*T1\" (repeatable)");
  s->add_option("--axes", sim.axes, "Gyro axes of the unit: 1 (default), or 3 (columns gyro_y_dph, gyro_z_dph: y and z share the "
                                    "housing's drift and --effect, each with its own noise)")
      ->check(CLI::IsMember({1, 3}));
  s->add_flag("--axis-thermistors", sim.axis_thermistors,
              "With --axes 3: each axis's coil has its own thermistors (columns t1_y_c, t2_y_c, t1_z_c, t2_z_c), y's and z's "
              "deeper in the housing; an --axis-effect may then read another axis's coil, e.g. \"x=0.05*T1y\"");
  s->add_option("--axis-effect", sim.axis_effects,
                "With --axes 3: one axis's own extra drift, AXIS=TERMS, e.g. \"y=0.05*T1\" (repeatable); the other axes have none");
  s->add_option("--seed", sim.seed, "Random seed, 0 to 18446744073709551615 (same seed, same run)")
      ->check(seed_check());
  s->add_option("--serial", sim.serial, "Serial number of the simulated gyro");
  s->add_option("--coil", sim.coil,
                "Coil model: distributed (radial layers, drift from the temperature field; default) or lumped (two nodes, the "
                "paper's model is the exact truth); docs/simulation.md");
  s->add_option("--t1-at", sim.t1_at, "Distributed coil: where the T1 thermistor sits (hub, inner, middle, outer; default inner)");
  s->add_option("--t2-at", sim.t2_at, "Distributed coil: where the T2 thermistor sits (default outer)");
  s->add_option("--arw", sim.arw_deg_per_sqrt_h, "The gyro's angle random walk, deg/sqrt(h) (default: sigma_a 0.146 deg/h, ARW 0.0024)")
      ->check(CLI::Range(0.0, 1.0));
  s->add_option("--bias-instability", sim.bias_instability_dph, "Flicker noise: the gyro's bias instability, deg/h (default 0)")
      ->check(CLI::Range(0.0, 10.0));
  s->add_option("--rrw", sim.rrw_dph_per_sqrt_h, "The gyro's rate random walk, deg/h/sqrt(h) (default 0)")->check(CLI::Range(0.0, 10.0));
  s->add_option("--ageing", sim.ageing_dph_per_h,
                 "Drift that is not thermal: an ageing (outgassing) ramp, deg/h per h of the run (default 0; no power-on column is written)")
      ->check(CLI::Range(-100.0, 100.0));
  s->add_option("--periodic-period", sim.periodic_period_s, "A periodic disturbance (not thermal): its period, s (with --periodic-amplitude)")
      ->check(CLI::Range(2.0, 1e6));
  s->add_option("--periodic-amplitude", sim.periodic_amplitude_dph, "The periodic disturbance's amplitude, deg/h (with --periodic-period)")
      ->check(CLI::Range(0.0, 1000.0));
  auto* seq = s->add_option("--rate-sequence", sim.rate_sequence,
                            "Rates commanded in turn, deg/s, e.g. \"0,10,-10,100,-100,300,-300\", cycled through every profile step: "
                            "writes the rate-sequence CSV (rate_in_dps, rate_out_dps) for fogctl scale-factor; docs/scale-factor.md");
  s->add_option("--rate-step", sim.rate_step_s, "With --rate-sequence: how long each rate is held, s (default 30)")
      ->check(CLI::Range(1.0, 86400.0))->needs(seq);
  s->add_option("--sf-tc", sim.sf_truth.tc_ppm_per_c, "With --rate-sequence: the true scale factor's temperature coefficient, ppm/degC (default 15)")
      ->check(CLI::Range(-1e4, 1e4))->needs(seq);
  s->add_option("--sf-tc2", sim.sf_truth.tc2_ppm_per_c2, "With --rate-sequence: its second-order coefficient, ppm/degC^2 (default 0)")
      ->check(CLI::Range(-100.0, 100.0))->needs(seq);
  s->add_option("--sf-temp-rate", sim.sf_truth.temp_rate_ppm_per_c_per_min,
                "With --rate-sequence: its dependence on the coil's temperature rate, ppm per degC/min (default 0)")
      ->check(CLI::Range(-1e4, 1e4))->needs(seq);
  s->add_option("--sf-nl", sim.sf_truth.nl_ppm,
                "With --rate-sequence: cubic nonlinearity, the local scale factor's change at 300 deg/s, ppm (default 0)")
      ->check(CLI::Range(-1e5, 1e5))->needs(seq);
  s->add_option("--sf-asym", sim.sf_truth.asymmetry_ppm, "With --rate-sequence: the asymmetry of positive and negative inputs, ppm (default 0)")
      ->check(CLI::Range(-1e5, 1e5))->needs(seq);
  s->add_option("-o,--output", sim.output, "Write the run's CSV here (default: standard output)");
  s->add_flag("--json", sim.json, "Print a JSON summary");
  s->add_flag("-q,--quiet", sim.quiet, "No progress line");
  s->callback([&] { code = run_simulate(sim, std::cout, std::cerr); });

  static FitCommandOptions fit;
  auto* f = app.add_subcommand("fit", "Fit the drift model on a run (CSV)");
  f->add_option("run", fit.run, "The run's CSV file")->required();
  f->add_option("--terms", fit.terms, "Terms, e.g. \"d(T1)@auto + grad@auto\", or paper (default)");
  f->add_option("--method", fit.method, "paper (two-step, shared lag) or joint (regression with AR errors); default: paper for `paper`, joint otherwise");
  f->add_option("--max-lag", fit.max_lag_s, "Longest lag searched for @auto terms, s");
  f->add_flag("--any-lag", fit.any_lag,
              "Search @auto lags from 0 s even for rates (default: a rate term's lag is at least 30 s, the latency of its "
              "61 s slope, so that firmware computes the model causally: fogctl coefficients)");
  f->add_option("--tref", fit.tref_c, "Reference temperature, degC");
  f->add_option("--ar-order", fit.ar_order, "Order p of the AR noise");
  f->add_option("-o,--output", fit.output, "Write the model's JSON here");
  f->add_flag("--json", fit.json, "Print the model as one JSON object");
  // The workbench's "add it": the model's terms plus one, refitted with the model's method.
  static FitAddOptions add;
  f->add_option("--model", add.model, "With --add: the model to extend (its terms, method and options)");
  f->add_option("--add", add.add, "With --model: the term to add, e.g. \"T1\" or \"lp(T1,300)@auto\"");
  add_run_input(f, fit.input);
  add_axis_option(f, fit.input);
  f->callback([&] {
    std::ostringstream text;
    if (add.model.empty() && add.add.empty()) {
      code = run_fit(fit, text, std::cerr);
    } else {
      add.run = fit.run;
      add.output = fit.output;
      add.json = fit.json;
      add.input = fit.input;
      code = run_fit_add(add, text, std::cerr);
    }
    // Its notes within the terminal's width, as verify's; the model's JSON as it is.
    std::cout << (fit.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });

  static VerifyOptions ver;
  auto* v = app.add_subcommand("verify", "Compensate runs with a model: the paper's Table 1 and pass/fail");
  v->add_option("--model", ver.model, "The model's JSON file")->required();
  v->add_option("runs", ver.runs, "The runs' CSV files")->required();
  v->add_option("--threshold", ver.threshold, "Pass when compensated std / raw std is under this (default 0.2)");
  v->add_option("--noise-factor", ver.noise_factor, "Second test: compensated std at most this times the gyro's noise std (default 1.25, as diagnose)");
  v->add_option("--max-fail", ver.max_fail_s, "Second test: a failing interval this long or longer, s, makes the run marginal (default 60)");
  v->add_flag("--no-noise-test", ver.no_noise_test, "The paper's ratio rule alone (no marginal verdict)");
  v->add_flag("--json", ver.json, "Print one JSON object");
  add_run_input(v, ver.input);
  add_axis_option(v, ver.input);
  v->callback([&] {
    std::ostringstream text;
    code = run_verify(ver, text, std::cerr);
    // Prose within the terminal's width (issue 28); JSON as it is.
    std::cout << (ver.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });
}

}  // namespace fogbench::cli
