// Drift that is not thermal (issue 25): a trend in the run's own time (ageing of the source,
// outgassing), a periodic disturbance (a line in the residual's spectrum), each tested against
// the gyro's own noise floor (noise.hpp), not against white noise; and bias jumps (a
// change-point scan of the residual, in workbench_jumps.cpp). Pure.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <limits>
#include <cmath>
#include <complex>
#include <numbers>
#include <numeric>

#include "fogbench/model/workbench.hpp"
#include "common.hpp"
#include "workbench_internal.hpp"

namespace fogbench::model::workbench {
namespace {

using wbi::fmt;
constexpr double kPi = std::numbers::pi;

// Upper tail of the chi-square law with k degrees of freedom (Wilson-Hilferty), enough for a
// consistency check.
double chi2_upper(double x, int k) {
  if (k <= 0) return 1.0;
  const double kk = static_cast<double>(k);
  const double z = (std::cbrt(x / kk) - (1.0 - 2.0 / (9.0 * kk))) / std::sqrt(2.0 / (9.0 * kk));
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

// The variance the floor gives a linear statistic sum c_i x_i of 1 s samples, (deg/h)^2:
// the fast part (white, or the model's AR noise) plus the slow (flicker, random walk) as the
// integral of S(f) |C(f)|^2, C computed on blocks (the slow part lives where a block is short).
double statistic_variance(const NoiseFloor& f, std::span<const double> c) {
  double c2 = 0.0, csum = 0.0;
  for (double v : c) {
    c2 += v * v;
    csum += v;
  }
  double k_sum = 0.0;
  for (double k : f.ar) k_sum += k;
  const double fast_var = f.white_var_dph2 > 0.0 ? f.white_var_dph2
                                                 : f.sigma_a_dph * f.sigma_a_dph / std::max(0.01, (1.0 - k_sum) * (1.0 - k_sum));
  double var = fast_var * c2;
  if (!f.slow()) return var;
  const std::size_t n = c.size();
  const std::size_t b = std::max<std::size_t>(1, n / 1000);
  std::vector<double> cb, tb;
  for (std::size_t i = 0; i < n; i += b) {
    double s = 0.0;
    const std::size_t e = std::min(n, i + b);
    for (std::size_t j = i; j < e; ++j) s += c[j];
    cb.push_back(s);
    tb.push_back(0.5 * static_cast<double>(i + e - 1));
  }
  constexpr int points = 400;
  const double lo = std::log(1e-7), hi = std::log(0.5 / static_cast<double>(b)), step = (hi - lo) / (points - 1);
  double sum = 0.0, prev = 0.0;
  for (int k = 0; k < points; ++k) {
    const double fk = std::exp(lo + step * k);
    std::complex<double> cf{0.0, 0.0};
    for (std::size_t i = 0; i < cb.size(); ++i) cf += cb[i] * std::polar(1.0, -2.0 * kPi * fk * tb[i]);
    const double g = (f.flicker_h / fk + f.walk_h / (fk * fk)) * std::norm(cf) * fk;
    if (k > 0) sum += 0.5 * (g + prev) * step;
    prev = g;
  }
  (void)csum;
  return var + sum;
}

// The slow noise a floor's Allan curve allows (issue 25 point 1: the non-thermal detectors'
// false alarms on FOG noise). The floor keeps a slow law only when it lowers the curve's misfit
// by 16 (4 sigma): a flicker of B 0.02-0.05 deg/h or a walk of 0.05-0.1 deg/h/sqrt(h) under
// white noise of 0.6 deg/h in 1 s (ARW 0.01) often is not kept, and a slow peak or a trend it
// makes then stands far above a floor of white noise alone (fogctl's grid: t 5 to 18 for "a
// drift in time", peaks 15-19 x "the gyro's noise" at 1000-3600 s). Undetected is not absent:
// for each slow law (flicker, random walk) the largest coefficient whose profile deviance over
// the curve's last six octaves (tau >= the longest / 64, where the slow laws show; the other
// laws refitted there, >= 0) rises by at most `chi2` above the best fit of all three laws, or
// the floor's own value when larger. Each point an Allan variance y of edf = terms / m degrees
// of freedom about the law's value v, counted half (half-octave points overlap):
// edf / 2 (y/v - 1 - ln(y/v)), as noise.cpp reads its walk bound. chi2 0 gives the best fit
// itself: the slow noise the long taus show, with no minimum gain.
// The trend's test reads the slow laws at their best fit (chi2 0), not at a bound: its slope is
// what a walk moves most, the curve's last octaves rest on 1-3 degrees of freedom, and even a
// bound at chi2 1 (joint over flicker and walk) lost 6 of the 12 ageing cases of
// tests/sim/workbench_nonthermal_test.cpp (0.02-0.1 deg/h per h), where the best fit loses 2;
// its |t| >= 5 is the margin for the fit's scatter. docs/workbench.md "Drift that is not thermal".
constexpr double kTrendSlowChi2 = 0.0;
struct CurvePoint {
  double tau = 0.0, y = 0.0, e = 0.0;  // s, (deg/h)^2, half the degrees of freedom
};
// The least deviance of the laws c0 / tau + cf + cw tau over `pts` with the laws in `fixed_mask`
// held at `fixed` and the others free and >= 0 (every subset of them, Fisher scoring from the
// least-squares start). +inf when none fits (a law at 0 everywhere).
struct CurveFit {
  double dev = std::numeric_limits<double>::infinity();
  std::array<double, 3> c{0.0, 0.0, 0.0};  // c0, cf, cw (the fixed ones as given)
};
CurveFit nt_curve_fit(const std::vector<CurvePoint>& pts, const std::array<double, 3>& fixed, unsigned fixed_mask) {
  auto basis = [](int j, double tau) { return j == 0 ? 1.0 / tau : j == 1 ? 1.0 : tau; };
  CurveFit best;
  for (unsigned sub = 0; sub < 8; ++sub) {
    if (sub & fixed_mask) continue;
    std::vector<int> js;
    for (int j = 0; j < 3; ++j)
      if (sub & (1u << j)) js.push_back(j);
    const auto q = static_cast<Eigen::Index>(js.size());
    auto value = [&](const Eigen::VectorXd& c, const CurvePoint& p) {
      double v = 0.0;
      for (int j = 0; j < 3; ++j)
        if (fixed_mask & (1u << j)) v += fixed[static_cast<std::size_t>(j)] * basis(j, p.tau);
      for (Eigen::Index k = 0; k < q; ++k) v += c(k) * basis(js[static_cast<std::size_t>(k)], p.tau);
      return v;
    };
    Eigen::VectorXd c = Eigen::VectorXd::Zero(q);
    bool ok = true;
    // Weights 1 / y^2 to start (relative misfit), then Fisher scoring: e / v^2.
    for (int it = 0; it < 40 && q > 0; ++it) {
      Eigen::MatrixXd A = Eigen::MatrixXd::Zero(q, q);
      Eigen::VectorXd g = Eigen::VectorXd::Zero(q);
      for (const auto& p : pts) {
        const double v = it == 0 ? p.y : value(c, p);
        if (!(v > 0.0)) {
          ok = false;
          break;
        }
        const double w = p.e / (v * v);
        double fixed_part = 0.0;
        for (int j = 0; j < 3; ++j)
          if (fixed_mask & (1u << j)) fixed_part += fixed[static_cast<std::size_t>(j)] * basis(j, p.tau);
        for (Eigen::Index a = 0; a < q; ++a) {
          const double xa = basis(js[static_cast<std::size_t>(a)], p.tau);
          g(a) += w * xa * (p.y - fixed_part);
          for (Eigen::Index b = 0; b < q; ++b) A(a, b) += w * xa * basis(js[static_cast<std::size_t>(b)], p.tau);
        }
      }
      if (!ok) break;
      const Eigen::VectorXd next = A.ldlt().solve(g);
      if (!next.allFinite()) {
        ok = false;
        break;
      }
      const double change = (next - c).norm();
      c = next;
      if (change <= 1e-10 * std::max(1e-300, c.norm())) break;
    }
    if (!ok || (q > 0 && c.minCoeff() <= 0.0)) continue;
    double dev = 0.0;
    for (const auto& p : pts) {
      const double v = value(c, p);
      if (!(v > 0.0)) {
        dev = std::numeric_limits<double>::infinity();
        break;
      }
      const double r = p.y / v;
      dev += p.e * (r - 1.0 - std::log(r));
    }
    if (dev < best.dev) {
      best.dev = dev;
      for (int j = 0; j < 3; ++j) best.c[static_cast<std::size_t>(j)] = (fixed_mask & (1u << j)) ? fixed[static_cast<std::size_t>(j)] : 0.0;
      for (Eigen::Index k = 0; k < q; ++k) best.c[static_cast<std::size_t>(js[static_cast<std::size_t>(k)])] = c(k);
    }
  }
  return best;
}

NoiseFloor with_slow_bounds(const NoiseFloor& f, double chi2, bool floor_walk_bound) {
  NoiseFloor out = f;
  if (!(chi2 >= 0.0) || f.curve.size() < 3) return out;
  const double longest = f.curve.back().tau_s;
  std::vector<CurvePoint> pts;
  for (const auto& p : f.curve)
    if (p.tau_s >= longest / 64.0 && p.adev_dph > 0.0 && p.m > 0)
      pts.push_back({p.tau_s, p.adev_dph * p.adev_dph, 0.5 * std::max(1.0, static_cast<double>(p.terms) / static_cast<double>(p.m))});
  if (pts.size() < 3) return out;
  const CurveFit free_fit = nt_curve_fit(pts, {0.0, 0.0, 0.0}, 0u);
  const double best = free_fit.dev;
  if (!std::isfinite(best)) return out;
  // The largest value of law j (1 flicker, 2 walk; Allan coefficients) within chi2 of the best.
  auto bound = [&](int j) {
    const unsigned mask = 1u << j;
    auto excess = [&](double v) {
      std::array<double, 3> fx{0.0, 0.0, 0.0};
      fx[static_cast<std::size_t>(j)] = v;
      return nt_curve_fit(pts, fx, mask).dev - best;
    };
    // From the best fit's value (the profile's least) up.
    double lo = free_fit.c[static_cast<std::size_t>(j)];
    double hi = std::max(2.0 * lo, j == 1 ? pts.back().y : pts.back().y / pts.back().tau);
    int grow = 0;
    while (excess(hi) <= chi2 && grow++ < 60) hi *= 2.0;
    if (grow > 60) return lo;  // never excluded: the best fit's value
    for (int it = 0; it < 40 && hi - lo > 1e-4 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (excess(mid) <= chi2 ? lo : hi) = mid;
    }
    return lo;
  };
  out.flicker_h = std::max(f.flicker_h, bound(1) / (2.0 * std::numbers::ln2));
  out.walk_h = std::max({f.walk_h, floor_walk_bound ? f.walk_bound_h : 0.0, bound(2) * 3.0 / (2.0 * kPi * kPi)});
  return out;
}

// A weighted line a + b t fitted to y: b, and the weights c with b = sum c_i y_i.
struct Line {
  double a = 0.0, b = 0.0;
  std::vector<double> c;
  bool ok = false;
};
Line fit_line(std::span<const double> t, std::span<const double> y, std::span<const double> w) {
  Line l;
  double sw = 0.0, st = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    sw += w[i];
    st += w[i] * t[i];
  }
  if (!(sw > 2.0)) return l;
  const double tm = st / sw;
  double sxx = 0.0, sxy = 0.0, sy = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    sxx += w[i] * (t[i] - tm) * (t[i] - tm);
    sxy += w[i] * (t[i] - tm) * y[i];
    sy += w[i] * y[i];
  }
  if (!(sxx > 0.0)) return l;
  l.b = sxy / sxx;
  l.a = sy / sw - l.b * tm;
  l.c.resize(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) l.c[i] = w[i] * (t[i] - tm) / sxx;
  l.ok = true;
  return l;
}

// The least-squares sinusoid at f (Hz) beside a constant and a line, on blocks x (weights w)
// at times t (s): amplitude, phase (x ~ A sin(2 pi f t + phase)).
struct Sine {
  double amp = 0.0, phase = 0.0, s = 0.0, c = 0.0;
};
Sine fit_sine(std::span<const double> t, std::span<const double> x, std::span<const double> w, double f) {
  // Normal equations of [1, t, sin, cos] (4x4), solved by Gaussian elimination.
  double A[4][5] = {};
  const double tm = t.empty() ? 0.0 : 0.5 * (t.front() + t.back()), ts = t.empty() ? 1.0 : std::max(1.0, t.back() - t.front());
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (w[i] == 0.0) continue;
    const double ph = 2.0 * kPi * f * t[i];
    const double v[4] = {1.0, (t[i] - tm) / ts, std::sin(ph), std::cos(ph)};
    for (int r = 0; r < 4; ++r) {
      for (int q = 0; q < 4; ++q) A[r][q] += w[i] * v[r] * v[q];
      A[r][4] += w[i] * v[r] * x[i];
    }
  }
  for (int col = 0; col < 4; ++col) {
    int piv = col;
    for (int r = col + 1; r < 4; ++r)
      if (std::abs(A[r][col]) > std::abs(A[piv][col])) piv = r;
    if (!(std::abs(A[piv][col]) > 1e-12)) return {};
    if (piv != col)
      for (int q = 0; q < 5; ++q) std::swap(A[col][q], A[piv][q]);
    for (int r = 0; r < 4; ++r) {
      if (r == col) continue;
      const double m = A[r][col] / A[col][col];
      for (int q = col; q < 5; ++q) A[r][q] -= m * A[col][q];
    }
  }
  Sine s;
  s.s = A[2][4] / A[2][2];
  s.c = A[3][4] / A[3][3];
  s.amp = std::hypot(s.s, s.c);
  s.phase = std::atan2(s.c, s.s);
  return s;
}

