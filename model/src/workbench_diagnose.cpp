// diagnose's step and add: which effect of the library a model misses, scored by refitting the
// model with each candidate (same method) on the fit run and applying it unchanged to held-out
// runs. diagnose_once runs the stages below in order; one candidate's evaluation is
// workbench_candidate.cpp, the search around the step workbench_search.cpp.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <future>
#include <memory>
#include <numeric>
#include <optional>
#include <thread>
#include <tuple>

#include "workbench_step.hpp"

namespace fogbench::model::workbench {

void sort_detected_first(std::vector<Candidate>& candidates) {
  std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    auto rank = [](const Candidate& c) { return c.detected ? 0 : c.evaluated ? 1 : 2; };
    if (rank(x) != rank(y)) return rank(x) < rank(y);
    if (rank(x) < 2) return x.delta_bic < y.delta_bic;
    return false;
  });
}

using detail::fail;

namespace wbi {
namespace {

// The base model's coefficients, standard errors and correlations, and the pairs too
// correlated to be told apart on this run (why, for the pair the paper's model is known for).
void report_coefficients(const Model& base, Diagnosis& d) {
  d.coefs.push_back({"mu0", base.mu0_dph, base.mu0_se_dph, "deg/h"});
  for (const auto& ft : base.terms)
    d.coefs.push_back({with_lag(ft.name(), ft.term.lag.seconds), ft.coef, ft.se_dph_per_unit, coef_unit(*ft.term.expr)});
  d.coef_corr = base.fit.coef_corr;
  for (std::size_t a = 1; a < d.coef_corr.size(); ++a)
    for (std::size_t b = a + 1; b < d.coef_corr.size(); ++b) {
      const double r = d.coef_corr[a][b];
      if (std::abs(r) <= 0.9) continue;
      const std::string ka = term_key(base.terms[a - 1].term), kb = term_key(base.terms[b - 1].term);
      std::string why = "this run barely tells them apart: only their combination is well determined";
      if ((ka == "d(T1)" && kb == "grad") || (ka == "grad" && kb == "d(T1)"))
        why = "on steady ramps the coil's gradient follows its rate (on a two-node coil grad = -core_tau * dT1/dt "
              "exactly), so the two betas are collinear: a hold right after a fast ramp, where the gradient decays "
              "while the rate is zero, separates them";
      d.collinear_coefs.push_back({d.coefs[a].term, d.coefs[b].term, r, why});
    }
}

// The fit run's signals (sig: the fit run's scorer's, shared), weights and the base model's
// regressors at their fitted lags.
std::expected<FitRun, FitError> prepare_fit_run(const Model& base, const RunData& fit_run, std::shared_ptr<const RunSignals> sig) {
  FitRun fr;
  if (!sig) {
    auto s = run_signals(fit_run, base.tref_c);
    if (!s) return std::unexpected(s.error());
    sig = std::make_shared<const RunSignals>(std::move(*s));
  }
  fr.sig = std::move(sig);
  fr.w = detail::good_weights(fit_run);
  auto bc = regressors(base, fit_run);
  if (!bc) return std::unexpected(bc.error());
  fr.base_cols = std::move(*bc);
  return fr;
}

// The residual of the base model on the fit run, prewhitened by its AR filter: its whiteness
// (d.whiteness) and its cross-correlations with every effect of the library (d.ccf).
std::expected<void, FitError> check_residual(const Model& base, const RunData& fit_run, const FitRun& fr, const DiagnoseOptions& o,
                                             Diagnosis& d) {
  // Whiteness of the residual prewhitened by the model's AR filter.
  auto mu = predict(base, fit_run);
  if (!mu) return std::unexpected(mu.error());
  const std::size_t n = fit_run.size();
  std::vector<double> e(n);
  for (std::size_t t = 0; t < n; ++t) e[t] = fr.w[t] != 0.0 ? fit_run.gyro_dph[t] - (*mu)[t] : 0.0;
  // Outliers (3 sigma) would dominate a correlation: they get weight 0 (value 0 in e).
  std::vector<double> wccf = fr.w;
  {
    std::vector<double> r;
    for (std::size_t t = 0; t < n; ++t)
      if (fr.w[t] != 0.0) r.push_back(e[t]);
    const OutlierResult ro = outliers_3sigma(r, 3.0);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t)
      if (fr.w[t] != 0.0 && !ro.keep[j++]) {
        wccf[t] = 0.0;
        e[t] = 0.0;
      }
  }
  std::vector<double> a = ar_filter(e, base.ar);
  {
    std::vector<double> used;
    for (std::size_t t = base.ar.size(); t < n; ++t)
      if (wccf[t] != 0.0) used.push_back(a[t]);
    d.whiteness = whiteness(used, o.whiteness_lags, static_cast<int>(base.ar.size()));
  }

