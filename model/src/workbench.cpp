// The workbench's effects library, compare (where a model fails on a run), lineage and the
// qualification summary. Diagnose and add live in workbench_diagnose.cpp, JSON in workbench_json.cpp.
#include "fogbench/model/workbench.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>

#include "common.hpp"
#include "workbench_internal.hpp"

namespace fogbench::model::workbench {
namespace {


using detail::fail;


// The phase most samples of [b, e) have.
Phase majority_phase(std::span<const Phase> ph, std::size_t b, std::size_t e) {
  std::array<std::size_t, 5> count{};
  for (std::size_t t = b; t < e; ++t) ++count[static_cast<std::size_t>(ph[t])];
  return static_cast<Phase>(std::max_element(count.begin(), count.end()) - count.begin());
}

}  // namespace

// Each entry: the term, the effect's name, why a gyro would show it, and what profile step
// makes it move unlike the terms it resembles (used to say how to separate look-alikes).
const std::vector<Effect>& effects_library() {
  static const std::vector<Effect> lib = {
      {"d(T1)", "Shupe effect (rate of the coil temperature)",
       "a time-varying temperature reaches the two halves of the fibre at different times, giving a non-reciprocal phase that follows dT/dt",
       "ramps at two different rates"},
      {"grad", "radial temperature gradient across the coil",
       "heat flowing between the coil's centre and its outer wall gives a gradient whose asymmetry about the fibre's midpoint acts like the Shupe effect",
       "a hold right after a fast ramp: the gradient decays with the coil's time constant while the rate is already zero"},
      {"T1", "absolute-temperature sensitivity of the bias",
       "the source wavelength, the scale of the modulator and the coupler's splitting ratio all shift with temperature, moving the bias in proportion to T",
       "long holds at temperatures far apart: the bias stays offset while the rate and gradient are zero"},
      {"T1^2", "nonlinear (quadratic) temperature sensitivity",
       "the bias-temperature curve bends: the same step of temperature moves the bias more far from the reference than near it",
       "holds on both sides of the reference temperature: a quadratic term has the same sign on both, a linear one opposite signs"},
      {"T2", "outer-wall temperature (outer fibre layers, housing)",
       "the outer layers and the housing, bonded to the wall, change the fibre's stress and the bias with the wall's temperature rather than the centre's",
       "a hold after a fast ramp: the wall settles before the centre"},
      {"d(T2)", "rate of the outer-wall temperature",
       "the outer layers see the air's changes first: a Shupe-like term driven by the wall's rate, ahead of the centre's",
       "a fast ramp: the wall's rate leads the centre's by the coil's time constant"},
      {"d(grad)", "rate of the gradient: transient thermal stress (elasto-optic)",
       "a changing gradient changes the stress across the winding, and the elasto-optic effect turns a stress rate into a non-reciprocal phase",
       "the start and the end of a ramp, where the gradient builds up and decays"},
      {"dd(T1)", "change of rate: a second thermal time constant",
       "a second, slower thermal path (potting, mount) adds drift when the rate changes, at the start and end of ramps",
       "abrupt changes of rate: ramps that start and stop sharply"},
      {"T1*d(T1)", "temperature-dependent Shupe coefficient",
       "the fibre's dn/dT and expansion change with temperature, so the Shupe coefficient depends on where the ramp happens",
       "ramps at the same rate at different temperatures, e.g. one near the cold limit and one near the hot limit"},
      {"up(d(T1))", "heating/cooling asymmetry (thermal hysteresis): heating part of the rate",
       "the coil's adhesive and jacket relax differently when heating and cooling, so the Shupe coefficient differs with the sign of the rate",
       "heating and cooling ramps at the same rate"},
      {"down(d(T1))", "heating/cooling asymmetry (thermal hysteresis): cooling part of the rate",
       "the coil's adhesive and jacket relax differently when heating and cooling, so the Shupe coefficient differs with the sign of the rate",
       "heating and cooling ramps at the same rate"},
      {"Ta", "direct coupling of the chamber air (electronics, source)",
       "the electronics and the light source sit in the air, not in the coil, and their bias follows the air temperature directly",
       "a fast chamber step: the air moves minutes before the coil"},
      {"d(Ta)", "rate of the chamber air (electronics, source)",
       "the source and the electronics react to the air's rate before the coil does",
       "a fast chamber step: the air's rate leads the coil's"},
      {"lp(T1,300)", "a second, slow thermal path (time constant 300 s)",
       "part of the gyro (mount, potting, housing) reaches the coil temperature only through a slow thermal path, so its bias follows T1 delayed and smoothed",
       "a hold after a fast ramp: lp(T1,300) keeps moving for about 15 min after T1 has settled"},
  };
  return lib;
}

namespace {
// Every axis's cross-axis entries (T1x, d(T1x), T1y, ...): find_effect names them whichever axis
// is analysed; cross_axis_effects gives an axis the other two's.
const std::vector<Effect>& all_cross_axis_effects() {
  static const std::vector<Effect> lib = [] {
    std::vector<Effect> v;
    for (Axis other : {Axis::x, Axis::y, Axis::z}) {
      const std::string a(to_string(other));
      v.push_back({"T1" + a, "cross-axis coupling: axis " + a + "'s coil temperature",
                   "the axes share a housing: heat from axis " + a + "'s coil, mount and electronics reaches this axis's coil or its "
                   "electronics, so the bias follows axis " + a + "'s temperature besides its own",
                   "a ramp whose heat reaches the axes' coils at different times (their thermistors apart)"});
      v.push_back({"d(T1" + a + ")", "cross-axis coupling: rate of axis " + a + "'s coil temperature",
                   "a gradient across the housing, set up as axis " + a + "'s coil warms, reaches this coil as a Shupe-like term "
                   "following the other coil's rate",
                   "ramps at two rates, where the axes' coils lag one another by different times"});
    }
    return v;
  }();
  return lib;
}
}  // namespace

std::vector<Effect> cross_axis_effects(Axis own) {
  std::vector<Effect> out;
  const std::string mine = "T1" + std::string(to_string(own));
  for (const auto& e : all_cross_axis_effects())
    if (e.term.find(mine) == std::string::npos) out.push_back(e);
  return out;
}

const Effect* find_effect(std::string_view canonical_term) {
  for (const auto& e : effects_library())
    if (e.term == canonical_term) return &e;
  for (const auto& e : all_cross_axis_effects())
    if (e.term == canonical_term) return &e;
  // The library spells terms as typed; compare canonical forms too (e.g. "lp(T1,300)").
  for (const auto& e : effects_library()) {
    auto t = parse_term(e.term);
    if (t && to_string(*t->expr) == canonical_term) return &e;
  }
  return nullptr;
}

std::vector<double> moving_average(std::span<const double> x, int w) {
  std::vector<double> ones(x.size(), 1.0);
  return model::moving_average(x, ones, w);
}

std::vector<std::size_t> decimate_indices(std::span<const double> y, std::size_t max_points) {
  const std::size_t n = y.size();
  std::vector<std::size_t> idx;
  if (n <= max_points || max_points < 4) {
    idx.resize(n);
    for (std::size_t i = 0; i < n; ++i) idx[i] = i;
    return idx;
  }
  // Buckets of equal length; each gives its minimum and its maximum in time order, so a
  // spike of one sample still shows on the plot.
  const std::size_t buckets = max_points / 2;
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t lo = b * n / buckets, hi = (b + 1) * n / buckets;
    if (lo >= hi) continue;
    std::size_t imin = lo, imax = lo;
    for (std::size_t i = lo; i < hi; ++i) {
      if (y[i] < y[imin]) imin = i;
      if (y[i] > y[imax]) imax = i;
    }
    idx.push_back(std::min(imin, imax));
    if (imin != imax) idx.push_back(std::max(imin, imax));
  }
  return idx;
}

