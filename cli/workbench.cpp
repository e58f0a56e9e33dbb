// compare, diagnose, fit --add and lineage: the model workbench from the command line.
#include "workbench.hpp"

#include "options.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <chrono>
#include <cmath>
#include <iostream>
#include <optional>
#include <nlohmann/json.hpp>

#include "fogbench/model/json.hpp"
#include "fogbench/model/workbench.hpp"
#include "progress.hpp"
#include "quality.hpp"
#include "table.hpp"

namespace fogbench::cli {
namespace wb = model::workbench;

namespace {



// Loads every run, naming the file in the error.
std::expected<std::vector<model::RunData>, std::string> load_runs(const std::vector<std::string>& paths, const RunInput& in,
                                                                  QualityLog* log = nullptr) {
  std::vector<model::RunData> runs;
  for (const auto& p : paths) {
    auto r = load_run(p, in, log);
    if (!r) return std::unexpected(r.error());
    runs.push_back(std::move(*r));
  }
  return runs;
}

std::string step_name(int s) { return s < 0 ? "-" : std::to_string(s); }

// diagnose's size check on the CSV files' data rows (their lines less the header, counted in
// blocks without parsing: at most the samples each will give) before they are loaded, so that a
// run of 10 million samples is refused at once, not after reading it (about 1.5 GB). Resampled
// input and what is not a regular file (a pipe) are left to diagnose's check on the runs read.
std::expected<void, std::string> diagnose_rows_within(const std::vector<std::string>& paths, const RunInput& in, std::size_t max_samples) {
  if (in.resample_s) return {};
  std::vector<model::workbench::RunSize> sizes;
  for (const auto& p : paths) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(p, ec)) return {};
    std::ifstream f(p, std::ios::binary);
    if (!f) return {};  // load_run names the problem
    std::vector<char> block(1 << 20);
    std::size_t lines = 0;
    char last = '\n';
    while (f) {
      f.read(block.data(), static_cast<std::streamsize>(block.size()));
      const auto got = static_cast<std::size_t>(f.gcount());
      lines += static_cast<std::size_t>(std::count(block.data(), block.data() + got, '\n'));
      if (got) last = block[got - 1];
    }
    if (last != '\n') ++lines;  // a last line without its newline
    sizes.push_back({display_name(p), lines > 0 ? lines - 1 : 0});
  }
  auto c = model::workbench::check_diagnose_size(sizes, max_samples);
  if (!c) return std::unexpected(c.error() + " (counted as the files' data rows, before reading them; --max-samples)");
  return {};
}

}  // namespace