  // Cross-correlations (MATLAB resid style): residual and regressor both through the
  // model's AR filter; the prewhitened residual is white when the model is adequate, and
  // then the sample CCF of it with any series independent of it lies in +-2/sqrt(N).
  const int Lc = std::max(0, std::min<int>(o.ccf_max_lag_s, static_cast<int>(n) / 2));
  {
    double sw = 0.0, ma = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      sw += wccf[t];
      ma += wccf[t] * a[t];
    }
    ma /= std::max(1.0, sw);
    std::vector<double> wa(n);
    double saa = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      wa[t] = wccf[t] * (a[t] - ma);
      saa += wa[t] * (a[t] - ma);
    }
    detail::LagScanner sc(n, Lc, wccf);
    const detail::Spectrum aspec = sc.spectrum_of_target(wa);
    for (const auto& eff : effects_library()) {
      auto t = parse_term(eff.term);
      if (!t) continue;
      auto x = evaluate(*t->expr, fr.sig->view());
      if (!x) continue;
      std::vector<double> xf = ar_filter(*x, base.ar);
      const double mx = std::accumulate(xf.begin(), xf.end(), 0.0) / static_cast<double>(n);
      double sxx = 0.0;
      for (double& v : xf) {
        v -= mx;
        sxx += v * v;
      }
      CrossCorrelation cc;
      cc.term = to_string(*t->expr);
      cc.band = white_band(static_cast<std::size_t>(sw));
      if (!(sxx > 0.0) || !(saa > 0.0)) {
        d.ccf.push_back(cc);
        continue;
      }
      const std::vector<double> c = sc.corr(detail::make_lagged(xf, Lc), aspec);
      cc.r.resize(c.size());
      for (std::size_t i = 0; i < c.size(); ++i) {
        cc.r[i] = c[i] / std::sqrt(saa * sxx);
        if (std::abs(cc.r[i]) > cc.band) ++cc.outside;
        if (std::abs(cc.r[i]) > std::abs(cc.peak_r)) {
          cc.peak_r = cc.r[i];
          cc.peak_lag_s = static_cast<int>(i);
        }
      }
      d.ccf.push_back(std::move(cc));
    }
  }
  return {};
}

// The candidates: the library's terms the model lacks, each model term again at a second
// lag, the extra terms asked for, then the language search's (from n_fixed on).
struct CandidateList {
  std::vector<Cand> cands;
  std::size_t n_fixed = 0;  // the first n_fixed are the library's, second lags and extras
};
std::expected<CandidateList, FitError> collect_candidates(const Model& base, const DiagnoseOptions& o, const std::vector<Generated>& gen,
                                                          const RunData& fit_run) {
  std::vector<Cand> cands;
  auto push = [&](const std::string& text, std::string effect, std::string expl, bool repeat) {
    auto t = parse_term(text);
    if (!t) return;
    Cand c{*t, to_string(*t->expr), std::move(effect), std::move(expl), repeat, false, {}};
    c.term.coef = 1.0;
    c.term.coef_given = false;
    for (const auto& x : cands)
      if (x.expr == c.expr && x.repeat == c.repeat) return;
    cands.push_back(std::move(c));
  };
  for (const auto& eff : effects_library()) {
    auto t = parse_term(eff.term);
    if (t && !has_key(base, to_string(*t->expr))) push(eff.term, eff.name, eff.explanation, false);
  }
  // A three-axis unit whose axes have their own coil thermistors: the other axes' coils too.
  if (fit_run.has_axis_thermistors())
    for (const auto& eff : cross_axis_effects(fit_run.gyro_axis())) {
      auto t = parse_term(eff.term);
      if (t && !has_key(base, to_string(*t->expr))) push(eff.term, eff.name, eff.explanation, false);
    }
  if (o.second_lags)
    for (const auto& ft : base.terms) {
      const std::string k = term_key(ft.term);
      // The run's clock has no second path: trun at another delay is trun again (a constant
      // apart), and the two would split one slope between them.
      if (k == "trun") continue;
      const Effect* eff = find_effect(k);
      push(k, "a second thermal path: " + (eff ? eff->name : k) + " again at another delay",
           "heat reaches the fibre by more than one path (through the flange and through the housing), each with its own delay",
           true);
    }
  for (const auto& x : o.extra_terms) {
    auto t = parse_term(x);
    if (!t) return fail(FitError::Code::bad_term, "extra candidate: " + t.error().pretty());
    const std::string k = to_string(*t->expr);
    if (has_key(base, k)) continue;
    const Effect* eff = find_effect(k);
    if (k == "trun") push(x, kTimeDriftName, kTimeDriftExplanation, false);
    else push(x, eff ? eff->name : "user term " + k, eff ? eff->explanation : "", false);
  }

  const std::size_t n_fixed = cands.size();
  for (const auto& g : gen) {
    auto t = parse_term(g.expr);
    if (!t) return fail(FitError::Code::bad_term, "search candidate: " + t.error().pretty());
    const std::string k = to_string(*t->expr);
    if (has_key(base, k)) continue;
    bool dup = false;
    for (const auto& x : cands) dup = dup || (x.expr == k && !x.repeat);
    if (dup) continue;
    Cand c{*t, k, g.effect, g.explanation, false, true, {}};
    c.term.coef = 1.0;
    c.term.coef_given = false;
    cands.push_back(std::move(c));
  }
  return CandidateList{std::move(cands), n_fixed};
}

