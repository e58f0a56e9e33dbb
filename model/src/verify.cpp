// Prediction checked on a run: Table 1 of the paper (whole run and per phase), the phases
// themselves, and the verdict (issue 10).
#include <cmath>
#include <cstdio>
#include <limits>

#include "common.hpp"
#include "fogbench/model/model.hpp"

namespace fogbench::model {

using detail::fail;

Table1 table1(std::span<const double> y, std::span<const double> mu) {
  Table1 r;
  r.n = y.size();
  if (y.empty()) return r;
  std::vector<double> c(y.size());
  for (std::size_t i = 0; i < y.size(); ++i) c[i] = y[i] - mu[i];
  r.est_mean = mean(mu);
  r.meas_mean = mean(y);
  r.est_std = stddev(mu);
  r.meas_std = stddev(y);
  r.comp_std = stddev(c);
  r.ratio = r.meas_std > 0.0 ? r.comp_std / r.meas_std : 0.0;
  return r;
}

std::vector<Phase> derive_phases(const RunData& run) {
  if (run.has_phase()) return run.phase;
  const std::size_t n = run.size();
  const std::vector<double>* src = &run.t1_c;
  double threshold = 0.1;  // degC/min
  if (run.has_setpoint()) {
    src = &run.setpoint_c;
    threshold = 0.05;
  } else if (run.has_chamber()) {
    src = &run.chamber_c;
  }
  const std::vector<double> rate = derivative_per_min(*src, 1.0);
  std::vector<Phase> ph(n, Phase::hold);
  for (std::size_t t = 0; t < n; ++t)
    if (rate[t] > threshold) ph[t] = Phase::heating;
    else if (rate[t] < -threshold) ph[t] = Phase::cooling;
  return ph;
}

std::string_view to_string(Verdict v) {
  switch (v) {
    case Verdict::pass: return "pass";
    case Verdict::marginal: return "marginal";
    case Verdict::fail: return "fail";
  }
  return "?";
}

std::expected<void, std::string> VerifyOptions::validate() const {
  if (!(threshold > 0.0 && threshold <= 1.0)) return std::unexpected("threshold must be in (0, 1], got " + std::to_string(threshold));
  return noise.validate();
}

namespace {

// verify's residual and weights: flagged and non-finite samples 0, and spikes about the
// residual's 61 s moving average (3 sigma of the deviations from it), not samples of a
// sustained error: a model that fails for five minutes must show it in Table 1, not lose those
// samples. The residual is 0 where the weight is.
struct VerifyResidual {
  std::vector<double> r, w;
};
VerifyResidual verify_residual(const RunData& run, std::span<const double> mu, std::size_t* n_flagged, std::size_t* n_outliers) {
  const std::size_t n = run.size();
  VerifyResidual out;
  out.w = detail::good_weights(run, n_flagged);
  std::vector<double>& w = out.w;
  out.r.assign(n, 0.0);
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0) out.r[t] = run.gyro_dph[t] - mu[t];
  const std::vector<double> local = moving_average(out.r, w, 61);
  std::vector<double> r;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0) r.push_back(out.r[t] - local[t]);
  const OutlierResult ro = outliers_3sigma(r, 3.0);
  if (n_outliers) *n_outliers = ro.removed;
  std::size_t j = 0;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0 && !ro.keep[j++]) {
      w[t] = 0.0;
      out.r[t] = 0.0;
    }
  return out;
}

}  // namespace

std::expected<NoiseFloor, FitError> unit_noise_floor(const Model& m, std::span<const RunData> runs, const NoiseFloorOptions& o) {
  std::vector<VerifyResidual> res;
  res.reserve(runs.size());
  std::vector<FloorRun> frs;
  for (const auto& run : runs) {
    auto mu = predict(m, run);
    if (!mu) return std::unexpected(FitError{mu.error().code, run.name + ": " + mu.error().message});
    res.push_back(verify_residual(run, *mu, nullptr, nullptr));
    const std::vector<Phase> ph = derive_phases(run);
    for (std::size_t t = 0; t < run.size(); ++t)
      if (ph[t] == Phase::settle) res.back().w[t] = 0.0;
  }
  for (std::size_t i = 0; i < runs.size(); ++i) frs.push_back({&runs[i], res[i].r, res[i].w});
  return estimate_noise_floor(frs, m.ar, m.sigma_a_dph, o);
}