int run_compare(const CompareCommandOptions& o, std::ostream& out, std::ostream& err) {
  if (o.model.empty() || o.runs.empty()) {  // both optional on the command line, with --run N
    err << "fogctl compare: " << (o.model.empty() ? "--model MODEL.json is required (or --run N: the unit's current model)" : "which runs? give CSV files, or --run N")
        << "\n";
    return kExitError;
  }
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl compare: " << m.error() << "\n";
    return kExitError;
  }
  wb::CompareOptions co;
  co.noise.k_sigma = o.k_sigma;
  co.noise.smooth_s = o.smooth_s;
  co.noise.max_fail_s = o.min_duration_s;
  if (auto v = co.validate(); !v) {
    err << "fogctl compare: "
        << as_typed(v.error(), {{"k_sigma", "--k-sigma"}, {"smooth_s", "--smooth"}, {"the longest failing interval", "--min-duration"}}) << "\n";
    return kExitError;
  }
  nlohmann::json results = nlohmann::json::array();
  std::string text;
  bool adequate = true;
  QualityLog quality;
  for (const auto& path : o.runs) {
    auto run = load_run(path, with_model_axis(o.input, *m), &quality);  // the model's axis of a three-axis run
    if (!run) {
      err << "fogctl compare: " << run.error() << "\n";
      return kExitError;
    }
    auto c = wb::compare(*m, *run, co);
    if (!c) {
      err << "fogctl compare: " << c.error().message << "\n";
      return kExitError;
    }
    adequate = adequate && c->adequate();
    results.push_back(wb::to_json(*c, o.series));
    const auto& v = c->verification;
    text += (display_name(path) == path ? "run " + path : display_name(path)) + ": " + std::to_string(v.run.n) + " samples, measured std " + fixed(v.run.meas_std, 3) +
            " deg/h, compensated std " + fixed(v.run.comp_std, 3) + " deg/h (" + pct(v.run.ratio) + " of raw)\n\n";
    Table t({"part", "samples", "est mean", "meas mean", "est std", "meas std", "comp std", "comp/raw"});
    auto row = [&](const std::string& name, const model::Table1& s) {
      t.add({name, std::to_string(s.n), fixed(s.est_mean, 3), fixed(s.meas_mean, 3), fixed(s.est_std, 3),
             fixed(s.meas_std, 3), fixed(s.comp_std, 3), pct(s.ratio)});
    };
    row("whole run", v.run);
    for (const auto& p : v.phases) row(std::string(to_string(p.phase)), p.stats);
    for (const auto& s : c->steps)
      row("step " + std::to_string(s.step) + " (" + std::string(to_string(s.phase)) + ", " + fixed(s.start_s, 0) + " s)", s.stats);
    text += t.str();
    text += "\nnoise: compensated std " + fixed(v.noise_factor, 2) + " x the gyro's noise std " + fixed(v.noise_std, 3) + " deg/h (at most " +
            fixed(v.noise_limit_factor, 2) + " x" + (v.noise_factor <= v.noise_limit_factor ? ", ok" : ", TOO LARGE") + "); floor " + v.floor.note + "\n";
    if (c->failures.empty()) {
      text += "no interval where the model fails (smoothed residual beyond " + fixed(c->threshold_dph, 3) + " deg/h for " +
              fixed(co.noise.max_fail_s, 0) + " s or more)\n\n";
    } else {
      text += "the model FAILS in " + std::to_string(c->failures.size()) + " interval(s): smoothed residual beyond " +
              fixed(c->threshold_dph, 3) + " deg/h for " + fixed(co.noise.max_fail_s, 0) + " s or more\n";
      Table f({"phase", "step", "start s", "dur s", "mean err", "peak err", "T1 degC", "T2 degC", "Ta degC", "dT1/dt C/min", "grad degC"});
      for (const auto& x : c->failures)
        f.add({std::string(to_string(x.phase)), step_name(x.step), fixed(x.start_s, 0), fixed(x.duration_s, 0),
               fixed(x.mean_err_dph, 3), fixed(x.peak_err_dph, 3), fixed(x.t1_c, 2), fixed(x.t2_c, 2), fixed(x.ta_c, 2),
               fixed(x.rate_c_per_min, 3), fixed(x.grad_c, 3)});
      text += f.str() + "(errors in deg/h: measured - predicted)\n\n";
    }
  }
  if (o.json) {
    out << nlohmann::json{{"model", o.model}, {"terms", m->terms_string()}, {"runs", results}, {"adequate", adequate},
                          {"data_quality", quality.flags}}.dump() << "\n";
  } else {
    out << "compare: " << model_label(o.model) << " (" << m->terms_string() << ")\n\n";
    for (const auto& l : quality.lines) out << "warning: " << l << "\n";
    if (!quality.lines.empty()) out << "\n";
    out << text;
    if (!adequate) {
      out << "next: find the missing effect with\n  fogctl diagnose --model " << o.model;
      for (const auto& r : o.runs) out << " " << r;
      out << "\n(the first run is refitted, the others score the candidates as held-out runs)\n";
    }
  }
  return adequate ? kExitOk : kExitFailed;
}