// The language's candidates (from n_fixed on) screened by their lag scan's gain: only the
// best o.refit_top, one per group of look-alikes, stay in the list.
void screen_generated(std::vector<Cand>& cands, std::size_t n_fixed, const CandidateScan& scan, const RunData& fit_run, const FitRun& fr,
                      const DiagnoseOptions& o, SearchStats* stats) {
  // The language's candidates are many (docs/workbench.md): each is scanned over its lags (a
  // few FFTs), and only the best by the fall of the squared error, one per group of
  // look-alikes (columns correlating beyond 0.99 with the model's terms regressed out), are
  // refitted and scored like the library's.
  if (cands.size() > n_fixed) {
    // Only the gain and lag of each are kept while scanning; the partial column (x with the
    // model's terms regressed out, as long as the run) is made for those the choice visits,
    // from the best down, and kept for the chosen only (at most o.refit_top).
    struct Screened {
      std::size_t i;
      CandidateScan::Gain g;
    };
    // The scans are independent: on o.threads threads (as evaluate_all), each into its own
    // slot, then gathered in the list's order (the same list as one thread makes).
    std::vector<std::optional<Screened>> slot(cands.size() - n_fixed);
    // The bare signals' rates, which about 40 of the 90 derivatives here are (products, up/down,
    // dd), computed once for the screen (the same numbers: RateMemo).
    RateMemo rates(fr.sig->view());
    {
      std::atomic<std::size_t> next{n_fixed};
      auto worker = [&] {
        for (std::size_t i = next++; i < cands.size(); i = next++) {
          if (!missing_signal_of(*cands[i].term.expr, fit_run).empty()) continue;
          auto x = evaluate(*cands[i].term.expr, fr.sig->view(), &rates);
          if (!x) continue;
          auto g = scan.scan(*x);
          if (!g) continue;
          slot[i - n_fixed] = Screened{i, *g};
        }
      };
      unsigned threads = o.threads > 0 ? static_cast<unsigned>(o.threads) : std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
      threads = std::min<unsigned>(threads, static_cast<unsigned>(slot.size()));
      std::vector<std::thread> pool;
      for (unsigned k = 1; k < threads; ++k) pool.emplace_back(worker);
      worker();
      for (auto& th : pool) th.join();
    }
    std::vector<Screened> sc;
    for (const auto& x : slot)
      if (x) sc.push_back(*x);
    if (stats) stats->scanned += sc.size();
    std::sort(sc.begin(), sc.end(), [](const Screened& x1, const Screened& x2) { return x1.g.best > x2.g.best; });
    std::vector<std::size_t> keep;
    std::vector<std::vector<double>> kept_cols;
    for (const auto& x : sc) {
      if (keep.size() >= static_cast<std::size_t>(o.refit_top)) break;
      auto v = evaluate(*cands[x.i].term.expr, fr.sig->view(), &rates);
      if (!v) continue;  // evaluated above: not reached
      std::vector<double> partial = scan.partial(lagged(*v, x.g.lag));
      bool alike = false;
      for (const auto& kc : kept_cols) alike = alike || std::abs(weighted_corr(partial, kc, fr.w)) > 0.99;
      if (alike) continue;
      keep.push_back(x.i);
      kept_cols.push_back(std::move(partial));
      // Its evaluation starts from this scan (the same scan, the same signals). Its column is
      // evaluated again there, not kept: up to refit_top run-length columns (21 MB on the 3-day
      // run) would otherwise wait here through every candidate's refits.
      cands[x.i].screened = x.g;
    }
    std::sort(keep.begin(), keep.end());
    std::vector<Cand> kept(cands.begin(), cands.begin() + static_cast<std::ptrdiff_t>(n_fixed));
    for (std::size_t i : keep) kept.push_back(std::move(cands[i]));
    cands = std::move(kept);
  }
}