std::expected<Verification, FitError> verify(const Model& m, const RunData& run, double threshold) {
  VerifyOptions o;
  o.threshold = threshold;
  return verify(m, run, o);
}

std::expected<Verification, FitError> verify(const Model& m, const RunData& run, const VerifyOptions& o) {
  if (auto ok = o.validate(); !ok) return fail(FitError::Code::bad_options, "verify: " + ok.error());
  // A model is one axis's: another axis's output against it would be a verdict on nothing.
  if (m.axis.value_or(Axis::x) != run.gyro_axis())
    return fail(FitError::Code::missing_signal, "verify: the model was fitted on axis " + std::string(to_string(m.axis.value_or(Axis::x))) +
                                                    ", " + (run.name.empty() ? std::string("the run") : run.name) + " holds axis " +
                                                    std::string(to_string(run.gyro_axis())) + " (pick the model's axis of the run)");
  const double threshold = o.threshold;
  auto mu = predict(m, run);
  if (!mu) return std::unexpected(mu.error());
  Verification v;
  v.threshold = threshold;
  const std::size_t n = run.size();
  VerifyResidual vr = verify_residual(run, *mu, &v.n_flagged, &v.n_outliers);
  std::vector<double>& w = vr.w;
  const std::vector<double>& res = vr.r;
  const std::vector<Phase> ph = derive_phases(run);
  auto collect = [&](std::optional<Phase> only) {
    std::vector<double> y, p;
    for (std::size_t t = 0; t < n; ++t) {
      if (w[t] == 0.0 || ph[t] == Phase::settle) continue;
      if (only && ph[t] != *only) continue;
      y.push_back(run.gyro_dph[t]);
      p.push_back((*mu)[t]);
    }
    return table1(y, p);
  };
  v.run = collect(std::nullopt);
  if (v.run.n < 2) return fail(FitError::Code::too_short, "no usable samples to verify on");
  for (Phase p : {Phase::hold, Phase::heating, Phase::cooling}) {
    Table1 t = collect(p);
    if (t.n >= 2) v.phases.push_back({p, t});
  }
  v.ratio_pass = v.run.ratio < threshold;
  // The second test: what is left should look like the model's own noise.
  v.noise_test = o.noise_test;
  // The yardstick: the gyro's noise floor read off this run's settled holds (noise.hpp).
  {
    std::vector<double> wf(w);
    for (std::size_t t = 0; t < n; ++t)
      if (ph[t] == Phase::settle) wf[t] = 0.0;
    const Yardstick ys = yardstick(run, res, wf, m.ar, m.sigma_a_dph, v.run.n, o.noise);
    v.floor = ys.floor;
    v.noise_std = ys.noise_std_dph;
    v.noise_limit_factor = ys.limit_factor;
    v.threshold_dph = ys.threshold_dph;
    v.acf_allowance = ys.acf_allowance;
  }
  v.noise_factor = v.noise_std > 0.0 ? v.run.comp_std / v.noise_std : std::numeric_limits<double>::infinity();
  {
    // Failing intervals exactly as compare finds them: the residual without its spikes,
    // averaged over smooth_s, beyond the yardstick's threshold (settle samples do not count).
    std::vector<double> wf(w);
    std::vector<double> rz(n, 0.0);
    for (std::size_t t = 0; t < n; ++t) {
      if (ph[t] == Phase::settle) wf[t] = 0.0;
      if (wf[t] != 0.0) rz[t] = res[t];
    }
    const std::vector<double> s = moving_average(rz, wf, o.noise.smooth_s);
    const double thr = v.threshold_dph;
    std::size_t t = 0;
    while (t < n) {
      if (wf[t] == 0.0 || std::abs(s[t]) <= thr) {
        ++t;
        continue;
      }
      const double sign = s[t] > 0 ? 1.0 : -1.0;
      std::size_t e = t;
      while (e < n && sign * s[e] > thr) ++e;
      v.longest_fail_s = std::max(v.longest_fail_s, run.time_s[e - 1] - run.time_s[t] + 1.0);
      t = e;
    }
  }
  auto pct = [](double x) {
    char b[32];
    std::snprintf(b, sizeof b, "%.1f%%", 100.0 * x);
    return std::string(b);
  };
  auto num = [](double x, int d) {
    char b[32];
    std::snprintf(b, sizeof b, "%.*f", d, x);
    return std::string(b);
  };
  if (!v.ratio_pass) v.reasons.push_back("comp/raw " + pct(v.run.ratio) + " is not under " + pct(threshold) + " (the paper's rule)");
  bool second_ok = true;
  if (o.noise_test) {
    if (!(v.noise_factor <= v.noise_limit_factor)) {
      second_ok = false;
      v.reasons.push_back(noise_factor_reason(v.run.comp_std, v.noise_std, v.noise_factor, v.noise_limit_factor, v.floor));
    }
    if (v.longest_fail_s >= o.noise.max_fail_s) {
      second_ok = false;
      v.reasons.push_back("a failing interval of " + num(v.longest_fail_s, 0) + " s (the residual's " + std::to_string(o.noise.smooth_s) +
                          " s average beyond " + num(v.threshold_dph, 3) + " deg/h" + allowance_note(v.floor) + "; " + num(o.noise.max_fail_s, 0) + " s or more is not passed)");
    }
  }
  v.verdict = !v.ratio_pass ? Verdict::fail : second_ok ? Verdict::pass : Verdict::marginal;
  v.pass = v.verdict == Verdict::pass;
  return v;
}