int run_diagnose(const DiagnoseCommandOptions& o, std::ostream& out, std::ostream& err) {
  if (o.model.empty() || o.runs.empty()) {  // both optional on the command line, with --run N
    err << "fogctl diagnose: " << (o.model.empty() ? "--model MODEL.json is required (or --run N: the unit's current model)" : "which runs? give CSV files, or --run N")
        << "\n";
    return kExitError;
  }
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl diagnose: " << m.error() << "\n";
    return kExitError;
  }
  QualityLog quality;
  if (auto one = check_one_gyro(o.runs, o.input.quality, quality.lines); !one) {
    err << "fogctl diagnose: " << one.error() << "\n";
    return kExitError;
  }
  {  // the limit's range as diagnose checks it (DiagnoseOptions::validate), before any file is read
    wb::DiagnoseOptions probe;
    probe.max_samples = o.max_samples;
    if (auto v = probe.validate(); !v) {
      err << "fogctl diagnose: " << as_typed(v.error(), {{"max_samples", "--max-samples"}}) << "\n";
      return kExitError;
    }
  }
  if (auto within = diagnose_rows_within(o.runs, o.input, o.max_samples); !within) {
    err << "fogctl diagnose: " << within.error() << "\n";
    return kExitError;
  }
  auto runs = load_runs(o.runs, with_model_axis(o.input, *m), &quality);
  if (!runs) {
    err << "fogctl diagnose: " << runs.error() << "\n";
    return kExitError;
  }
  wb::DiagnoseOptions dopt;
  dopt.max_samples = o.max_samples;
  dopt.extra_terms = o.candidates;
  dopt.max_lag_s = o.max_lag_s;
  if (o.search == "library") dopt.search = wb::DiagnoseOptions::Search::library;
  else if (o.search == "language") dopt.search = wb::DiagnoseOptions::Search::language;
  else {
    err << "fogctl diagnose: --search must be library or language, got '" << o.search << "'\n";
    return kExitError;
  }
  dopt.max_terms = o.max_terms;
  dopt.tau_points = o.tau_points;
  for (const auto& c : o.candidates)
    if (auto t = model::parse_term(c); !t) {
      err << "fogctl diagnose: --candidate: " << t.error().pretty() << "\n";
      return kExitError;
    } else if (auto s = model::run_signals(runs->front(), m->tref_c); s) {
      // A term the user asked for that the fit run cannot give (ton without since_power_on_s,
      // Ta without chamber_c) is bad input, not a candidate to skip: say so, exit 2.
      if (auto x = model::evaluate(*t->expr, s->view()); !x) {
        err << "fogctl diagnose: --candidate " << c << " on " << runs->front().name << ": " << x.error() << "\n";
        return kExitError;
      }
    }
  // The candidates on both cores (up to 4 threads): the same answer as one thread, sooner.
  dopt.threads = 0;
  // Progress on stderr for long work (a 3-day run takes a minute), never on stdout (--json
  // stays one object). On a terminal redrawn, nothing in the first half second, so that a short
  // diagnose shows none; in a file or a pipe a line per stage once it has taken 2 s (a short
  // diagnose writes nothing), from the start with --progress (then one every 5 s as well) or
  // FOGCTL_PROGRESS=lines.
  std::optional<Progress> bar;
  const auto t0 = std::chrono::steady_clock::now();
  const bool redraw = progress_redraws();
  {
    const bool from_start = o.progress || progress_lines_asked();
    const double quiet_s = from_start ? 0.0 : redraw ? 0.5 : 2.0;
    bar.emplace(err, redraw, o.progress ? 5.0 : 60.0);
    bar->set_width(progress_width());
    dopt.progress = [&, quiet_s](const wb::DiagnoseProgress& p) {
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (s < quiet_s) return;
      std::string text = "diagnose: step " + std::to_string(p.step) + ", " + p.stage;
      if (p.stage == "screening") text += " " + std::to_string(p.total) + " generated candidates";
      else if (p.total > 0) text += " candidate " + std::to_string(p.done) + " of " + std::to_string(p.total);
      text += " (" + fixed(s, 1) + " s)";
      bar->update(std::to_string(p.step) + " " + p.stage, text);
    };
  }
  auto d = wb::diagnose(*m, runs->front(), std::span<const model::RunData>(*runs).subspan(1), dopt);
  if (bar) bar->finish();
  if (!d) {
    err << "fogctl diagnose: "
        << as_typed(d.error().message, {{"max_terms", "--max-terms"}, {"tau_points", "--tau-points"}, {"max_lag_s", "--max-lag"}, {"max_samples", "--max-samples"}})
        << "\n";
    return kExitError;
  }
  // A sensor problem left in the data (--quality warn) is the answer, before any physical
  // term: what the search finds on such data is the fault's echo.
  const bool adequate = d->adequate && !quality.sensor_problem;
  if (o.json) {
    auto j = wb::to_json(*d);
    j["data_quality"] = quality.flags;
    j["sensor_problem"] = quality.sensor_problem;
    if (quality.sensor_problem) {
      j["adequate"] = false;
      j["headline"] = quality.headline;
    }
    out << j.dump() << "\n";
    return adequate ? kExitOk : kExitFailed;
  }
  out << "diagnose: " << model_label(o.model) << " (" << d->model_terms << ", " << d->method << " method) refitted on " << d->fit_run;
  if (d->base_refitted_on_other_run) out << " (the model was fitted on other data: " << m->fitted_on.name << ")";
  out << "\n\n";
  if (quality.sensor_problem)
    out << "NOT ADEQUATE: " << quality.headline << ", not a physical effect: the search below ran on faulty data "
        << "(--quality warn) and what it names may be the fault's echo\n\n";
  for (const auto& l : quality.lines) out << "warning: " << l << "\n";
  if (!quality.lines.empty()) out << "\n";
  out << (d->adequate ? "ADEQUATE: " : "NOT ADEQUATE: ") << d->summary << "\n\n";
  for (const auto& e : model::lags_at_edge(*m)) out << "warning: in the model as given, " << e << "\n\n";
  out << "adequacy of " << d->model_terms << " (Ljung-Box p >= " << fixed(dopt.adequacy_alpha, 3) << ", comp std <= "
      << fixed(dopt.failing.noise.max_noise_factor, 2) << " x the gyro's noise std, no failing interval):\n";
  {
    Table at({"run", "role", "comp std", "noise std", "factor", "allowed", "Ljung-Box p", "failing intervals", "result"});
    for (const auto& c : d->checks)
      at.add({c.run, c.held_out ? "held out" : "fit", fixed(c.comp_std_dph, 3), fixed(c.noise_std_dph, 3), fixed(c.noise_factor, 2),
              fixed(c.noise_limit_factor, 2), c.ljung_box_p < 1e-4 ? "<1e-4" : fixed(c.ljung_box_p, 4), std::to_string(c.failures.size()),
              c.reasons.empty() ? "ok" : "FAILS"});
    out << at.str();
    // The yardstick: where the gyro's own noise was read and what it holds beyond AR(2).
    for (const auto& c : d->checks)
      if (!c.floor_note.empty()) out << "  noise floor of " << c.run << ": " << c.floor_note << "\n";
  }
  for (const auto& r : d->reasons) out << "  - " << r << "\n";
  // Drift that is not thermal: the figures behind the findings (the plots are in the report).
  if (d->time_drift.found) {
    const auto& td = d->time_drift;
    out << "\ndrift in time (ageing/outgassing, not thermal): slope " << fixed(td.slope_dph_per_h, 4) << " deg/h per h, 1 sigma "
        << fixed(td.se_dph_per_h, 4) << " (t " << fixed(td.t, 1) << " against the gyro's noise floor), runs agree: p "
        << fixed(td.consistency_p, 3) << (td.named ? ", named by the search (trun)" : "")
        << (td.collinear ? ", NOT separable from temperature on these runs" : "") << "\n";
    Table tt({"run", "slope deg/h per h", "1 sigma"});
    for (const auto& r : td.runs) tt.add({r.run, fixed(r.slope_dph_per_h, 4), fixed(r.se_dph_per_h, 4)});
    out << tt.str();
  }
  if (!d->periodic.empty()) {
    out << "\nperiodic disturbance (the residual's spectral peak against the gyro's noise):\n";
    Table pt({"run", "period s", "amplitude deg/h", "peak / noise", "p", "std before", "std after", "thermal period"});
    for (const auto& p : d->periodic)
      pt.add({p.run, fixed(p.period_s, 0), fixed(p.amplitude_dph, 3), fixed(p.power_ratio, 1), p.p_value < 1e-6 ? "<1e-6" : sig(p.p_value),
              fixed(p.rms_before_dph, 3), fixed(p.rms_after_dph, 3), p.thermal_period ? "yes" : "no"});
    out << pt.str();
  }
  if (!d->steps.empty()) {
    out << "\nsearch (" << d->search << ", " << d->search_space.value("total", 0) << " candidates, "
        << d->search_space.value("refitted", 0) << " refitted): terms found, each validated on the held-out runs:\n";
    for (std::size_t i = 0; i < d->steps.size(); ++i) {
      const auto& st = d->steps[i];
      out << "  " << i + 1 << ". " << st.added << "  " << st.effect << (st.library ? "" : " [not in the library]") << "  fit run "
          << fixed(st.rms_before_dph, 3) << " -> " << fixed(st.rms_after_dph, 3);
      for (const auto& h : st.held_out)
        if (h.scored) out << ", " << h.run << " " << fixed(h.rms_before_dph, 3) << " -> " << fixed(h.rms_after_dph, 3);
      const CommandForm mf = command_form(o.model);
      if (i == 0 && !mf.fetch.empty()) out << "\n     first: " << mf.fetch;
      out << "\n     add it: fogctl fit --model " << (i ? "model" + std::to_string(i + 1) + ".json" : mf.arg) << " --add \"" << st.added
          << "\" " << command_form(o.runs.front()).arg << " -o model" << i + 2 << ".json\n";
    }
    out << "  model with them: " << d->final_terms << (d->outside_search ? " (something still remains: outside the search)" : " (adequate)") << "\n";
  }
  out << "\ncoefficients (1 sigma):\n";
  Table ct({"term", "coef", "se", "unit"});
  for (const auto& c : d->coefs) ct.add({c.term, sig(c.coef), sig(c.se_in_unit), c.unit});
  out << ct.str();
  for (const auto& p : d->collinear_coefs)
    out << "collinear: " << p.a << " and " << p.b << " (r = " << fixed(p.r, 3) << "): " << p.why << "\n";
  const auto& w = d->whiteness;
  out << "\nresidual (prewhitened by the model's AR): Ljung-Box Q " << fixed(w.lb.q, 1) << " on " << w.lb.dof << " dof, p "
      << fixed(w.lb.p_value, 4) << (w.white() ? " (white)" : " (NOT white)") << "; ACF outside +-" << fixed(w.band, 3) << ": "
      << w.acf_outside << " of " << w.acf.size() << " lags, PACF " << w.pacf_outside << "\n\n";
  out << "candidates, best first (rms = compensated std, deg/h; held-out: the refitted model applied unchanged):\n";
  std::vector<std::string> head{"#", "term", "effect", "rms fit", "fall", "dBIC", "p"};
  for (const auto& h : d->held_out_runs) head.push_back("rms " + h);
  head.push_back("verdict");
  Table t(head);
  int rank = 0;
  std::string skipped;
  for (const auto& c : d->candidates) {
    if (!c.evaluated) {
      skipped += "  " + c.term + " (" + c.effect + "): " + c.skipped + "\n";
      continue;
    }
    std::vector<std::string> row{std::to_string(++rank), c.term, c.effect, fixed(c.rms_before_dph, 3) + " -> " + fixed(c.rms_after_dph, 3),
                                 pct(c.fall), fixed(c.delta_bic, 1), c.p_value < 1e-4 ? "<1e-4" : fixed(c.p_value, 4)};
    for (const auto& h : c.held_out)
      row.push_back(h.scored ? fixed(h.rms_before_dph, 3) + " -> " + fixed(h.rms_after_dph, 3) : "skipped");
    row.push_back(!c.detected ? "-" : rank == 1 ? "MISSING" : "helps too");
    t.add(row);
  }
  out << t.str();
  for (const auto& c : d->candidates)
    for (const auto& h : c.held_out)
      if (!h.scored) out << "note: " << c.term << " not scored on " << h.run << ": " << h.skipped << "\n";
  if (!skipped.empty()) out << "skipped:\n" << skipped;
  for (const auto& c : d->candidates)
    if (c.detected && !c.collinear_with.empty()) {
      out << "look-alikes: " << c.term << " cannot be told from";
      for (const auto& x : c.collinear_with) out << " " << x;
      out << " on these runs: " << c.separate_by << "\n";
    }
  // The headline's term: the first the search adds (the same in summary, reasons and here).
  if (!d->steps.empty()) {
    const auto& st = d->steps.front();
    for (const auto& b : d->candidates)
      if (b.expr == st.expr) {
        out << "\nwhy " << b.expr << ": " << b.explanation << "\n";
        break;
      }
    const CommandForm mf = command_form(o.model);
    if (!mf.fetch.empty()) out << "first: " << mf.fetch << "\n";
    out << "add it: fogctl fit --model " << mf.arg << " --add \"" << st.added << "\" " << command_form(o.runs.front()).arg
        << " -o model2.json\n";
  }
  out << "\ncross-correlation of the prewhitened residual with each regressor (lags 0.." << (d->ccf.empty() || d->ccf[0].r.empty() ? 0 : d->ccf[0].r.size() - 1)
      << " s, band +-" << (d->ccf.empty() ? "-" : fixed(d->ccf[0].band, 3)) << "):\n";
  Table x({"term", "peak r", "at lag s", "lags outside band"});
  for (const auto& c : d->ccf)
    x.add({c.term, fixed(c.peak_r, 3), std::to_string(c.peak_lag_s), std::to_string(c.outside) + " of " + std::to_string(c.r.size())});
  out << x.str() << "\nrule: " << d->rule << "\n";
  return adequate ? kExitOk : kExitFailed;
}