// Every candidate evaluated, on o.threads threads (each with its own scorers: their column
// caches are not shared, the runs' signals, weights and phases are, and the refits' FitCache,
// fit_scorer's); fit_scorer and held_scorers serve the calling thread.
std::vector<EvaluatedCandidate> evaluate_all(const StepContext& ctx, std::vector<Cand>& cands, Scorer& fit_scorer,
                                             std::vector<Scorer>& held_scorers) {
  std::vector<EvaluatedCandidate> results(cands.size());
  unsigned threads = ctx.o.threads > 0 ? static_cast<unsigned>(ctx.o.threads) : std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
  threads = std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::size_t>(1, cands.size())));
  std::atomic<std::size_t> next{0}, done{0};
  // Progress is reported by the calling thread only (after each candidate it finishes).
  auto report = [&](std::size_t n) {
    if (ctx.o.progress) ctx.o.progress(DiagnoseProgress{"refitting", 0, n, cands.size()});
  };
  report(0);
  // One cache of the fit run's refits for all the threads (made here, before they start): each
  // uses what the others computed (the base's columns, sums and first step), the same numbers.
  detail::FitCache& fc = fit_scorer.fit_cache(ctx.fo.max_lag_s);
  // The fit run's scorers read the term columns there (the refits hold them anyway).
  fit_scorer.read_columns_from(&fc);
  auto worker = [&](Scorer& fs, std::vector<Scorer>& hs, bool caller) {
    for (std::size_t ci = next++; ci < cands.size(); ci = next++) {
      results[ci] = evaluate_candidate(ctx, cands[ci], fs, hs, fc);
      const std::size_t n = ++done;
      if (caller) report(n);
    }
  };
  std::vector<std::thread> pool;
  std::vector<std::unique_ptr<Scorer>> fit_scorers;
  std::vector<std::vector<Scorer>> held_sets(threads);
  for (unsigned k = 1; k < threads; ++k) {
    fit_scorers.push_back(std::make_unique<Scorer>(fit_scorer.sibling()));
    fit_scorers.back()->read_columns_from(&fc);
    held_sets[k].reserve(held_scorers.size());
    for (const auto& h : held_scorers) held_sets[k].push_back(h.sibling());
  }
  for (unsigned k = 1; k < threads; ++k) pool.emplace_back(worker, std::ref(*fit_scorers[k - 1]), std::ref(held_sets[k]), false);
  worker(fit_scorer, held_scorers, true);
  for (auto& th : pool) th.join();
  fit_scorer.read_columns_from(nullptr);
  if (done.load() > 0) report(done.load());
  return results;
}

// Look-alikes among the detected (collinear_with, separate_by) from their partial columns.
void mark_look_alikes(Diagnosis& d, const std::vector<std::vector<double>>& partial_cols, const FitRun& fr, const Model& base,
                      const DiagnoseOptions& o) {
  // Collinear look-alikes among the detected: their columns, with the model's terms regressed
  // out, correlate so that these profiles cannot tell one from the other.
  // Each pair's two correlations (r(i, j) and r(j, i), rounded apart) in one pass over the two
  // columns, each column's mean and sum of squares once: weighted_corr's numbers exactly.
  const std::size_t nc = d.candidates.size();
  auto used = [&](std::size_t i) { return d.candidates[i].detected && !partial_cols[i].empty(); };
  std::vector<CorrStats> st(nc);
  for (std::size_t i = 0; i < nc; ++i)
    if (used(i)) st[i] = corr_stats(partial_cols[i], fr.w);
  std::vector<double> rr(nc * nc, 0.0);
  for (std::size_t i = 0; i < nc; ++i)
    for (std::size_t j = i + 1; j < nc; ++j)
      if (used(i) && used(j)) std::tie(rr[i * nc + j], rr[j * nc + i]) = weighted_corr_pair(partial_cols[i], st[i], partial_cols[j], st[j], fr.w);
  for (std::size_t i = 0; i < d.candidates.size(); ++i) {
    auto& ci = d.candidates[i];
    if (!ci.detected || partial_cols[i].empty()) continue;
    for (std::size_t j = 0; j < d.candidates.size(); ++j) {
      const auto& cj = d.candidates[j];
      if (i == j || !cj.detected || partial_cols[j].empty()) continue;
      const double r = rr[i * nc + j];  // weighted_corr(partial_cols[i], partial_cols[j], fr.w)
      if (std::abs(r) < o.collinear_r) continue;
      ci.collinear_with.push_back(cj.term);
      // up(x) + down(x) = x: with x in the model the two are one effect written two ways.
      auto inner = [](const std::string& expr, const char* f) {
        const std::string p = std::string(f) + "(";
        return expr.rfind(p, 0) == 0 && expr.back() == ')' ? expr.substr(p.size(), expr.size() - p.size() - 1) : std::string();
      };
      const std::string xa = inner(ci.expr, "up").empty() ? inner(ci.expr, "down") : inner(ci.expr, "up");
      const std::string xb = inner(cj.expr, "up").empty() ? inner(cj.expr, "down") : inner(cj.expr, "up");
      if (ci.separate_by.empty() && !xa.empty() && xa == xb && ci.expr != cj.expr && has_key(base, xa)) {
        ci.separate_by = "with " + xa + " in the model, " + ci.expr + " and " + cj.expr + " are the same asymmetry written two ways (up(x) + down(x) = x): no profile separates them and either will do";
      }
      if (ci.separate_by.empty()) {
        const Effect* ea = find_effect(ci.expr);
        const Effect* eb = find_effect(cj.expr);
        const std::string how = ea ? ea->separated_by : eb ? eb->separated_by : "a profile step where the two move differently";
        ci.separate_by = how + " separates " + ci.expr + " from " + cj.expr + " (their columns correlate at r = " + fmt(r, 3) + " here)";
      }
    }
  }
}