std::expected<RunWhiteness, FitError> run_whiteness(const Model& m, const RunData& run, int lags, int highpass_s) {
  auto mu = predict(m, run);
  if (!mu) return std::unexpected(FitError{mu.error().code, run.name + ": " + mu.error().message});
  const std::size_t n = run.size();
  const std::vector<Phase> ph = derive_phases(run);
  std::vector<double> r(n, 0.0), w(n, 1.0);
  for (std::size_t t = 0; t < n; ++t) {
    const double e = run.gyro_dph[t] - (*mu)[t];
    if (run.flagged(t) || !std::isfinite(e) || ph[t] == Phase::settle) w[t] = 0.0;
    else r[t] = e;
  }
  // Spikes about the residual's 61 s average (3 sigma of the deviations) do not count.
  const std::vector<double> s0 = moving_average(r, w, 61);
  std::vector<double> dev;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0) dev.push_back(r[t] - s0[t]);
  const OutlierResult ro = outliers_3sigma(dev, 3.0);
  std::size_t j = 0;
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] != 0.0 && !ro.keep[j++]) {
      w[t] = 0.0;
      r[t] = 0.0;
    }
  // The high-pass (model.hpp): the residual less its centred highpass_s average.
  if (highpass_s > 1) {
    const std::vector<double> s1 = moving_average(r, w, highpass_s);
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) r[t] -= s1[t];
  }
  const std::vector<double> a = ar_filter(r, m.ar);
  std::vector<double> used;
  const std::size_t p = m.ar.size();
  for (std::size_t t = p; t < a.size(); ++t) {
    bool whole = true;
    for (std::size_t i = 0; i <= p && whole; ++i) whole = w[t - i] != 0.0;
    if (whole) used.push_back(a[t]);
  }
  RunWhiteness out;
  out.wh = whiteness(used, lags, static_cast<int>(p));
  out.n = used.size();
  out.acf_rms = used.empty() ? 0.0 : std::sqrt(out.wh.lb.q / (static_cast<double>(used.size()) * std::max(1, lags)));
  return out;
}

}  // namespace fogbench::model
