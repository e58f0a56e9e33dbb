// Bias jumps (issue 25 point 3, drift that is not thermal): a change-point scan of the model's
// residual for steps of the bias, away from the profile's changes of rate where the thermal terms
// move (mark_rate_changes); each jump with its time, size and evidence. Out of
// workbench_nonthermal.cpp (the trend and the periodic disturbance), which had passed 800 lines.
// Pure.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include "fogbench/model/workbench.hpp"
#include "common.hpp"
#include "workbench_internal.hpp"

namespace fogbench::model::workbench {

namespace wbi {

void mark_rate_changes(const std::vector<double>& rt, std::size_t half, double spread, std::vector<bool>& marked) {
  const std::size_t n = rt.size();
  bool finite = true;
  for (double v : rt) finite = finite && !std::isnan(v);
  if (!finite) {
    // std::min/max keep a NaN at the window's first sample and skip the others: the loop as it
    // was, for those (a run with gaps) only.
    for (std::size_t k = 0; k < n; ++k) {
      if (marked[k]) continue;
      const std::size_t lo = k >= half ? k - half : 0, hi = std::min(n - 1, k + half);
      double mn = rt[lo], mx = rt[lo];
      for (std::size_t u = lo; u <= hi; ++u) {
        mn = std::min(mn, rt[u]);
        mx = std::max(mx, rt[u]);
      }
      marked[k] = mx - mn > spread;
    }
    return;
  }
  // The window [k - half, k + half] (cut at the ends) slides by one: its minimum and maximum
  // from two monotonic queues of indices, O(n) in all (was O(n x window)), the same values.
  std::vector<std::size_t> qmin(n), qmax(n);
  std::size_t a0 = 0, a1 = 0, b0 = 0, b1 = 0;  // qmin[a0, a1), qmax[b0, b1)
  std::size_t next = 0;                       // the next sample to enter a window
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t lo = k >= half ? k - half : 0, hi = std::min(n - 1, k + half);
    for (; next <= hi; ++next) {
      while (a1 > a0 && rt[qmin[a1 - 1]] >= rt[next]) --a1;
      qmin[a1++] = next;
      while (b1 > b0 && rt[qmax[b1 - 1]] <= rt[next]) --b1;
      qmax[b1++] = next;
    }
    while (qmin[a0] < lo) ++a0;
    while (qmax[b0] < lo) ++b0;
    if (!marked[k]) marked[k] = rt[qmax[b0]] - rt[qmin[a0]] > spread;
  }
}

// The change-point scan: at every k, the residual over k-W..k+W-1 is fitted by a line with
// a kink at k plus a step at k; the step's estimate over its standard error is the statistic.
// The kink keeps a change of slope (a ramp's corner seen through a missing temperature term)
// from looking like a step. Where the coil's rate changes within 90 s a step is what a missing
// rate term gives, so no jump is called there. Found jumps are removed one at a time.
std::vector<BiasJump> find_jumps(const Model& m, const RunData& run, const DiagnoseOptions& o, std::vector<double>* removed) {
  std::vector<BiasJump> out;
  auto res = wbi::residual_of(m, run);
  if (!res) return out;
  const std::size_t n = run.size();
  const int W = o.jump_window_s;
  if (n < static_cast<std::size_t>(4 * W)) return out;
  std::vector<double> r = res->r;
  const std::vector<double>& w = res->w;
  // The step's coefficient as a linear combination of the window's samples.
  const auto nw = static_cast<Eigen::Index>(2 * W);
  Eigen::MatrixXd X(nw, 4);
  for (Eigen::Index i = 0; i < nw; ++i) {
    const double j = static_cast<double>(i - W);
    X(i, 0) = 1.0;
    X(i, 1) = j;
    X(i, 2) = std::max(0.0, j);
    X(i, 3) = j >= 0 ? 1.0 : 0.0;
  }
  const Eigen::MatrixXd G = (X.transpose() * X).inverse();
  const Eigen::VectorXd coef_row = G.row(3);  // step = coef_row . (X' r)
  const double c2 = G(3, 3);                  // sum of the squared weights of the step's estimate
  // Noise: the larger of the model's long-run std of its AR noise and a robust std of the
  // residual's first differences (a misfit adds to it).
  double sum_k = 0.0;
  for (double k : m.ar) sum_k += k;
  const double sigma_long = m.sigma_a_dph / std::max(0.1, std::abs(1.0 - sum_k));
  std::vector<double> dif;
  for (std::size_t t = 1; t < n; ++t)
    if (w[t] != 0.0 && w[t - 1] != 0.0) dif.push_back(std::abs(r[t] - r[t - 1]));
  double sigma_rob = 0.0;
  if (!dif.empty()) {
    std::nth_element(dif.begin(), dif.begin() + static_cast<std::ptrdiff_t>(dif.size() / 2), dif.end());
    sigma_rob = 1.4826 * dif[dif.size() / 2] / std::sqrt(2.0);
  }
  const double sigma = std::max(sigma_long, sigma_rob);
  // The gyro's slow noise (the floor's flicker and random walk, when seen) moves a step
  // estimated over +-W s too: its variance through the estimator's weights adds.
  double slow_var = 0.0;
  if (o.failing.noise.given && o.failing.noise.given->slow()) {
    std::vector<double> cw(static_cast<std::size_t>(nw));
    for (Eigen::Index i = 0; i < nw; ++i) cw[static_cast<std::size_t>(i)] = coef_row.dot(X.row(i).transpose());
    slow_var = floor_slow_variance(*o.failing.noise.given, cw);
  }
  const double se = std::sqrt(sigma * sigma * c2 + slow_var);
  const std::vector<double> rate = derivative_per_min(run.t1_c, 1.0);
  // Where any temperature (setpoint, air, wall, centre) starts or ends a ramp within
  // kThermal_s, a step of the residual is what a missing rate term gives: no jump is called.
  constexpr std::size_t kThermal_s = 150;
  std::vector<bool> thermal(n, false);
  auto mark = [&](const std::vector<double>& x) {
    if (x.size() != n) return;
    wbi::mark_rate_changes(derivative_per_min(x, 1.0), kThermal_s, 0.15, thermal);  // degC/min
  };
  mark(run.setpoint_c);
  mark(run.chamber_c);
  mark(run.t2_c);
  mark(run.t1_c);
  // The coil's rate changes (a ramp starting or ending): where T1's rate differs by more
  // than 0.15 degC/min across +-90 s, at the largest difference of each stretch; degC/min.
  struct RateChange {
    std::size_t at;
    double change_c_per_min;
  };
  std::vector<RateChange> changes;
  {
    constexpr std::size_t kSide = 90;
    auto diff_at = [&](std::size_t c) { return rate[std::min(n - 1, c + kSide)] - rate[c >= kSide ? c - kSide : 0]; };
    for (std::size_t c = 0; c < n;) {
      if (std::abs(diff_at(c)) <= 0.15) {
        ++c;
        continue;
      }
      std::size_t best = c;
      for (; c < n && std::abs(diff_at(c)) > 0.15; ++c)
        if (std::abs(diff_at(c)) > std::abs(diff_at(best))) best = c;
      changes.push_back({best, diff_at(best)});
    }
  }
  for (int found = 0, tried = 0; found < o.max_jumps && tried < 4 * o.max_jumps; ++tried) {
    // Prefix sums of r and t*r.
    std::vector<double> s0(n + 1, 0.0), s1(n + 1, 0.0);
    for (std::size_t t = 0; t < n; ++t) {
      s0[t + 1] = s0[t] + r[t];
      s1[t + 1] = s1[t] + static_cast<double>(t) * r[t];
    }
    auto step_at = [&](std::size_t k) {
      const std::size_t a = k - static_cast<std::size_t>(W), b = k + static_cast<std::size_t>(W);
      const double kd = static_cast<double>(k);
      const double S0 = s0[b] - s0[a];
      const double S1 = (s1[b] - s1[a]) - kd * S0;
      const double S3 = s0[b] - s0[k];
      const double S2 = (s1[b] - s1[k]) - kd * S3;
      return coef_row(0) * S0 + coef_row(1) * S1 + coef_row(2) * S2 + coef_row(3) * S3;
    };
    double best_t = 0.0, best_x = 0.0;
    std::size_t best_k = 0;
    for (std::size_t k = static_cast<std::size_t>(W); k + static_cast<std::size_t>(W) <= n; ++k) {
      if (thermal[k] || w[k] == 0.0) continue;
      const double x = step_at(k);
      const double tt = se > 0.0 ? std::abs(x) / se : 0.0;
      if (tt > best_t) {
        best_t = tt;
        best_x = x;
        best_k = k;
      }
    }
    if (!(best_t >= o.jump_t) || std::abs(best_x) < o.jump_min_sigma * m.sigma_a_dph) break;
    // A rate term the model lacks at a delay L (a second thermal path) steps the residual L s
    // after each change of the coil's rate, in proportion to the change: a step that follows
    // one change by L and has its echoes, L s after the other changes with the sizes the same
    // coefficient gives, is that term, not a jump (a jump has no echoes). Such a step is left
    // to the search and the scan goes on past it.
    auto echoed = [&](std::size_t k, double x) {
      const auto max_lag = static_cast<std::size_t>(std::max(0, m.max_lag_s));
      for (const auto& ch : changes) {
        if (ch.at > k || k - ch.at > max_lag) continue;
        const std::size_t lag = k - ch.at;
        const double beta = x / ch.change_c_per_min;  // deg/h per degC/min
        int echoes = 0, agree = 0;
        for (const auto& other : changes) {
          if (other.at == ch.at) continue;
          const std::size_t k2 = other.at + lag;
          if (k2 < static_cast<std::size_t>(W) || k2 + static_cast<std::size_t>(W) > n) continue;
          const double expect = beta * other.change_c_per_min, seen = step_at(k2);
          ++echoes;
          if (expect * seen > 0.0 && std::abs(seen) >= 0.5 * std::abs(expect) && std::abs(seen) <= 2.0 * std::abs(expect)) ++agree;
        }
        if (echoes > 0 && 3 * agree >= 2 * echoes) return true;
      }
      return false;
    };
    if (echoed(best_k, best_x)) {
      const std::size_t lo = best_k - static_cast<std::size_t>(W) / 2, hi = std::min(n, best_k + static_cast<std::size_t>(W) / 2);
      for (std::size_t t = lo; t < hi; ++t) thermal[t] = true;
      continue;
    }
    ++found;
    BiasJump bj;
    bj.run = run.name;
    bj.time_s = run.time_s[best_k];
    bj.size_dph = best_x;
    bj.t = best_t;
    const double rate_here = rate[best_k];
    bj.message = "a bias jump of " + std::string(best_x > 0 ? "+" : "") + fmt(best_x, 3) + " deg/h at t = " + fmt(bj.time_s, 0) + " s on " +
                 run.name + ": not a thermal effect (the coil's rate is steady there, " + fmt(rate_here, 2) + " degC/min, T1 " +
                 fmt(run.t1_c[best_k], 1) + " degC); check the gyro's power and mode (a restart, a mode or range switch), the light "
                 "source's drive current and the detector, the connectors and the fibre pigtail, and the bench log at that time. "
                 "It is removed from this run for the search only and is never part of a model.";
    out.push_back(bj);
    for (std::size_t t = best_k; t < n; ++t) {
      if (w[t] != 0.0) r[t] -= best_x;
      if (removed) (*removed)[t] += best_x;
    }
  }
  return out;
}

}  // namespace wbi

}  // namespace fogbench::model::workbench