void rank_candidates(Diagnosis& d, const DiagnoseOptions& o) {
  sort_detected_first(d.candidates);
  // Look-alikes the data cannot rank (BIC within o.tie_bic of the best, columns collinear):
  // the first of them in the library, which lists effects from the most direct (the coil's
  // own temperature) to the most remote (the air, slow paths), is named first.
  if (!d.candidates.empty() && d.candidates.front().detected) {
    auto lib_index = [](const Candidate& c) {
      const auto& lib = effects_library();
      for (std::size_t i = 0; i < lib.size(); ++i)
        if (c.expr == lib[i].term && !c.second_lag) return i;
      return lib.size();
    };
    const Candidate& top = d.candidates.front();
    std::size_t pick = 0;
    for (std::size_t i = 1; i < d.candidates.size(); ++i) {
      const Candidate& c = d.candidates[i];
      if (!c.detected || c.delta_bic - top.delta_bic >= o.tie_bic) continue;
      if (std::find(top.collinear_with.begin(), top.collinear_with.end(), c.term) == top.collinear_with.end()) continue;
      if (lib_index(c) < lib_index(d.candidates[pick])) pick = i;
    }
    if (pick) std::rotate(d.candidates.begin(), d.candidates.begin() + static_cast<std::ptrdiff_t>(pick),
                          d.candidates.begin() + static_cast<std::ptrdiff_t>(pick) + 1);
  }
}

// adequate, the detection rule in words, and the summary for people.
void summarize(Diagnosis& d, bool no_held_out, const DiagnoseOptions& o) {
  d.adequate = d.candidates.empty() || !d.candidates.front().detected;
  d.rule = no_held_out
               ? "detected when, refitted with the model: delta BIC < " + fmt(o.max_delta_bic_alone, 0) + ", p < " +
                     fmt(o.max_p_value, 4) + " and the compensated std of the fit run falls by at least " +
                     fmt(100.0 * o.min_fit_fall_alone, 0) + "% (stricter: no held-out run was given)"
               : "detected when, refitted with the model: delta BIC < " + fmt(o.max_delta_bic, 0) + ", p < " +
                     fmt(o.max_p_value, 4) + ", the compensated std of the fit run falls by at least " +
                     fmt(100.0 * o.min_fit_fall, 0) + "% and that of every held-out run by at least " +
                     fmt(100.0 * o.min_held_out_fall, 0) + "% (the refitted model applied unchanged)";
  if (d.adequate) {
    d.summary = "No effect of the library improves the model " + d.model_terms + " on these runs: it is adequate (compensated std " +
                fmt(d.rms_fit_dph, 3) + " deg/h on " + d.fit_run + ").";
  } else {
    const Candidate& b = d.candidates.front();
    d.summary = "Missing effect: " + b.effect + ", term " + b.term + ". Adding it takes the compensated std on " + d.fit_run +
                " from " + fmt(b.rms_before_dph, 3) + " to " + fmt(b.rms_after_dph, 3) + " deg/h";
    for (const auto& h : b.held_out)
      if (h.scored) d.summary += ", on " + h.run + " from " + fmt(h.rms_before_dph, 3) + " to " + fmt(h.rms_after_dph, 3);
    d.summary += ".";
    if (!b.collinear_with.empty()) {
      d.summary += " These profiles cannot tell it from";
      for (std::size_t i = 0; i < b.collinear_with.size(); ++i) d.summary += (i ? ", " : " ") + b.collinear_with[i];
      d.summary += ": " + b.separate_by + ".";
    }
  }
  if (!d.whiteness.white() && d.adequate)
    d.summary += " The residual is not white (Ljung-Box p " + fmt(d.whiteness.lb.p_value, 4) +
                 "): something outside the library, or the noise order, may be missing.";
}

}  // namespace
}  // namespace wbi

