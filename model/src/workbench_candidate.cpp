// One candidate of diagnose's step: its lag (the scan beside the model, rescans while the
// refit moves the model's own lags, lag 0 tried as the simpler explanation), the refit with
// it, its score on the fit run and the held-out runs, and the verdict.
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include "workbench_step.hpp"

namespace fogbench::model::workbench::wbi {
namespace {


// A candidate's column prepared for its scans (CandidateScan::prepare by the step's scan) on
// first use.
struct LazyPrepared {
  const CandidateScan& scan;
  std::span<const double> x;
  std::optional<CandidateScan::Prepared> p;
  const CandidateScan::Prepared& get() {
    if (!p) p = scan.prepare(x);
    return *p;
  }
};

// The candidate at its lag, and the model refitted with it.
struct Refit {
  Term term;                               // the candidate, its lag fixed
  std::expected<Model, FitError> model;    // the base's terms plus the candidate, refitted on the fit run
  int extra_params = 0;                    // lag parameters estimated outside the fit (BIC's count)
  bool inner_delay = false;                // a second path written (x@L) in the model (second_path)
  std::vector<Term> fitted;                // the terms of the refits' columns made for the candidate (FitCache::forget)
};

// The model's terms plus the candidate at lag_s, refitted on the fit run (a copy of a model
// term beside the model's lags frozen: extended_terms).
Refit refit_at(const StepContext& ctx, const Cand& cd, int lag_s, detail::FitCache& fc) {
  Term t = cd.term;
  t.lag = Lag{false, lag_s};
  auto [tl, extra_params] = extended_terms(ctx.base, t, true);
  return Refit{t, detail::fit_with(ctx.fit_run, tl, ctx.fo, fc), extra_params, false, {}};
}

// A clock (trun, ton) delayed by L s is the same clock less L s: a constant the model's mu0
// holds (in warm(tau), a factor its coefficient holds), so the run cannot tell its lag and a
// scan would pick one by noise (an ageing slope came out as trun@262). A term that reads no
// temperature is refitted at lag 0, with no lag parameter.
bool reads_temperature(const Expr& e) {
  return uses_signal(e, Signal::T1) || uses_signal(e, Signal::T2) || uses_signal(e, Signal::Ta) || uses_signal(e, Signal::grad) ||
         uses_axis_thermistor(e);
}

Refit refit_undelayed(const StepContext& ctx, const Cand& cd, detail::FitCache& fc) {
  Term t = cd.term;
  t.lag = Lag{false, 0};
  auto [tl, extra_params] = extended_terms(ctx.base, t, false);
  return Refit{t, detail::fit_with(ctx.fit_run, tl, ctx.fo, fc), extra_params, false, {}};
}

// The lag of x (the candidate evaluated on the fit run) starting at the scan's best, then
// coordinate descent with the refit (as the joint fit does), then lag 0 if BIC prefers it.
// fc: this thread's cache of the fit run's refits.
Refit refit_at_best_lag(const StepContext& ctx, const Cand& cd, LazyPrepared& x, int first_lag, detail::FitCache& fc) {
  const Model& base = ctx.base;
  Refit r = refit_at(ctx, cd, first_lag, fc);
  // The candidate's lag was scanned with the model's terms at the lags they had without
  // it; the refit moves those lags, so scan again with the refitted model's columns until
  // the lag settles.
  std::vector<int> lags_before;
  for (const auto& ft : base.terms) lags_before.push_back(ft.term.lag.seconds);
  for (int it = 0; it < ctx.o.lag_iterations && r.model && !cd.repeat; ++it) {
    // The model's own lags did not move: the rescan would find the same lag.
    std::vector<int> lags_now;
    for (std::size_t j = 0; j + 1 < r.model->terms.size(); ++j) lags_now.push_back(r.model->terms[j].term.lag.seconds);
    if (lags_now == lags_before) break;
    lags_before = lags_now;
    auto rescan = scan_beside(*r.model, fc, ctx.fo.max_lag_s, /*without_last_term=*/true);
    if (!rescan) break;
    const auto g2 = rescan->scan(x.get());
    if (!g2 || g2->lag == r.term.lag.seconds) break;
    Term t2 = r.term;
    t2.lag.seconds = g2->lag;
    auto [tl2, ep2] = extended_terms(base, t2, true);
    auto m3 = detail::fit_with(ctx.fit_run, tl2, ctx.fo, fc);
    if (!m3 || m3->fit.bic >= r.model->fit.bic) break;
    r.term = t2;
    r.model = std::move(m3);
  }
  // A lag is a parameter: the term without delay costs ln(n) less in BIC, and is the
  // simpler explanation when the runs hardly tell the two apart.
  // Always tried: the scan's gains cannot tell when lag 0 loses, because the refit moves
  // the model's own lags (a T1 hidden at lag 0 scans best at 150 to 450 s beside a paper
  // model whose lag it had pulled to 0).
  if (r.model && r.term.lag.seconds != 0 && !cd.repeat) {
    Term t0 = r.term;
    t0.lag.seconds = 0;
    auto [tl0, ep0] = extended_terms(base, t0, false);
    auto m0 = detail::fit_with(ctx.fit_run, tl0, ctx.fo, fc);
    if (m0 && m0->fit.bic + ep0 * ctx.ln_n <= r.model->fit.bic + r.extra_params * ctx.ln_n) {
      r.term = t0;
      r.model = std::move(m0);
      r.extra_params = ep0;
    }
  }
  return r;
}

// A model term again at a second lag (a second thermal path) written as one term: the copy
// delayed inside, (x@L) at lag 0, which is x at lag L sample for sample. Being a term of its
// own, it leaves the model's @auto lags free in a refit (a copy of the same term beside them
// would need them frozen), and add_term takes it as diagnose spells it.
Term second_path(const Term& t, int lag_s) {
  Term s = t;
  if (lag_s > 0) {
    auto d = std::make_shared<Expr>();
    d->kind = Expr::Kind::delay;
    d->a = t.expr;
    d->delay_s = lag_s;
    s.expr = d;
  }
  s.lag = Lag{false, 0};
  return s;
}

// The lag of the model's own copy of the candidate's term in m (the window a second path
// keeps away from), if it has one.
std::optional<int> own_lag(const Model& m, const std::string& key) {
  for (const auto& ft : m.terms)
    if (term_key(ft.term) == key) return ft.term.lag.seconds;
  return std::nullopt;
}

// A second path's refit. With the model's lags frozen where they were fitted alone, a second
// path is poorly placed: the paper's shared lag had settled between the two paths (a
// d(T1)@300 hidden beside the paper's terms near 0 s pulled it to 113 s, and a copy beside
// that froze lag took 12% off the residual where the two paths take 60%). So the model's
// @auto lags are refitted with the copy, and the copy's lag scanned again beside them, in
// turn, while BIC falls (as the joint fit's coordinate descent does for its own lags).
Refit refit_second_path(const StepContext& ctx, const Cand& cd, LazyPrepared& x, int first_lag, detail::FitCache& fc) {
  const Model& base = ctx.base;
  Refit r = refit_at(ctx, cd, first_lag, fc);
  if (auto_lag_params(base) == 0) return r;  // nothing to free
  int lag = first_lag;
  // Each lag's copy is a column of its own in the fit cache (the delayed expression): one that
  // is not, or no longer, the kept model's leaves it at once rather than at the candidate's end
  // (issue 30's memory: both threads' second paths held up to 5 columns each at the 3-day run's peak).
  auto drop = [&](const Term& t) {
    if (!has_key(base, term_key(t))) fc.forget(t);
  };
  std::optional<Term> kept_copy;
  for (int it = 0; it < ctx.o.lag_iterations; ++it) {
    TermList free = terms_of(base);
    free.paper = false;
    free.terms.push_back(second_path(cd.term, lag));
    r.fitted.push_back(free.terms.back());
    auto m2 = detail::fit_with(ctx.fit_run, free, ctx.fo, fc);
    if (!m2) {
      drop(free.terms.back());
      break;
    }
    const int ep = 1;  // the copy's scanned lag; the model's own lags are the fit's
    if (r.model && m2->fit.bic + ep * ctx.ln_n >= r.model->fit.bic + r.extra_params * ctx.ln_n) {
      drop(free.terms.back());
      break;
    }
    if (kept_copy && term_key(*kept_copy) != term_key(free.terms.back())) drop(*kept_copy);
    kept_copy = free.terms.back();
    r.model = std::move(m2);
    r.term.lag.seconds = lag;
    r.extra_params = ep;
    r.inner_delay = true;
    auto rescan = scan_beside(*r.model, fc, ctx.fo.max_lag_s, /*without_last_term=*/true);
    if (!rescan) break;
    const auto g = rescan->scan(x.get(), own_lag(*r.model, cd.expr), kDerivativeHalfWidth);
    if (!g || g->lag == lag) break;
    lag = g->lag;
  }
  return r;
}

// The refitted model's scores (fit run, every held-out run), the new term's statistics, and
// the detection rule's verdict, into c.
void score(const StepContext& ctx, const Cand& cd, const Model& m2, int extra_params, Scorer& fs, std::vector<Scorer>& held_sc,
           Candidate& c) {
  const DiagnoseOptions& o = ctx.o;
  c.evaluated = true;
  auto after = fs.comp_std(m2);
  c.rms_after_dph = after ? *after : kNaN;
  c.fall = c.rms_before_dph > 0.0 ? 1.0 - c.rms_after_dph / c.rms_before_dph : 0.0;
  c.delta_bic = m2.fit.bic + extra_params * ctx.ln_n - ctx.base.fit.bic;
  const FittedTerm& nt = m2.terms.back();
  c.coef = nt.coef;
  c.se_dph_per_unit = nt.se_dph_per_unit;
  c.t = nt.se_dph_per_unit > 0.0 ? nt.coef / nt.se_dph_per_unit : 0.0;
  c.p_value = std::erfc(std::abs(c.t) / std::sqrt(2.0));
  double min_fall = std::numeric_limits<double>::infinity();
  int scored = 0;
  for (std::size_t h = 0; h < ctx.held_out.size(); ++h) {
    HeldOutScore hs;
    hs.run = ctx.held_out[h].name;
    if (!ctx.held_before[h]) {
      hs.skipped = "the model does not run on it: " + ctx.held_before[h].error();
    } else if (auto why = missing_signal_of(*cd.term.expr, ctx.held_out[h]); !why.empty()) {
      hs.skipped = why;
    } else if (auto ha = held_sc[h].comp_std(m2); !ha) {
      hs.skipped = ha.error();
    } else {
      hs.scored = true;
      hs.rms_before_dph = *ctx.held_before[h];
      hs.rms_after_dph = *ha;
      min_fall = std::min(min_fall, hs.rms_before_dph > 0.0 ? 1.0 - hs.rms_after_dph / hs.rms_before_dph : 0.0);
      ++scored;
    }
    c.held_out.push_back(hs);
  }
  c.held_out_fall = scored ? min_fall : 0.0;
  // Beyond the gyro's slow noise: the variance the term removes exceeds the slow noise's on
  // the fit run and on every scored held-out run.
  std::string within_slow;
  auto removed = [](double rms_before, double rms_after) { return rms_before * rms_before - rms_after * rms_after; };
  auto within = [&](const std::string& run, double rem, double slow) {
    if (slow > 0.0 && !(rem > slow) && within_slow.empty())
      within_slow = run + " (" + fmt(rem, 4) + " (deg/h)^2 removed, the slow noise " + fmt(slow, 4) + ")";
  };
  within(ctx.fit_run.name, removed(c.rms_before_dph, c.rms_after_dph), ctx.slow_fit_var);
  for (std::size_t h = 0; h < c.held_out.size(); ++h)
    if (c.held_out[h].scored && ctx.slow_held_var && h < ctx.slow_held_var->size())
      within(c.held_out[h].run, removed(c.held_out[h].rms_before_dph, c.held_out[h].rms_after_dph), (*ctx.slow_held_var)[h]);
  const bool significant = c.p_value < o.max_p_value;
  if (scored > 0) {
    c.detected = c.delta_bic < o.max_delta_bic && significant && c.fall >= o.min_fit_fall && c.held_out_fall >= o.min_held_out_fall;
  } else {
    c.detected = c.delta_bic < o.max_delta_bic_alone && significant && c.fall >= o.min_fit_fall_alone;
  }
  c.within_slow_noise = !within_slow.empty();
  const bool explained_by_noise = c.detected && !within_slow.empty();
  if (explained_by_noise) c.detected = false;
  if (c.detected) {
    c.verdict = "missing: compensated std falls " + fmt(100.0 * c.fall, 1) + "% on the fit run" +
                (scored ? " and at least " + fmt(100.0 * c.held_out_fall, 1) + "% on every held-out run" : "") +
                ", delta BIC " + fmt(c.delta_bic, 1);
  } else {
    std::string why;
    if (!(c.delta_bic < (scored ? o.max_delta_bic : o.max_delta_bic_alone))) why = "BIC does not fall enough (" + fmt(c.delta_bic, 1) + ")";
    else if (!significant) why = "its coefficient is not significant (p " + fmt(c.p_value, 4) + ")";
    else if (c.fall < (scored ? o.min_fit_fall : o.min_fit_fall_alone)) why = "the fit run's compensated std falls only " + fmt(100.0 * c.fall, 1) + "%";
    else if (explained_by_noise)
      why = "on " + within_slow + " it removes less variance than the gyro's own slow noise (flicker, random walk) gives";
    else why = "it does not hold up on held-out data (the smallest fall there is " + fmt(100.0 * c.held_out_fall, 1) + "%)";
    c.verdict = "not needed: " + why;
  }
}

}  // namespace

// The fall of the compensated std the one-column update gives (the model's lags held):
// 1 - sqrt(1 - gain / SSE), the weighted squared error before and its fall at the best lag.
static double update_fall(const CandidateScan::Gain& g) {
  if (!(g.sse > 0.0)) return 0.0;
  return 1.0 - std::sqrt(std::max(0.0, 1.0 - g.best / g.sse));
}

// The smallest fall of the fit run's compensated std that any detection rule accepts: with
// held-out runs the per-run rule's or the pooled rule's, whichever is lower; alone, the stricter one.
static double prune_floor(const StepContext& ctx) {
  const DiagnoseOptions& o = ctx.o;
  return ctx.held_out.empty() ? o.min_fit_fall_alone : std::min(o.min_fit_fall, o.min_fit_fall_pooled);
}

EvaluatedCandidate evaluate_candidate(const StepContext& ctx, Cand& cd, Scorer& fs, std::vector<Scorer>& held_sc, detail::FitCache& fc) {
  EvaluatedCandidate out;
  Candidate& c = out.c;
  c.expr = cd.expr;
  c.effect = cd.effect;
  c.explanation = cd.explanation;
  c.unit = coef_unit(*cd.term.expr);
  c.rms_before_dph = ctx.rms_fit_dph;
  c.second_lag = cd.repeat;
  c.term = cd.expr + (cd.repeat ? "@auto (second lag)" : "@auto");
  if (auto why = missing_signal_of(*cd.term.expr, ctx.fit_run); !why.empty()) {
    c.skipped = why + " (the fit run)";
    return out;
  }
  // The column on the fit run's signals (for a generated candidate the screen's numbers: the
  // same expression on the same signals).
  auto x = evaluate(*cd.term.expr, ctx.fr.sig->view());
  if (!x) {
    c.skipped = x.error();
    return out;
  }
  std::optional<int> avoid;
  if (cd.repeat)
    for (const auto& ft : ctx.base.terms)
      if (term_key(ft.term) == cd.expr) avoid = ft.term.lag.seconds;
  // Its scans (the first below, the rescans as the refit moves the model's lags) share its lag
  // extension, spectrum and weighted sums, made once.
  LazyPrepared px{ctx.scan, *x, std::nullopt};
  // Within the derivative window (30 s) of the model's own lag the same term is nearly
  // the same column: a second path must be further away to mean anything. A generated
  // candidate (never a second path: no window) was scanned so by the screen.
  const auto gain = cd.screened ? cd.screened : ctx.scan.scan(px.get(), avoid, kDerivativeHalfWidth);
  if (!gain) {
    c.skipped = "no lag in 0.." + std::to_string(ctx.fo.max_lag_s) + " s adds anything the model's terms do not already hold";
    return out;
  }
  // Pruning: with the model's lags held, the column's best lag lowers the weighted squared error
  // by gain->best; a candidate whose fall is below prune_fraction of the smallest fit-run fall
  // the rule could accept cannot be detected however its refit moves the lags (on the search
  // tests a refit's fall was at most 3.8 x the update's, 11.6 x on the 3-day run), and is not refitted.
  if (const double need = ctx.o.prune_fraction * prune_floor(ctx); need > 0.0 && !cd.repeat && cd.expr != "trun") {
    const double upd = update_fall(*gain);
    if (upd < need) {
      c.lag_s = gain->lag;
      c.skipped = "not refitted: with the model's lags held it lowers the compensated std by " + fmt(100.0 * upd, 3) +
                  "% at best (lag " + std::to_string(gain->lag) + " s), under " + fmt(100.0 * need, 3) +
                  "% (" + fmt(ctx.o.prune_fraction, 2) + " x the smallest fall the detection rule accepts)";
      out.pruned = true;
      return out;
    }
  }
  // The refits are compared by BIC (fc.standard_errors is off); the standard errors only for
  // the one kept (score's p).
  // x is the candidate's column on the fit run's signals (ctx.fr.sig: run_signals of the fit run
  // at the base's tref, as the cache's and the scorer's): handed to both (the scorer's below), so
  // that its refits and its score do not evaluate it again. A second path's refit is another
  // expression: not put.
  if (!cd.repeat) fc.put(cd.term, *x);
  Refit r = cd.repeat                          ? refit_second_path(ctx, cd, px, gain->lag, fc)
            : !reads_temperature(*cd.term.expr) ? refit_undelayed(ctx, cd, fc)
                                                : refit_at_best_lag(ctx, cd, px, gain->lag, fc);
  // The refits' columns of terms the base lacks (this candidate's: every other candidate is
  // another expression) leave the fit cache when this evaluation ends, each with its lag
  // extension and spectrum (6.6 MB on the 3-day run), instead of waiting to be the least
  // recently used of its 8 (memory, issue 30; the same numbers).
  r.fitted.push_back(cd.term);
  struct ForgetAtEnd {
    detail::FitCache& fc;
    const Model& base;
    const std::vector<Term>& terms;
    ~ForgetAtEnd() {
      for (const auto& t : terms)
        if (!has_key(base, term_key(t))) fc.forget(t);
    }
  } forget_at_end{fc, ctx.base, r.fitted};
  if (r.model) detail::add_standard_errors(*r.model, fc);
  c.lag_s = r.term.lag.seconds;
  // What add_term is given to build the same model: a second path with the model's lags
  // refitted is the delayed copy as its own term.
  c.term = r.inner_delay ? to_string(second_path(cd.term, r.term.lag.seconds), false)
                         : with_lag(cd.expr, r.term.lag.seconds);
  if (!r.model) {
    c.skipped = (cd.repeat ? "the same term at a second lag cannot be separated on this run: " : "refit failed: ") + r.model.error().message;
    return out;
  }
  if (!cd.repeat) fs.put(cd.term, *x);  // dropped below with the other columns the base lacks
  score(ctx, cd, *r.model, r.extra_params, fs, held_sc, c);
  // x is r.term's column unlagged (the same expression, evaluated on the same signals). Only the
  // detected are compared as look-alikes (mark_look_alikes, right after the step's evaluations):
  // the others' partial columns, one run-length vector each kept to the end of the step, are not made.
  // The step makes them (from this lag) after the refits, when their buffers are gone.
  if (c.detected) out.partial_lag = r.term.lag.seconds;
  // The scorers' columns of terms the base model lacks are used by this candidate only: dropped,
  // so that memory does not grow with the candidates refitted (a 3-day run's column is 2 MB).
  for (const auto& ft : r.model->terms)
    if (!has_key(ctx.base, term_key(ft.term))) {
      fs.forget(term_key(ft.term));
      for (auto& h : held_sc) h.forget(term_key(ft.term));
    }
  return out;
}

std::expected<CandidateScan, FitError> scan_beside(const Model& m, const RunData& run, int max_lag_s, bool without_last_term) {
  auto cols = regressors(m, run);
  if (!cols) return std::unexpected(cols.error());
  if (without_last_term && !cols->empty()) cols->pop_back();
  return CandidateScan(run.gyro_dph, std::move(*cols), detail::good_weights(run), max_lag_s);
}

std::expected<CandidateScan, FitError> scan_beside(const Model& m, detail::FitCache& cache, int max_lag_s, bool without_last_term) {
  // A cache of another reference: the columns made for this model (regressors_with's), no keys.
  if (cache.tref_c() != m.tref_c) {
    auto cols = detail::regressors_with(m, cache);
    if (!cols) return std::unexpected(cols.error());
    if (without_last_term && !cols->empty()) cols->pop_back();
    return CandidateScan(cache.run().gyro_dph, std::move(*cols), detail::good_weights(cache.run()), max_lag_s, {}, nullptr,
                         /*keep_columns=*/false);
  }
  // The columns are the cache's (its run and reference), read where they lie at their lags
  // (pinned for this thread until its next fit: the scan is made before) rather than copied
  // (a copy of each, 2.1 MB on the 3-day run, per rescan alive); their spectra are kept there by key.
  const std::size_t k = m.terms.size() - (without_last_term && !m.terms.empty() ? 1 : 0);
  std::vector<CandidateScan::BaseColumn> cols;
  std::vector<std::string> keys;
  cols.reserve(k);
  for (std::size_t j = 0; j < k; ++j) {
    const Term& t = m.terms[j].term;
    auto x = cache.column(t);
    if (!x) return std::unexpected(x.error());
    cols.emplace_back(*x, static_cast<std::size_t>(t.lag.seconds));
    keys.push_back(term_key(t) + "@" + std::to_string(t.lag.seconds));
  }
  // A rescan is only scanned (partial() is the step's scan's): its columns are not kept.
  return CandidateScan(cache.run().gyro_dph, std::move(cols), detail::good_weights(cache.run()), max_lag_s, keys, &cache,
                       /*keep_columns=*/false);
}

std::vector<Term> frozen_terms(const Model& m) {
  std::vector<Term> out;
  for (const auto& ft : m.terms) {
    Term t = ft.term;
    t.lag.automatic = false;
    out.push_back(t);
  }
  return out;
}

int auto_lag_params(const Model& m) {
  int n = 0;
  for (const auto& ft : m.terms) n += ft.term.lag.automatic;
  return m.method == Method::paper ? std::min(n, 1) : n;  // the paper method shares one lag
}

bool has_key(const Model& m, const std::string& key) {
  for (const auto& ft : m.terms)
    if (term_key(ft.term) == key) return true;
  return false;
}

std::pair<TermList, int> extended_terms(const Model& base, const Term& extra, bool lag_scanned) {
  TermList tl;
  const bool repeat = has_key(base, term_key(extra));
  tl.terms = repeat ? frozen_terms(base) : terms_of(base).terms;
  tl.terms.push_back(extra);
  return {tl, (lag_scanned ? 1 : 0) + (repeat ? auto_lag_params(base) : 0)};
}

const RunData& finite_gyro(const RunData& run, RunData& copy) {
  bool any = false;
  for (double v : run.gyro_dph) any = any || !std::isfinite(v);
  if (!any) return run;
  copy = run;
  if (copy.flags.empty()) copy.flags.assign(copy.size(), 0);
  for (std::size_t t = 0; t < copy.size(); ++t)
    if (!std::isfinite(copy.gyro_dph[t])) {
      copy.gyro_dph[t] = 0.0;
      copy.flags[t] |= flag::missing;
    }
  return copy;
}

}  // namespace fogbench::model::workbench::wbi