int run_fit_add(const FitAddOptions& o, std::ostream& out, std::ostream& err) {
  if (o.model.empty() || o.add.empty()) {
    err << "fogctl fit: --model and --add go together: --model M --add TERM refits M's terms plus TERM\n";
    return kExitError;
  }
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl fit: " << m.error() << "\n";
    return kExitError;
  }
  auto run = load_run(o.run, with_model_axis(o.input, *m));
  if (!run) {
    err << "fogctl fit: " << run.error() << "\n";
    return kExitError;
  }
  if (m->axis.value_or(model::Axis::x) != run->gyro_axis()) {
    err << "fogctl fit: --add: " << o.model << " is a model of axis " << model::to_string(m->axis.value_or(model::Axis::x)) << ", --axis "
        << model::to_string(run->gyro_axis()) << " asks for another: a model extends on its own axis\n";
    return kExitError;
  }
  // A term the model has already, given without a lag (d(T1) when the model has d(T1)@120), is
  // said as such rather than left to the fit to find collinear. With an explicit other lag it is
  // a second thermal path, which add_term takes (and refuses at the same lag or @auto).
  if (auto t = model::parse_term(o.add); t && o.add.find('@') == std::string::npos) {
    const std::string name = model::to_string(*t, false);
    for (const auto& ft : m->terms)
      if (ft.name() == name) {
        const int other = ft.term.lag.seconds + 120;
        err << "fogctl fit: --add " << o.add << ": the model already has the term " << name << " (at lag "
            << ft.term.lag.seconds << " s: " << m->terms_string() << "); to add it again as a second thermal path give "
            << "it a fixed lag, e.g. " << name << "@" << other << "\n";
        return kExitError;
      }
  }
  auto r = wb::add_term(*m, *run, o.add);
  if (!r) {
    err << "fogctl fit: " << r.error().message << "\n";
    return kExitError;
  }
  r->model.created_at = now_iso8601();
  const nlohmann::json j = model::to_json(r->model);
  if (!o.output.empty()) {
    if (auto w = write_text(o.output, j.dump(2) + "\n"); !w) {
      err << "fogctl fit: " << w.error() << "\n";
      return kExitError;
    }
  }
  if (o.json) {
    out << j.dump() << "\n";
    return kExitOk;
  }
  const auto before = model::verify(*m, *run);
  const auto after = model::verify(r->model, *run);
  out << "added " << r->added << ": " << r->model.terms_string() << " (" << to_string(r->model.method) << " method), parent "
      << m->terms_string() << "\n\n";
  Table t({"term", "lag_s", "coef", "se (1 sigma)", "unit"});
  t.add({"mu0", "", fixed(r->model.mu0_dph, 3), fixed(r->model.mu0_se_dph, 3), "deg/h"});
  for (const auto& ft : r->model.terms)
    t.add({ft.name(), std::to_string(ft.term.lag.seconds), sig(ft.coef), sig(ft.se_dph_per_unit), coef_unit(*ft.term.expr)});
  out << t.str();
  if (before && after)
    out << "\ncompensated std on " << o.run << ": " << fixed(before->run.comp_std, 3) << " -> " << fixed(after->run.comp_std, 3)
        << " deg/h; BIC " << fixed(m->fit.bic, 1) << " -> " << fixed(r->model.fit.bic, 1) << "\n";
  for (const auto& n : r->notes) out << "note: " << n << "\n";
  for (const auto& e : model::lags_at_edge(r->model)) out << "warning: " << e << "\n";
  if (!o.output.empty()) out << "model written to " << o.output << "\n";
  return kExitOk;
}