using namespace wbi;

FitOptions options_of(const Model& m) {
  FitOptions o;
  o.method = m.method;
  o.ar_order = std::max<int>(1, static_cast<int>(m.ar.size()));
  o.max_lag_s = m.max_lag_s;
  o.tref_c = m.tref_c;
  o.smooth_s = m.smooth_s;
  o.hold_s = m.hold_s;
  return o;
}

TermList terms_of(const Model& m) {
  TermList tl;
  for (const auto& ft : m.terms) tl.terms.push_back(ft.term);
  tl.paper = m.method == Method::paper && m.shared_lag && m.terms.size() == 2 && term_key(m.terms[0].term) == "d(T1)" &&
             term_key(m.terms[1].term) == "grad";
  return tl;
}

std::string missing_signal_of(const Expr& e, const RunData& run) {
  if (uses_signal(e, Signal::Ta) && !run.has_chamber())
    return "needs Ta, the chamber air temperature, which " + run.name + " did not record (no chamber_c column)";
  if (uses_signal(e, Signal::ton) && !run.has_power_on())
    return "needs ton, the time since the gyro's power-on, which " + run.name + " did not record (no since_power_on_s column)";
  if (uses_axis_thermistor(e) && !run.has_axis_thermistors())
    return "needs a per-axis coil thermistor (T1x..T2z), which " + run.name +
           " did not record (no t1_y_c, t2_y_c, t1_z_c, t2_z_c columns: its axes share the unit's thermistors)";
  return {};
}