// A run of the same clock as `run` held throughout: the noise floor is then read over the whole
// run's residual (taus up to a third of the run), not only over the settled holds, whose short
// stretches leave the slow noise over hours poorly known. What a model misses there lifts the
// floor: the tests below then ask for more, never less.
RunData held_throughout(const RunData& run) {
  RunData c;
  c.name = run.name;
  c.time_s = run.time_s;
  c.gyro_dph = run.gyro_dph;
  c.t1_c = run.t1_c;
  c.t2_c = run.t2_c;
  c.phase.assign(run.size(), Phase::hold);
  return c;
}

std::vector<double> decimate(std::span<const double> x, std::size_t max_points, std::vector<std::size_t>& idx) {
  idx.clear();
  const std::size_t n = x.size();
  const std::size_t step = std::max<std::size_t>(1, (n + max_points - 1) / std::max<std::size_t>(1, max_points));
  std::vector<double> out;
  for (std::size_t i = 0; i < n; i += step) {
    idx.push_back(i);
    out.push_back(x[i]);
  }
  return out;
}

}  // namespace

TimeDrift time_drift(const Model& m, std::span<const RunData> runs, const DiagnoseOptions& o) {
  TimeDrift td;
  td.tested = true;
  // Each run's residual and the line in its own time (h); the floor read off the holds of the
  // residual with that line removed, so that a true trend is not read as a random walk.
  struct Per {
    const RunData* run;
    wbi::Residual res;
    std::vector<double> th, detrended;
    Line line;
  };
  std::vector<Per> per;
  if (runs.empty()) {
    td.tested = false;
    return td;
  }
  // The model's terms refitted with trun on the first run (the fit run): the thermal terms
  // then take no part of a ramp (the base model alone bends its terms and its lag towards
  // one). Each run's residual with the time term put back is what the slope is read on.
  Model mt = m;
  double bt = 0.0;
  bool has_trun = false;
  for (const auto& ft : m.terms) has_trun = has_trun || term_key(ft.term) == "trun";
  if (!has_trun)
    if (auto a = add_term(m, runs.front(), "trun@0")) {
      mt = a->model;
      for (const auto& ft : mt.terms)
        if (term_key(ft.term) == "trun") bt = ft.coef;
    }
  for (const auto& run : runs) {
    auto res = wbi::residual_of(mt, run);
    if (!res) continue;
    Per p{&run, std::move(*res), {}, {}, {}};
    const std::size_t n = run.size();
    p.th.resize(n);
    for (std::size_t i = 0; i < n; ++i) p.th[i] = static_cast<double>(i) / 3600.0;
    for (std::size_t i = 0; i < n; ++i)
      if (p.res.w[i] != 0.0) p.res.r[i] += bt * p.th[i];
    p.line = fit_line(p.th, p.res.r, p.res.w);
    if (!p.line.ok) continue;
    p.detrended.resize(n);
    for (std::size_t i = 0; i < n; ++i) p.detrended[i] = p.res.w[i] != 0.0 ? p.res.r[i] - p.line.a - p.line.b * p.th[i] : 0.0;
    per.push_back(std::move(p));
  }
  if (per.empty()) {
    td.tested = false;
    return td;
  }
  NoiseFloor floor;
  if (o.failing.noise.given) {
    floor = *o.failing.noise.given;
  } else {
    std::vector<RunData> held;
    held.reserve(per.size());
    for (const auto& p : per) held.push_back(held_throughout(*p.run));
    std::vector<FloorRun> fr;
    for (std::size_t i = 0; i < per.size(); ++i) fr.push_back({&held[i], per[i].detrended, per[i].res.w});
    floor = estimate_noise_floor(fr, mt.ar, mt.sigma_a_dph, o.failing.noise.floor);
  }
  td.floor = floor;
  // Each slope judged against the floor with the slow noise its curve shows on the long taus,
  // whatever its size (with_slow_bounds at chi2 0: the best fit of the three laws there).
  const NoiseFloor judged = with_slow_bounds(floor, kTrendSlowChi2, false);
  double sw = 0.0, swb = 0.0;
  for (auto& p : per) {
    const double var = statistic_variance(judged, p.line.c);
    const double se = std::sqrt(std::max(var, 1e-30));
    td.runs.push_back({p.run->name, p.line.b, se});
    sw += 1.0 / (se * se);
    swb += p.line.b / (se * se);
  }
  td.slope_dph_per_h = swb / sw;
  td.se_dph_per_h = 1.0 / std::sqrt(sw);
  td.t = td.slope_dph_per_h / td.se_dph_per_h;
  double chi2 = 0.0;
  for (const auto& r : td.runs) chi2 += std::pow((r.slope_dph_per_h - td.slope_dph_per_h) / r.se_dph_per_h, 2);
  td.consistency_p = td.runs.size() > 1 ? chi2_upper(chi2, static_cast<int>(td.runs.size()) - 1) : 1.0;
  td.found = std::abs(td.t) >= o.time_t && td.consistency_p >= 1e-3;
  // Time against temperature within each run, pooled: a run whose T1 only rises (or falls)
  // cannot tell ageing from a temperature term.
  {
    std::vector<double> tt, t1, w;
    for (const auto& p : per) {
      const double mean_t = std::accumulate(p.th.begin(), p.th.end(), 0.0) / static_cast<double>(p.th.size());
      const double m1 = std::accumulate(p.run->t1_c.begin(), p.run->t1_c.end(), 0.0) / static_cast<double>(p.th.size());
      for (std::size_t i = 0; i < p.th.size(); ++i) {
        tt.push_back(p.th[i] - mean_t);
        t1.push_back(std::isfinite(p.run->t1_c[i]) ? p.run->t1_c[i] - m1 : 0.0);
        w.push_back(std::isfinite(p.run->t1_c[i]) ? 1.0 : 0.0);
      }
    }
    td.r_time_t1 = wbi::weighted_corr(tt, t1, w);
    td.collinear = std::abs(td.r_time_t1) >= o.collinear_r;
  }
  // The evidence: each run's residual (61 s average) and its line, decimated.
  for (const auto& p : per) {
    DriftSeries s;
    s.run = p.run->name;
    const std::vector<double> sm = model::moving_average(p.res.r, p.res.w, 61);
    std::vector<std::size_t> idx;
    decimate(sm, 600, idx);
    for (std::size_t i : idx) {
      s.time_s.push_back(p.run->time_s.size() == sm.size() ? p.run->time_s[i] : static_cast<double>(i));
      s.residual_dph.push_back(p.res.w[i] != 0.0 ? sm[i] : kNaN);
      s.fitted_dph.push_back(p.line.a + p.line.b * p.th[i]);
    }
    td.series.push_back(std::move(s));
  }
  if (td.found)
    td.message = "a drift in time (ageing/outgassing), not thermal: " + std::string(td.slope_dph_per_h > 0 ? "+" : "") +
                 fmt(td.slope_dph_per_h, 4) + " deg/h per h (1 sigma " + fmt(td.se_dph_per_h, 4) + ", t " + fmt(td.t, 1) + " against the gyro's noise floor, over " +
                 std::to_string(td.runs.size()) + " run" + (td.runs.size() > 1 ? "s" : "") + ")";
  return td;
}