int run_lineage(const LineageOptions& o, std::ostream& out, std::ostream& err) {
  auto m = load_model(o.model);
  if (!m) {
    err << "fogctl lineage: " << m.error() << "\n";
    return kExitError;
  }
  std::vector<std::string> warnings;
  if (auto one = check_one_gyro(o.runs, o.input.quality, warnings); !one) {
    err << "fogctl lineage: " << one.error() << "\n";
    return kExitError;
  }
  for (const auto& w : warnings) err << "warning: " << w << "\n";
  auto runs = load_runs(o.runs, with_model_axis(o.input, *m));  // the model's axis of a three-axis run
  if (!runs) {
    err << "fogctl lineage: " << runs.error() << "\n";
    return kExitError;
  }
  const wb::Lineage l = wb::lineage(*m, *runs);
  if (o.json) {
    out << wb::to_json(l).dump() << "\n";
    return kExitOk;
  }
  out << "lineage of " << o.model << ", root first: compensated std, deg/h\n\n";
  std::vector<std::string> head{"#", "terms"};
  for (const auto& r : o.runs) head.push_back(r);
  head.push_back("note");
  Table t(head);
  for (std::size_t i = 0; i < l.steps.size(); ++i) {
    const auto& s = l.steps[i];
    std::vector<std::string> row{std::to_string(i), s.terms};
    for (double v : s.comp_std_dph) row.push_back(fixed(v, 3));
    row.push_back(s.note);
    t.add(row);
  }
  out << t.str();
  for (std::size_t i = 0; i < l.steps.size(); ++i)
    for (std::size_t r = 0; r < l.steps[i].errors.size(); ++r)
      if (!l.steps[i].errors[r].empty()) out << "step " << i << " on " << o.runs[r] << ": " << l.steps[i].errors[r] << "\n";
  return kExitOk;
}