std::expected<void, std::string> CompareOptions::validate() const { return noise.validate(); }

std::expected<RunComparison, FitError> compare(const Model& m, const RunData& run, const CompareOptions& o) {
  if (auto v = o.validate(); !v) return fail(FitError::Code::bad_options, "compare: " + v.error());
  auto mu = predict(m, run);
  if (!mu) return std::unexpected(FitError{mu.error().code, run.name + ": " + mu.error().message});
  VerifyOptions vo;
  vo.noise = o.noise;
  auto ver = verify(m, run, vo);
  if (!ver) return std::unexpected(FitError{ver.error().code, run.name + ": " + ver.error().message});
  RunComparison c;
  const std::size_t n = run.size();
  c.run = run.name;
  c.time_s = run.time_s;
  c.measured_dph = run.gyro_dph;
  c.predicted_dph = std::move(*mu);
  c.residual_dph.resize(n);
  c.t1_c = run.t1_c;
  c.t2_c = run.t2_c;
  c.ta_c = run.chamber_c;
  c.phase = derive_phases(run);
  c.verification = std::move(*ver);
  // Weights: flagged, non-finite and outlying samples do not count. An outlier is a spike
  // about the smoothed residual (3 sigma of the deviations from it), not a sample of a
  // sustained error: the 3-sigma rule on the residual itself would drop the very samples
  // where the model fails.
  std::vector<double> w(n, 1.0);
  for (std::size_t t = 0; t < n; ++t) {
    c.residual_dph[t] = run.gyro_dph[t] - c.predicted_dph[t];
    if (run.flagged(t) || !std::isfinite(c.residual_dph[t]) || c.phase[t] == Phase::settle) w[t] = 0.0;
  }
  std::vector<double> rz(c.residual_dph);
  for (std::size_t t = 0; t < n; ++t)
    if (w[t] == 0.0) rz[t] = 0.0;
  {
    const std::vector<double> s0 = model::moving_average(rz, w, o.noise.smooth_s);
    std::vector<double> dev;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0) dev.push_back(rz[t] - s0[t]);
    const OutlierResult ro = outliers_3sigma(dev, 3.0);
    std::size_t j = 0;
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] != 0.0 && !ro.keep[j++]) {
        w[t] = 0.0;
        rz[t] = 0.0;
      }
  }
  c.residual_smooth_dph = model::moving_average(rz, w, o.noise.smooth_s);

  // Table 1 per profile step: contiguous stretches of one step value.
  if (run.has_step()) {
    std::size_t b = 0;
    while (b < n) {
      std::size_t e = b;
      while (e < n && run.step[e] == run.step[b]) ++e;
      std::vector<double> y, p;
      for (std::size_t t = b; t < e; ++t)
        if (w[t] != 0.0) {
          y.push_back(run.gyro_dph[t]);
          p.push_back(c.predicted_dph[t]);
        }
      if (y.size() >= 2) {
        StepTable st;
        st.step = run.step[b];
        st.phase = majority_phase(c.phase, b, e);
        st.start_s = run.time_s[b];
        st.duration_s = static_cast<double>(e - b);
        st.stats = table1(y, p);
        c.steps.push_back(st);
      }
      b = e;
    }
  }

  // Failing intervals: the smoothed residual beyond the yardstick's threshold (verify's, on
  // the gyro's own noise floor) for at least noise.max_fail_s.
  c.threshold_dph = c.verification.threshold_dph;
  const std::vector<double> rate = derivative_per_min(run.t1_c, 1.0);
  std::size_t t = 0;
  while (t < n) {
    if (w[t] == 0.0 || std::abs(c.residual_smooth_dph[t]) <= c.threshold_dph) {
      ++t;
      continue;
    }
    const double sign = c.residual_smooth_dph[t] > 0 ? 1.0 : -1.0;
    std::size_t e = t;
    while (e < n && sign * c.residual_smooth_dph[e] > c.threshold_dph) ++e;
    const double dur = run.time_s[e - 1] - run.time_s[t] + 1.0;
    if (dur >= o.noise.max_fail_s) {
      FailInterval f;
      f.phase = majority_phase(c.phase, t, e);
      f.step = run.has_step() ? run.step[t] : -1;
      f.start_s = run.time_s[t];
      f.duration_s = dur;
      double sm = 0.0, cnt = 0.0, s1 = 0.0, s2 = 0.0, sa = 0.0, sr = 0.0;
      for (std::size_t u = t; u < e; ++u) {
        if (std::abs(c.residual_smooth_dph[u]) > std::abs(f.peak_err_dph)) f.peak_err_dph = c.residual_smooth_dph[u];
        s1 += run.t1_c[u];
        s2 += run.t2_c[u];
        sr += rate[u];
        if (run.has_chamber()) sa += run.chamber_c[u];
        if (w[u] != 0.0) {
          sm += c.residual_dph[u];
          cnt += 1.0;
        }
      }
      const double len = static_cast<double>(e - t);
      f.mean_err_dph = cnt > 0 ? sm / cnt : kNaN;
      f.t1_c = s1 / len;
      f.t2_c = s2 / len;
      f.grad_c = f.t1_c - f.t2_c;
      f.rate_c_per_min = sr / len;
      f.ta_c = run.has_chamber() ? sa / len : kNaN;
      c.failures.push_back(f);
    }
    t = e;
  }
  return c;
}