std::optional<PeriodicDisturbance> find_periodic(const Model& m, const RunData& run, const DiagnoseOptions& o) {
  auto res = wbi::residual_of(m, run);
  if (!res) return std::nullopt;
  const std::size_t n = run.size();
  const double p_max = static_cast<double>(n) / 3.0;  // at least three cycles in the run
  if (p_max < 2.0 * o.periodic_min_s) return std::nullopt;
  // Blocks of b s (at most 16384 of them): the periods searched are long beside a block.
  const std::size_t b = std::max<std::size_t>(1, (n + 16383) / 16384);
  std::vector<double> tb, xb, wb;
  for (std::size_t i = 0; i < n; i += b) {
    double s = 0.0, w = 0.0;
    const std::size_t e = std::min(n, i + b);
    for (std::size_t j = i; j < e; ++j) {
      s += res->w[j] * res->r[j];
      w += res->w[j];
    }
    tb.push_back(0.5 * static_cast<double>(i + e - 1));
    xb.push_back(w > 0.0 ? s / w : 0.0);
    wb.push_back(w > 0.0 ? 1.0 : 0.0);
  }
  const Line line = fit_line(tb, xb, wb);
  if (!line.ok) return std::nullopt;
  for (std::size_t i = 0; i < xb.size(); ++i) xb[i] = wb[i] != 0.0 ? xb[i] - line.a - line.b * tb[i] : 0.0;
  const double m_used = std::accumulate(wb.begin(), wb.end(), 0.0);
  const double bd = static_cast<double>(b);
  const double span_s = static_cast<double>(xb.size()) * bd;
  const double min_p = std::max(o.periodic_min_s, 4.0 * bd);
  const int k_lo = std::max(3, static_cast<int>(std::ceil(span_s / p_max)));
  const int k_hi = static_cast<int>(std::floor(span_s / min_p));
  if (k_hi < k_lo + 4) return std::nullopt;
  // The noise floor read on this run's residual (or the one given).
  const RunData held = held_throughout(run);
  auto read_floor = [&](std::span<const double> r) {
    if (o.failing.noise.given) return *o.failing.noise.given;
    // Over the whole run, its line removed (a trend read as a random walk would excuse a line).
    std::vector<double> x(r.begin(), r.end());
    std::vector<double> ti(n);
    for (std::size_t i = 0; i < n; ++i) ti[i] = static_cast<double>(i);
    const Line l = fit_line(ti, x, res->w);
    if (l.ok)
      for (std::size_t i = 0; i < n; ++i)
        if (res->w[i] != 0.0) x[i] -= l.a + l.b * ti[i];
    return estimate_noise_floor(held, x, res->w, m.ar, m.sigma_a_dph, o.failing.noise.floor);
  };
  // What a peak is judged against: the floor with the slow noise its curve cannot exclude.
  auto judged_floor = [&](std::span<const double> r) { return with_slow_bounds(read_floor(r), o.failing.noise.floor.walk_bound_chi2, true); };
  // |X(f)|^2 of the blocks, and what the noise gives there: M S(f) / (2 b) for M blocks.
  auto power = [&](double f) {
    std::complex<double> x{0.0, 0.0};
    for (std::size_t i = 0; i < xb.size(); ++i)
      if (wb[i] != 0.0) x += xb[i] * std::polar(1.0, -2.0 * kPi * f * tb[i]);
    return std::norm(x);
  };
  const NoiseFloor floor0 = judged_floor(res->r);
  auto expected = [&](const NoiseFloor& fl, double f) { return m_used * floor_psd(fl, f) / (2.0 * bd); };
  // The grid's powers. f = k / span_s with span_s = M b, and a full block's time is i b + c
  // (c = (b - 1) / 2), so its phase is 2 pi (k i / M + f c): the M roots of unity in a table
  // (index k i mod M) replace a sincos per block and frequency (on a 3-day run 35 M of them were
  // a tenth of diagnose), and the common phase f c drops out of |X|^2. A last, partial block is
  // added at its own time.
  std::vector<double> fk, pk;
  {
    const std::size_t M = xb.size();
    const double c = 0.5 * (bd - 1.0);
    std::vector<std::complex<double>> root(M);
    for (std::size_t j = 0; j < M; ++j) root[j] = std::polar(1.0, -2.0 * kPi * static_cast<double>(j) / static_cast<double>(M));
    const bool last_partial = M * b != n;
    const std::size_t full = last_partial ? M - 1 : M;
    for (int k = k_lo; k <= k_hi; ++k) {
      const double f = static_cast<double>(k) / span_s;
      const std::size_t ku = static_cast<std::size_t>(k) % M;
      std::complex<double> x{0.0, 0.0};
      for (std::size_t i = 0, idx = 0; i < full; ++i, idx = idx + ku >= M ? idx + ku - M : idx + ku)
        if (wb[i] != 0.0) x += xb[i] * root[idx];
      if (last_partial && wb[M - 1] != 0.0) x += xb[M - 1] * std::polar(1.0, -2.0 * kPi * f * (tb[M - 1] - c));
      fk.push_back(f);
      pk.push_back(std::norm(x));
    }
  }
  // Two candidates: the highest ordinate over the floor read with any line still in, and the
  // highest ordinate of all. A line of the run reads, through the whole run's Allan curve, as
  // a random walk (its bump near a third of its period): that floor then rises as 1/f^2 below
  // the line's frequency and the line itself no longer stands out against it, while a noise
  // ordinate at a short period does. The largest ordinate is the line whenever it rises above
  // the slow noise; each candidate is judged against the floor read with its own sinusoid
  // removed, the first that passes is reported.
  std::size_t best_floor = 0, best_raw = 0;
  {
    double best_z = 0.0, best_p = 0.0;
    for (std::size_t i = 0; i < fk.size(); ++i) {
      const double z = pk[i] / expected(floor0, fk[i]);
      if (z > best_z) {
        best_z = z;
        best_floor = i;
      }
      if (pk[i] > best_p) {
        best_p = pk[i];
        best_raw = i;
      }
    }
  }
  auto judge = [&](std::size_t best) -> std::optional<PeriodicDisturbance> {
    // The peak refined between its neighbours (the grid's half-bin costs up to a third of the
    // amplitude), by the least-squares sinusoid's amplitude.
    double f_hat = fk[best];
    Sine sine = fit_sine(tb, xb, wb, f_hat);
    {
      const double df = 1.0 / span_s;
      for (int s = -20; s <= 20; ++s) {
        const double f = fk[best] + df * s / 20.0;
        if (f <= 0.0) continue;
        const Sine x = fit_sine(tb, xb, wb, f);
        if (x.amp > sine.amp) {
          sine = x;
          f_hat = f;
        }
      }
    }
    // The floor again with the sinusoid removed: a line read as flicker or random walk on the
    // holds would otherwise excuse itself.
    std::vector<double> clean(n, 0.0);
    for (std::size_t i = 0; i < n; ++i)
      if (res->w[i] != 0.0) clean[i] = res->r[i] - sine.amp * std::sin(2.0 * kPi * f_hat * static_cast<double>(i) + sine.phase);
    const NoiseFloor floor1 = judged_floor(clean);
    // The noise at the peak: the floor's, or the periodogram's own level around it (its median
    // over an octave each side, the peak's bins left out: an exponential ordinate's median is
    // ln 2 of its mean) when that is higher (slow noise the holds did not show). At long
    // periods an octave holds fewer than 6 bins: then the 6 nearest beyond the peak's, read on
    // the blocks with the sinusoid removed (its leakage would otherwise lift them). A random
    // walk's lowest ordinate taken for a line lowers the walk the floor reads once removed; its
    // neighbours then stand above that floor too, where a line's do not.
    double noise = expected(floor1, f_hat);
    {
      std::vector<double> around;
      for (std::size_t i = 0; i < fk.size(); ++i)
        if (fk[i] >= 0.5 * f_hat && fk[i] <= 2.0 * f_hat && std::abs(fk[i] - f_hat) * span_s > 2.5) around.push_back(pk[i] / expected(floor1, fk[i]));
      if (around.size() < 6) {
        std::vector<std::pair<double, std::size_t>> near;  // (bins from the peak, index)
        for (std::size_t i = 0; i < fk.size(); ++i)
          if (const double dk = std::abs(fk[i] - f_hat) * span_s; dk > 2.5) near.emplace_back(dk, i);
        std::sort(near.begin(), near.end());
        if (near.size() > 6) near.resize(6);
        around.clear();
        for (const auto& [dk, i] : near) {
          std::complex<double> x{0.0, 0.0};
          for (std::size_t j = 0; j < xb.size(); ++j)
            if (wb[j] != 0.0) {
              const double ph = 2.0 * kPi * f_hat * tb[j];
              x += (xb[j] - sine.s * std::sin(ph) - sine.c * std::cos(ph)) * std::polar(1.0, -2.0 * kPi * fk[i] * tb[j]);
            }
          around.push_back(std::norm(x) / expected(floor1, fk[i]));
        }
      }
      if (around.size() >= 6) {
        std::nth_element(around.begin(), around.begin() + static_cast<std::ptrdiff_t>(around.size() / 2), around.end());
        noise *= std::max(1.0, around[around.size() / 2] / std::log(2.0));
      }
    }
    const double p_peak = power(f_hat);
    PeriodicDisturbance pd;
    pd.run = run.name;
    pd.period_s = 1.0 / f_hat;
    pd.amplitude_dph = sine.amp;
    pd.phase_rad = sine.phase;
    pd.power_ratio = p_peak / noise;
    pd.frequencies = static_cast<int>(fk.size());
    // Every grid frequency searched (and twice as many for the refinement between them).
    const double p1 = std::exp(-pd.power_ratio);
    pd.p_value = std::min(1.0, -std::expm1(2.0 * static_cast<double>(fk.size()) * std::log1p(-std::min(p1, 0.999999))));
    if (!(pd.p_value < o.periodic_alpha)) return std::nullopt;
    // Residual std with and without the sinusoid.
    {
      double s0 = 0.0, s1 = 0.0, q0 = 0.0, q1 = 0.0, w = 0.0;
      for (std::size_t i = 0; i < n; ++i)
        if (res->w[i] != 0.0) {
          s0 += res->r[i];
          q0 += res->r[i] * res->r[i];
          s1 += clean[i];
          q1 += clean[i] * clean[i];
          w += 1.0;
        }
      pd.rms_before_dph = std::sqrt(std::max(0.0, q0 / w - (s0 / w) * (s0 / w)));
      pd.rms_after_dph = std::sqrt(std::max(0.0, q1 / w - (s1 / w) * (s1 / w)));
    }
    // The temperature program swinging at this period: T1's amplitude there beside its spread
    // (a missing thermal term then repeats with the profile's cycles).
    {
      std::vector<double> t1b(xb.size(), 0.0);
      for (std::size_t i = 0, k = 0; i < n; i += b, ++k) {
        double s = 0.0, w = 0.0;
        for (std::size_t j = i; j < std::min(n, i + b); ++j)
          if (std::isfinite(run.t1_c[j])) {
            s += run.t1_c[j];
            w += 1.0;
          }
        t1b[k] = w > 0.0 ? s / w : 0.0;
      }
      const Line lt = fit_line(tb, t1b, wb);
      for (std::size_t i = 0; i < t1b.size(); ++i) t1b[i] = wb[i] != 0.0 ? t1b[i] - lt.a - lt.b * tb[i] : 0.0;
      // A line of T1's own periodogram at the peak: its power there over its level around
      // (the median over an octave each side, the peak's bins left out, over ln 2) beyond 10.
      // A profile of repeated cycles has lines at its period and harmonics; ramps and holds
      // give a smooth spectrum.
      double at_peak = 0.0;
      std::vector<double> around;
      for (std::size_t i = 0; i < fk.size(); ++i) {
        const double dk = std::abs(fk[i] - f_hat) * span_s;
        if (dk > 2.5 && (fk[i] < 0.5 * f_hat || fk[i] > 2.0 * f_hat)) continue;
        std::complex<double> x{0.0, 0.0};
        for (std::size_t j = 0; j < t1b.size(); ++j)
          if (wb[j] != 0.0) x += t1b[j] * std::polar(1.0, -2.0 * kPi * fk[i] * tb[j]);
        const double p = std::norm(x);
        if (dk <= 1.0) at_peak = std::max(at_peak, p);
        else if (dk > 2.5) around.push_back(p);
      }
      double level = 0.0;
      if (around.size() >= 4) {
        std::nth_element(around.begin(), around.begin() + static_cast<std::ptrdiff_t>(around.size() / 2), around.end());
        level = around[around.size() / 2] / std::log(2.0);
      }
      pd.thermal_period = level > 0.0 && at_peak > 10.0 * level;
    }
    // At a period the temperature program itself swings with, a line of the residual is what a
    // missing thermal term gives: the search's business, not a disturbance.
    if (pd.thermal_period) return std::nullopt;
    // The evidence: amplitude spectra by period (a sinusoid of amplitude a gives |X| = a M / 2).
    for (std::size_t i = 0; i < fk.size(); ++i) {
      pd.spectrum_period_s.push_back(1.0 / fk[i]);
      pd.spectrum_amp_dph.push_back(2.0 * std::sqrt(pk[i]) / m_used);
      pd.noise_amp_dph.push_back(2.0 * std::sqrt(expected(floor1, fk[i])) / m_used);
    }
    pd.message = "a periodic disturbance on " + run.name + ": period " + fmt(pd.period_s, 0) + " s, amplitude " + fmt(pd.amplitude_dph, 3) +
                 " deg/h (its spectral peak " + fmt(pd.power_ratio, 0) + " x the gyro's noise there, p " +
                 (pd.p_value < 1e-6 ? std::string("< 1e-6") : fmt(pd.p_value, 6)) + " over " + std::to_string(pd.frequencies) +
                 " periods searched); removing it takes the residual std from " + fmt(pd.rms_before_dph, 3) + " to " + fmt(pd.rms_after_dph, 3) + " deg/h";
    pd.message += pd.thermal_period
                      ? ". The temperature program also swings at this period: it may be a thermal term the model lacks, not a disturbance"
                      : ": not thermal (the temperature program does not swing at this period); look for a source with this period on the "
                        "bench (the chamber's compressor or defrost cycle, the air conditioning, a pump, a neighbouring machine)";
    return pd;
  };
  auto found = judge(best_floor);
  if (!found && (best_raw > best_floor + 1 || best_floor > best_raw + 1)) found = judge(best_raw);
  return found;
}

}  // namespace fogbench::model::workbench