void add_workbench_commands(CLI::App& app, int& code) {
  static CompareCommandOptions cmp;
  auto* c = app.add_subcommand("compare", "Where a model fails on runs: Table 1 per phase and step, failing intervals");
  c->add_option("--model", cmp.model, "The model's JSON file")->required();
  c->add_option("runs", cmp.runs, "The runs' CSV files")->required();
  c->add_option("--k-sigma", cmp.k_sigma, "Failing where the smoothed residual is beyond k sigma_a and the floor's slow noise (default 3)");
  c->add_option("--smooth", cmp.smooth_s, "Residual smoother width, s, odd (default 61)");
  c->add_option("--min-duration", cmp.min_duration_s, "Shortest failing interval reported, s (default 60)");
  c->add_flag("--json", cmp.json, "Print one JSON object");
  c->add_flag("--series", cmp.series, "With --json: include the measured, predicted and residual series");
  add_run_input(c, cmp.input);
  c->callback([&] {
    std::ostringstream text;
    code = run_compare(cmp, text, std::cerr);
    // Prose within the terminal's width (issue 28); JSON as it is.
    std::cout << (cmp.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });

  static DiagnoseCommandOptions dia;
  auto* d = app.add_subcommand("diagnose", "Why a model fails: whiteness, coefficients, and the missing effect from the library");
  d->add_option("--model", dia.model, "The model's JSON file")->required();
  d->add_option("runs", dia.runs, "The fit run's CSV, then held-out runs")->required();
  d->add_option("--candidate", dia.candidates, "A further candidate term beyond the library (repeatable)");
  d->add_option("--max-lag", dia.max_lag_s, "Longest lag searched, s (default: the model's; lower it for short runs)");
  d->add_option("--search", dia.search, "library (the effects library) or language (the term language, default)");
  d->add_option("--max-terms", dia.max_terms, "Greedy forward selection: terms added at most, 1 to 6 (default 5)");
  d->add_option("--tau-points", dia.tau_points, "Time constants of lp and warm on a log grid 30 s to 4 h (default 12)");
  d->add_option("--max-samples", dia.max_samples,
                "The runs' samples in all, at most (default 2000000: about 2 GB); larger runs are refused before they are read");
  d->add_flag("--json", dia.json, "Print one JSON object");
  d->add_flag("--progress", dia.progress, "Progress lines on stderr even when it is not a terminal (on a terminal they are drawn anyway)");
  add_run_input(d, dia.input);
  add_axis_option(d, dia.input);
  d->callback([&] {
    std::ostringstream text;
    code = run_diagnose(dia, text, std::cerr);
    // Prose within the terminal's width (issue 28); JSON as it is.
    std::cout << (dia.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });

  static LineageOptions lin;
  auto* l = app.add_subcommand("lineage", "The error of each model of a lineage (root first) on runs");
  l->add_option("model", lin.model, "The model's JSON file")->required();
  l->add_option("runs", lin.runs, "The runs' CSV files")->required();
  l->add_flag("--json", lin.json, "Print one JSON object");
  add_run_input(l, lin.input);
  l->callback([&] {
    std::ostringstream text;
    code = run_lineage(lin, text, std::cerr);
    // Prose within the terminal's width (issue 28); JSON as it is.
    std::cout << (lin.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });

  static ReportOptions rep;
  auto* r = app.add_subcommand("report", "One self-contained HTML report: profile, drift, residual, diagnosis, lineage, qualification");
  r->add_option("--model", rep.model, "The model's JSON file")->required();
  r->add_option("runs", rep.runs, "The fit run's CSV, then held-out runs")->required();
  r->add_option("-o,--output", rep.output, "The HTML file to write")->required();
  r->add_option("--threshold", rep.threshold, "Pass when compensated std / raw std is under this (default 0.2)");
  r->add_option("--max-points", rep.max_points, "Plotted samples per series at most (default 3000)");
  r->add_option("--scale-factor", rep.scale_factor,
                "A rate-sequence CSV of the unit (fogctl scale-factor's input): adds its scale factor over temperature, with plots");
  add_run_input(r, rep.input);
  r->callback([&] { code = run_report(rep, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