namespace wbi {
std::expected<Diagnosis, FitError> diagnose_once(const Model& m, const RunData& fit_run_in, std::span<const RunData> held_out,
                                                 const DiagnoseOptions& o, const std::vector<Generated>& gen, SearchStats* stats,
                                                 const StepHint& hint) {
  RunData fit_copy;
  const RunData& fit_run = finite_gyro(fit_run_in, fit_copy);
  // The hint was computed on the run as given: it holds only when no non-finite gyro sample was
  // zeroed into a copy here.
  const bool hint_holds = &fit_run == &fit_run_in;
  Diagnosis d;
  d.fit_run = fit_run.name;
  for (const auto& h : held_out) d.held_out_runs.push_back(h.name);
  FitOptions fo = options_of(m);
  if (o.max_lag_s) fo.max_lag_s = *o.max_lag_s;
  // The base: the model's terms refitted on the fit run, so that every candidate is compared
  // with the same method on the same data (BIC compares models of one run only).
  auto base = hint_holds && hint.base ? std::expected<Model, FitError>(*hint.base) : fit(fit_run, terms_of(m), fo);
  if (!base) return std::unexpected(FitError{base.error().code, "fit run " + fit_run.name + ": " + base.error().message});
  // The unit's floor (diagnose reads it over every run at once; a step's own base reads it
  // again, as its terms move the holds' residual). Read beside the residual's checks and the
  // screen when threads are allowed (it needs neither): the same numbers, sooner.
  const bool floor_read = o.failing.noise.read_floor && !(hint_holds && hint.floor);
  // The runs side by side (a copy only when they are not already, and the floor is read).
  std::vector<RunData> all_copy;
  const std::span<const RunData> all_runs =
      floor_read ? side_by_side(fit_run, held_out, all_copy) : std::span<const RunData>(&fit_run, 1);
  auto read_unit_floor = [&]() -> std::optional<NoiseFloor> {
    std::optional<NoiseFloor> f = o.failing.noise.given;
    if (o.failing.noise.read_floor) {
      if (!floor_read) return *hint.floor;
      if (auto r = unit_noise_floor(*base, all_runs, o.failing.noise.floor)) f = std::move(*r);
    }
    return f;
  };
  const bool floor_aside = floor_read && o.threads != 1;
  // Declared after what it reads: an early return waits for it before those go.
  std::future<std::optional<NoiseFloor>> floor_later;
  if (floor_aside) floor_later = std::async(std::launch::async, read_unit_floor);
  d.base_refitted_on_other_run = !m.fitted_on.fingerprint.empty() && m.fitted_on.fingerprint != base->fitted_on.fingerprint;
  d.model_terms = base->terms_string();
  d.method = std::string(to_string(base->method));
  Scorer fit_scorer(fit_run, base->tref_c);
  std::vector<Scorer> held_scorers;
  held_scorers.reserve(held_out.size());
  for (const auto& h : held_out) held_scorers.emplace_back(h, base->tref_c);
  auto rms0 = fit_scorer.comp_std(*base);
  if (!rms0) return fail(FitError::Code::degenerate, "fit run " + fit_run.name + ": " + rms0.error());
  d.rms_fit_dph = *rms0;
  report_coefficients(*base, d);
  auto fr = prepare_fit_run(*base, fit_run, fit_scorer.signals());
  if (!fr) return std::unexpected(fr.error());
  // The residual's whiteness and cross-correlations (d.whiteness, d.ccf): beside the candidates'
  // list and screen when threads are allowed (it reads the base, the run and fr's signals and
  // weights, which nothing changes meanwhile), into a Diagnosis of its own, its error returned
  // first as when it runs first.
  Diagnosis resid;
  auto residual_checks = [&] { return check_residual(*base, fit_run, *fr, o, resid); };
  std::future<std::expected<void, FitError>> resid_later;
  if (o.threads != 1) resid_later = std::async(std::launch::async, residual_checks);
  else if (auto r = residual_checks(); !r) return std::unexpected(r.error());
  auto resid_done = [&]() -> std::expected<void, FitError> {
    if (resid_later.valid())
      if (auto r = resid_later.get(); !r) return r;
    d.whiteness = std::move(resid.whiteness);
    d.ccf = std::move(resid.ccf);
    return {};
  };

  // Held-out runs: the base model as fitted, applied unchanged.
  std::vector<std::expected<double, std::string>> held_before;
  for (auto& h : held_scorers) held_before.push_back(h.comp_std(*base));

  auto list = collect_candidates(*base, o, gen, fit_run);
  if (!list) {
    if (auto r = resid_done(); !r) return std::unexpected(r.error());
    return std::unexpected(list.error());
  }
  std::vector<Cand>& cands = list->cands;
  // The base's columns are the scan's from here on (nothing else reads fr->base_cols).
  CandidateScan scan(fit_run.gyro_dph, std::move(fr->base_cols), fr->w, fo.max_lag_s);
  if (o.progress && cands.size() > list->n_fixed) o.progress(DiagnoseProgress{"screening", 0, 0, cands.size() - list->n_fixed});
  screen_generated(cands, list->n_fixed, scan, fit_run, *fr, o, stats);
  if (auto r = resid_done(); !r) return std::unexpected(r.error());
  const double ln_n = std::log(static_cast<double>(std::max<std::size_t>(base->fit.n_used, 2)));
  // The gyro's slow noise on each run, read off its settled holds under the base model: the
  // unit's floor (above), the slow part's mean over each run.
  const std::optional<NoiseFloor> unit_floor = floor_aside ? floor_later.get() : read_unit_floor();
  auto slow_of = [&](const RunData& r) {
    return unit_floor && unit_floor->slow() ? floor_variance(*unit_floor, r.size(), 1).slow : 0.0;
  };
  std::vector<double> slow_held;
  for (const auto& h : held_out) slow_held.push_back(slow_of(h));
  const StepContext ctx{*base, fit_run, held_out, o, fo, *fr, scan, d.rms_fit_dph, held_before, ln_n, slow_of(fit_run), &slow_held};
  std::vector<std::optional<int>> partial_lag;
  for (auto& r : evaluate_all(ctx, cands, fit_scorer, held_scorers)) {
    if (stats) ++(r.pruned ? stats->pruned : stats->refitted);
    d.candidates.push_back(std::move(r.c));
    partial_lag.push_back(r.partial_lag);
  }
  // The refits are done: their cache goes before the detected candidates' partial columns are
  // made (the column as evaluate_candidate evaluated it, at the lag it kept), so that those (one
  // run-length column each: 18 of 2.1 MB on the 3-day run's first step) are not held beside
  // the refits' buffers on both threads (issue 30's memory; the same numbers).
  fit_scorer.drop_fit_cache();
  std::vector<std::vector<double>> partial_cols(cands.size());
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (!partial_lag[i]) continue;
    if (auto x = evaluate(*cands[i].term.expr, fr->sig->view())) partial_cols[i] = scan.partial(lagged(*x, *partial_lag[i]));
  }
  mark_look_alikes(d, partial_cols, *fr, *base, o);
  rank_candidates(d, o);
  summarize(d, held_out.empty(), o);
  return d;
}
}  // namespace wbi