Lineage lineage(const Model& m, std::span<const RunData> runs) {
  Lineage l;
  for (const auto& r : runs) l.runs.push_back(r.name);
  std::vector<const Model*> chain;
  for (const Model* p = &m; p; p = p->parent.get()) chain.push_back(p);
  std::reverse(chain.begin(), chain.end());
  for (const Model* p : chain) {
    LineageStep s;
    s.terms = p->terms_string();
    s.note = p->note;
    s.created_at = p->created_at;
    s.fitted_on = p->fitted_on.name;
    for (const auto& r : runs) {
      auto v = verify(*p, r);
      s.comp_std_dph.push_back(v ? v->run.comp_std : kNaN);
      s.errors.push_back(v ? std::string() : v.error().message);
    }
    l.steps.push_back(std::move(s));
  }
  return l;
}

Qualification qualify(const Model& m, std::span<const RunData> runs, std::span<const bool> held_out, double threshold) {
  Qualification q;
  q.threshold = threshold;
  q.mu0_dph = m.mu0_dph;
  q.mu0_se_dph = m.mu0_se_dph;
  for (const auto& ft : m.terms) {
    std::string name = ft.name();
    if (ft.term.lag.seconds) name += "@" + std::to_string(ft.term.lag.seconds);
    q.sensitivities.push_back({name, coef_unit(*ft.term.expr), ft.coef, ft.se_dph_per_unit});
  }
  q.pass = !runs.empty();
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const RunData& run = runs[i];
    QualRun qr;
    qr.run = run.name;
    qr.held_out = i < held_out.size() && held_out[i];
    auto v = verify(m, run, threshold);
    if (!v) {
      q.pass = false;
      q.runs.push_back(qr);
      continue;
    }
    qr.meas_std_dph = v->run.meas_std;
    qr.comp_std_dph = v->run.comp_std;
    qr.ratio = v->run.ratio;
    qr.pass = v->pass;
    qr.verdict = v->verdict;
    qr.reasons = v->reasons;
    q.pass = q.pass && qr.pass;
    // Smoothed output (61 s) so that the excursion and the hysteresis are of the drift, not the noise.
    const std::size_t n = run.size();
    std::vector<double> w(n, 1.0);
    for (std::size_t t = 0; t < n; ++t)
      if (run.flagged(t) || !std::isfinite(run.gyro_dph[t])) w[t] = 0.0;
    std::vector<double> y(run.gyro_dph);
    for (std::size_t t = 0; t < n; ++t)
      if (w[t] == 0.0) y[t] = 0.0;
    const std::vector<double> ys = model::moving_average(y, w, 61);
    const std::vector<Phase> ph = derive_phases(run);
    // Heating minus cooling at equal T1: 1 degC bins of T1 visited by both, each bin's
    // difference of mean output weighted by the fewer of its two sample counts; of the raw
    // output (what the gyro does) and of the compensated one (what the model leaves).
    auto mu = predict(m, run);
    std::map<long, std::array<double, 6>> bins;  // sum heat, n heat, sum cool, n cool, comp heat, comp cool
    for (std::size_t t = 0; t < n; ++t) {
      if (w[t] == 0.0) continue;
      if (ph[t] == Phase::heating || ph[t] == Phase::cooling) {
        qr.peak_ramp_excursion_dph = std::max(qr.peak_ramp_excursion_dph, std::abs(ys[t] - m.mu0_dph));
        auto& b = bins[std::lround(std::floor(run.t1_c[t]))];
        const bool heat = ph[t] == Phase::heating;
        b[heat ? 0 : 2] += run.gyro_dph[t];
        b[heat ? 1 : 3] += 1.0;
        if (mu) b[heat ? 4 : 5] += run.gyro_dph[t] - (*mu)[t];
      }
    }
    double sd = 0.0, sc = 0.0, sw = 0.0;
    for (const auto& [key, b] : bins) {
      const double wgt = std::min(b[1], b[3]);
      if (wgt < 30.0) continue;  // fewer than 30 s in a bin: the mean carries 0.146/sqrt(30) = 0.03 deg/h of noise
      sd += wgt * (b[0] / b[1] - b[2] / b[3]);
      sc += wgt * (b[4] / b[1] - b[5] / b[3]);
      sw += wgt;
    }
    if (sw > 0.0) {
      qr.hysteresis_dph = sd / sw;
      if (mu) qr.hysteresis_comp_dph = sc / sw;
    }
    q.runs.push_back(qr);
  }
  q.marginal = !q.pass && !q.runs.empty() &&
               std::all_of(q.runs.begin(), q.runs.end(), [](const QualRun& r) { return r.verdict != Verdict::fail; }) &&
               q.runs.size() == runs.size();
  return q;
}

}  // namespace fogbench::model::workbench