std::expected<AddResult, FitError> add_term(const Model& m, const RunData& run_in, std::string_view text) {
  RunData copy;
  const RunData& run = finite_gyro(run_in, copy);
  auto parsed = parse_term(text);
  if (!parsed) return fail(FitError::Code::bad_term, "--add: " + parsed.error().pretty());
  Term t = *parsed;
  if (t.coef_given) return fail(FitError::Code::bad_term, "--add '" + std::string(text) + "': give the term without a coefficient (the fit estimates it)");
  t.coef = 1.0;
  const std::string key = to_string(*t.expr);
  // The same term again is a second thermal path only at another fixed lag (the model's
  // lags are then frozen at their fitted values: the fit cannot search two lags of one term).
  for (const auto& ft : m.terms)
    if (term_key(ft.term) == key && (t.lag.automatic || ft.term.lag.seconds == t.lag.seconds)) {
      const int other = ft.term.lag.seconds + 120 <= m.max_lag_s ? ft.term.lag.seconds + 120 : std::max(0, ft.term.lag.seconds - 120);
      return fail(FitError::Code::bad_term, "the model already has the term " + key + " (" + m.terms_string() +
                                                "); to add it again as a second thermal path give it a fixed lag other than " +
                                                std::to_string(ft.term.lag.seconds) + " s, e.g. " + key + "@" + std::to_string(other));
    }
  if (auto why = missing_signal_of(*t.expr, run); !why.empty()) return fail(FitError::Code::missing_signal, "term " + key + " " + why);
  const FitOptions fo = options_of(m);
  bool scanned = false;
  // The paper method gives all @auto terms one shared lag: the new term gets its own lag
  // from the scan instead, so that adding it does not move the paper's lag.
  if (t.lag.automatic && fo.method == Method::paper) {
    auto base = fit(run, terms_of(m), fo);
    if (!base) return std::unexpected(FitError{base.error().code, run.name + ": " + base.error().message});
    auto scan = scan_beside(*base, run, fo.max_lag_s);
    if (!scan) return std::unexpected(scan.error());
    auto sig = run_signals(run, fo.tref_c);
    if (!sig) return std::unexpected(sig.error());
    auto x = evaluate(*t.expr, sig->view());
    if (!x) return fail(FitError::Code::missing_signal, "term " + key + ": " + x.error());
    const auto lag = scan->best_lag(*x);
    if (!lag) return fail(FitError::Code::collinear, "term " + key + " adds nothing at any lag in 0.." + std::to_string(fo.max_lag_s) +
                                                         " s that the model's terms do not already hold");
    t.lag = Lag{false, *lag};
    scanned = true;
  }
  TermList tl;
  if (has_key(m, key)) {
    tl.terms = frozen_terms(m);
  } else {
    tl = terms_of(m);
    tl.paper = false;
  }
  tl.terms.push_back(t);
  auto m2 = fit(run, tl, fo);
  if (!m2) return std::unexpected(FitError{m2.error().code, run.name + ": " + m2.error().message});
  // A refit that runs the model's own lag to the edge of its scan has not estimated it
  // (lags_at_edge): the model's lags then stay where they were fitted (issue 16: with d(T2)
  // added on the distributed coil, the paper's shared lag ran to 599 s standing in for the
  // absolute term, which the next diagnose then no longer saw).
  std::vector<std::string> kept;
  if (!has_key(m, key) && lags_at_edge(m).empty()) {
    Model own = *m2;
    own.terms.pop_back();
    if (const auto edge = lags_at_edge(own); !edge.empty()) {
      TermList frozen;
      frozen.terms = frozen_terms(m);
      frozen.terms.push_back(t);
      if (auto m3 = fit(run, frozen, fo)) {
        for (const auto& e : edge) kept.push_back("refitted with " + key + ", " + e + "; kept at the lags fitted before (" + m.terms_string() + ")");
        m2 = std::move(m3);
      }
    }
  }
  AddResult r;
  r.notes = kept;
  r.model = std::move(*m2);
  r.model.parent = std::make_shared<const Model>(m);
  const FittedTerm& nt = r.model.terms.back();
  r.added = with_lag(nt.name(), nt.term.lag.seconds);
  r.model.note = "added " + r.added + (scanned ? " (lag from the residual's lag scan)" : "") + " to " + m.terms_string() +
                 ", refitted on " + run.name + " (" + std::string(to_string(fo.method)) + " method)";
  for (const auto& k : kept) r.model.note += "; " + k;
  return r;
}

}  // namespace fogbench::model::workbench
