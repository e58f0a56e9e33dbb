// Data quality before physics (quality.hpp): each sensor problem found by sensor and interval,
// the cleaning that flags what can be skipped, and the identification check of a fitted model.
#include "fogbench/model/quality.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <span>

#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "lagscan.hpp"

namespace fogbench::model {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string num(double v, int digits = 2) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  char buf[64];
  if (std::abs(v) >= 1e5 || (std::abs(v) < 1e-3 && v != 0.0))
    std::snprintf(buf, sizeof buf, "%.*g", digits + 1, v);
  else
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

struct Interval {
  std::size_t first, last;
  std::size_t size() const { return last - first + 1; }
};

// Runs of true in a mask.
std::vector<Interval> runs_of(const std::vector<char>& mask) {
  std::vector<Interval> out;
  for (std::size_t i = 0; i < mask.size();) {
    if (!mask[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < mask.size() && mask[j + 1]) ++j;
    out.push_back({i, j});
    i = j + 1;
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Robust std: 1.4826 times the median absolute deviation from the median (Gaussian-consistent).
double robust_std(const std::vector<double>& v) {
  if (v.size() < 3) return kNaN;
  const double m = median(v);
  std::vector<double> d(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) d[i] = std::abs(v[i] - m);
  return 1.4826 * median(std::move(d));
}

// Linear interpolation across the samples where good is false (ends held); NaN when none is good.
std::vector<double> bridged(std::span<const double> x, const std::vector<char>& good) {
  const std::size_t n = x.size();
  std::vector<double> y(n, kNaN);
  std::size_t last = n;
  for (std::size_t t = 0; t < n; ++t) {
    if (!good[t]) continue;
    y[t] = x[t];
    if (last == n) {
      for (std::size_t u = 0; u < t; ++u) y[u] = x[t];
    } else {
      for (std::size_t u = last + 1; u < t; ++u)
        y[u] = x[last] + (x[t] - x[last]) * static_cast<double>(u - last) / static_cast<double>(t - last);
    }
    last = t;
  }
  if (last != n)
    for (std::size_t u = last + 1; u < n; ++u) y[u] = x[last];
  return y;
}

// The lag k (s) in -max_k..max_k at which b(t + k) best correlates with a(t): b's lag behind a.
// Pearson's r over the overlap of a(t) and b(t + k) at every lag, the cross sums of all lags
// by FFT (LagScanner, lagscan.hpp: the two one-sided correlations of a against b and b against
// a), the other sums by prefix sums; refined between samples by a parabola through the peak and
// its neighbours. The direct sums over every second sample on a 4 s grid that this replaced
// were 40 % of `fogctl allan` on 864,000 samples (docs/performance.md, "Allan deviation").
std::optional<double> lag_behind(const std::vector<double>& a, const std::vector<double>& b, int max_k) {
  const std::size_t n = a.size();
  if (n < 4 * static_cast<std::size_t>(max_k) || max_k < 1) return std::nullopt;
  const detail::LagScanner scanner(n, max_k, std::vector<double>(n, 1.0));
  // ahead[i] = sum_t b(t) a(t - i), behind[i] = sum_t a(t) b(t - i), i = 0..max_k, each with its
  // series held at its first value before the run (make_lagged): that hold is taken off below.
  const auto ahead = scanner.corr(detail::make_lagged(a, max_k), b);
  const auto behind = scanner.corr(detail::make_lagged(b, max_k), a);
  std::vector<long double> pa(n + 1, 0.0L), paa(n + 1, 0.0L), pb(n + 1, 0.0L), pbb(n + 1, 0.0L);
  for (std::size_t t = 0; t < n; ++t) {
    pa[t + 1] = pa[t] + a[t], paa[t + 1] = paa[t] + static_cast<long double>(a[t]) * a[t];
    pb[t + 1] = pb[t] + b[t], pbb[t + 1] = pbb[t] + static_cast<long double>(b[t]) * b[t];
  }
  std::vector<double> r(static_cast<std::size_t>(2 * max_k + 1), -1.5);
  for (int k = -max_k; k <= max_k; ++k) {
    // The overlap: a(t), t in [lo, hi), against b(t + k).
    const std::size_t shift = static_cast<std::size_t>(std::abs(k));
    const std::size_t lo = k < 0 ? shift : 0, hi = k < 0 ? n : n - shift;
    const auto m = static_cast<long double>(hi - lo);
    long double sab = 0.0L;
    if (k >= 0)
      sab = static_cast<long double>(ahead[shift]) - static_cast<long double>(a[0]) * pb[shift];
    else
      sab = static_cast<long double>(behind[shift]) - static_cast<long double>(b[0]) * pa[shift];
    const long double sa = pa[hi] - pa[lo], saa = paa[hi] - paa[lo];
    // b over [lo + k, hi + k).
    const auto b_lo = static_cast<std::size_t>(static_cast<long>(lo) + k), b_hi = b_lo + (hi - lo);
    const long double sb = pb[b_hi] - pb[b_lo], sbb = pbb[b_hi] - pbb[b_lo];
    const long double va = saa - sa * sa / m, vb = sbb - sb * sb / m;
    if (va > 0 && vb > 0) r[static_cast<std::size_t>(k + max_k)] = static_cast<double>((sab - sa * sb / m) / std::sqrt(va * vb));
  }
  const auto best_at = std::max_element(r.begin(), r.end()) - r.begin();
  const int best = static_cast<int>(best_at) - max_k;
  if (r[static_cast<std::size_t>(best_at)] < 0.3) return std::nullopt;  // nothing in common: no lag to speak of
  double k = best;
  if (best > -max_k && best < max_k) {
    const double y0 = r[static_cast<std::size_t>(best_at - 1)], y1 = r[static_cast<std::size_t>(best_at)],
                 y2 = r[static_cast<std::size_t>(best_at + 1)];
    const double den = y0 - 2 * y1 + y2;
    if (den < 0) k += 0.5 * (y0 - y2) / den;
  }
  return k;
}

struct Sensor {
  std::string name;           // T1, T2, Ta
  std::string column;         // t1_c, ...
  const std::vector<double>* x;
  double max_noise_c;
};

class Assessor {
 public:
  Assessor(const RunData& run, const QualityOptions& o) : run_(run), o_(o), n_(run.size()) {}

  QualityReport run() {
    rep_.t1_noise_c = rep_.t2_noise_c = rep_.air_lag_s = rep_.wall_lag_s = rep_.core_lag_s = rep_.hold_offset_c = kNaN;
    if (n_ < 3) return rep_;
    if (!check_time()) return rep_;  // the rest counts samples as seconds
    std::vector<Sensor> sensors = {{"T1", "t1_c", &run_.t1_c, o_.max_noise_c}, {"T2", "t2_c", &run_.t2_c, o_.max_noise_c}};
    if (run_.has_chamber()) sensors.push_back({"Ta", "chamber_c", &run_.chamber_c, o_.max_air_noise_c});
    for (const auto& s : sensors) {
      std::vector<char> bad(n_, 0);
      readings(s, bad);
      const double noise = noisy(s, bad);
      if (s.name == "T1") rep_.t1_noise_c = noise;
      if (s.name == "T2") rep_.t2_noise_c = noise;
      good_[s.name] = std::vector<char>(n_);
      for (std::size_t i = 0; i < n_; ++i) good_[s.name][i] = !bad[i] && !known_bad(i);
    }
    gyro();
    offset();
    lags();
    return rep_;
  }

 private:
  // A sample the recording itself marks as not taken or out of range: already skipped by the fits.
  bool known_bad(std::size_t i) const {
    return run_.has_flags() && (run_.flags[i] & (flag::missing | flag::out_of_range));
  }
  double time_at(std::size_t i) const { return run_.time_s[i]; }

  void add(std::string sensor, QualityKind kind, Interval iv, double value, std::string unit, std::string evidence,
           std::string remedy, bool cleanable, bool by_default) {
    QualityFlag f;
    f.sensor = std::move(sensor);
    f.kind = kind;
    f.first = iv.first;
    f.last = iv.last;
    f.start_s = time_at(iv.first);
    f.end_s = time_at(iv.last);
    f.value = value;
    f.unit = std::move(unit);
    f.evidence = std::move(evidence);
    f.remedy = std::move(remedy);
    f.cleanable = cleanable;
    f.clean_by_default = cleanable && by_default;
    rep_.flags.push_back(std::move(f));
  }

  // Milliseconds, or not 1 s apart: judged on the median step (a few odd steps are the CSV
  // reader's business, which refuses uneven time).
  bool check_time() {
    std::vector<double> d(n_ - 1);
    for (std::size_t i = 1; i < n_; ++i) d[i - 1] = run_.time_s[i] - run_.time_s[i - 1];
    const double step = median(d);
    const Interval all{0, n_ - 1};
    if (std::abs(step - 1000.0) <= 10.0) {
      add("time_s", QualityKind::time_unit, all, step, "per sample",
          "time_s advances by " + num(step, 0) + " per sample (median): the column is in milliseconds, so " +
              std::to_string(n_) + " samples would span " + num(run_.time_s.back() - run_.time_s.front(), 0) +
              " s instead of " + std::to_string(n_ - 1) + " s",
          "convert time_s to seconds (fogctl: --time-unit ms); do not resample it as seconds", false, false);
      return false;
    }
    if (std::abs(step - 1.0) > 0.01) {
      add("time_s", QualityKind::time_step, all, step, "s",
          "time_s advances by " + num(step, 3) + " s per sample (median), not 1 s", "resample onto 1 s (fogctl: --resample 1)",
          false, false);
      return false;
    }
    return true;
  }

  // A reading inside a coil's physical range (min_temp_c..max_temp_c, degC, bounds included):
  // what the range check accepts is what the stuck check may use as evidence, one rule for both.
  bool in_coil_range(double t_c) const { return std::isfinite(t_c) && t_c >= o_.min_temp_c && t_c <= o_.max_temp_c; }

  // A witness of a thermistor's stuck check: a temperature that leads it (or the setpoint) and
  // the thermistor's lag behind it, s.
  struct Witness {
    std::string name;
    const std::vector<double>* x;
    double lag_s;
    bool lags = false;  // the witness follows the sensor (the coil's thermistors witnessing the air)
  };

  // The witnesses of s: the setpoint, the air and the coil's twin (T1 centre, T2 outer wall),
  // each with s's lag behind it: the cross-correlation peak of the rates (lag_behind), clamped
  // to 0..max_lag_scan_s, or the coil's bound when the run cannot measure it (no ramp, too
  // short), plus stuck_lag_margin_s for the spread of a coil's response (the peak is near the
  // median of the delay, a coil's first-minute rise near its end).
  std::vector<Witness> witnesses_of(const Sensor& s, const std::vector<char>& bad) {
    const auto& x = *s.x;
    std::vector<char> ok(n_, 0);
    for (std::size_t i = 0; i < n_; ++i) ok[i] = !bad[i] && !known_bad(i) && std::isfinite(x[i]);
    const auto own = bridged(x, ok);
    const bool measurable = !own.empty() && std::isfinite(own[0]);
    const auto own_rate = measurable ? derivative_per_min(own, 1.0) : std::vector<double>{};
    const int k = static_cast<int>(o_.max_lag_scan_s);
    std::vector<Witness> out;
    auto add_witness = [&](const std::string& name, const std::vector<double>& y, double bound_s) {
      if (y.empty() || &y == s.x) return;
      std::vector<char> yok(n_, 0);
      for (std::size_t i = 0; i < n_; ++i) yok[i] = in_coil_range(y[i]);
      const auto yb = bridged(y, yok);
      if (yb.empty() || !std::isfinite(yb[0])) return;
      std::optional<double> lag;
      if (measurable) lag = lag_behind(derivative_per_min(yb, 1.0), own_rate, k);
      // A witness leads s (lag >= 0), except the coil's thermistors witnessing the air (<= 0).
      const double lo = bound_s < 0 ? -o_.max_lag_scan_s : 0.0, hi = bound_s < 0 ? 0.0 : o_.max_lag_scan_s;
      const double l = lag ? std::clamp(*lag, lo, hi) : bound_s;
      out.push_back({name, &y, l + o_.stuck_lag_margin_s, bound_s < 0});
    };
    const double core = o_.max_core_lag_s, wall = o_.max_wall_lag_s, air = o_.max_air_lag_s;
    if (s.name == "T1") {
      add_witness("T2", run_.t2_c, core);
      add_witness("Ta", run_.chamber_c, core + wall);
      add_witness("the setpoint", run_.setpoint_c, core + wall + air);
    } else if (s.name == "T2") {
      // The centre follows the wall: T1 still moves after the wall has settled, so it is a
      // witness (looked at later) only when neither the air nor the setpoint is recorded.
      add_witness("Ta", run_.chamber_c, wall);
      add_witness("the setpoint", run_.setpoint_c, wall + air);
      if (!run_.has_chamber() && !run_.has_setpoint()) add_witness("T1", run_.t1_c, -core);
    } else if (run_.has_setpoint()) {
      // The air's only witness is the setpoint: the coil follows the air, so its thermistors
      // still move for many minutes after the air has settled.
      add_witness("the setpoint", run_.setpoint_c, air);
    } else {
      // No setpoint: the coil's thermistors, looked at later by their lag behind the air.
      add_witness("T2", run_.t2_c, -wall);
      add_witness("T1", run_.t1_c, -wall - core);
    }
    return out;
  }

  // The smaller of `measure` (degC) over two windows of the run: the interval shifted back by
  // lag_s and by lag_s - stuck_lag_margin_s (forward when negative), each clipped to the run,
  // 0 for a window outside it. The margin only ever lowers the evidence, at a ramp's start and
  // at its end alike. measure(first, last) takes the window's sample indices, inclusive.
  template <class Measure>
  double over_shifted_windows(Interval iv, double lag_s, Measure measure) const {
    auto at = [&](double shift_s) {
      const auto sh = static_cast<long>(std::lround(shift_s));
      const long a = static_cast<long>(iv.first) - sh, b = static_cast<long>(iv.last) - sh;
      const long end = static_cast<long>(n_) - 1;
      if (b < 0 || a > end) return 0.0;
      return measure(static_cast<std::size_t>(std::max(0L, a)), static_cast<std::size_t>(std::min(b, end)));
    };
    return std::min(at(lag_s), at(lag_s - o_.stuck_lag_margin_s));
  }

  // A witness that leads the sensor: its move (max - min over its in-range readings, degC)
  // over the shifted windows.
  double shifted_move(const std::vector<double>& y, Interval iv, double lag_s) const {
    return over_shifted_windows(iv, lag_s, [&](std::size_t first, std::size_t last) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (std::size_t i = first; i <= last; ++i)
        if (in_coil_range(y[i])) lo = std::min(lo, y[i]), hi = std::max(hi, y[i]);
      return hi > lo ? hi - lo : 0.0;
    });
  }

  // A witness that follows the sensor (the coil's thermistors witnessing the air when no
  // setpoint is recorded, T1 witnessing T2 when neither is): its move is no evidence, since a
  // coil keeps settling for many minutes after the air holds still. Its evidence is how far it
  // moves away from the repeated value v_c (degC): the largest rise of its distance from v_c
  // above the smallest distance before it, over the shifted windows (looked at later: its lag
  // is negative). A coil settling towards the air's held value only closes on it; a sensor
  // frozen on a ramp is crossed and left behind by the coil that follows the true temperature.
  double shifted_departure(const std::vector<double>& y, Interval iv, double lag_s, double v_c) const {
    return over_shifted_windows(iv, lag_s, [&](std::size_t first, std::size_t last) {
      double closest = std::numeric_limits<double>::infinity(), rise = 0.0;
      for (std::size_t i = first; i <= last; ++i) {
        if (!in_coil_range(y[i])) continue;
        const double d = std::abs(y[i] - v_c);
        closest = std::min(closest, d);
        rise = std::max(rise, d - closest);
      }
      return rise;
    });
  }

  // Dropouts, values out of the coil's range and stuck readings of one thermistor.
  void readings(const Sensor& s, std::vector<char>& bad) {
    const auto& x = *s.x;
    std::vector<char> nan(n_, 0), out(n_, 0);
    for (std::size_t i = 0; i < n_; ++i) {
      if (!std::isfinite(x[i])) nan[i] = 1;  // flagged missing or not: the fits bridge it either way
      else if (!known_bad(i) && !in_coil_range(x[i])) out[i] = 1;
    }
    // A gap the recording flagged missing is the recording's own business up to max_bridge_s;
    // beyond it the fits would bridge a long stretch by a straight line, silently.
    std::vector<Interval> dropouts;
    for (const auto& iv : runs_of(nan)) {
      bool all_known = true;
      for (std::size_t i = iv.first; i <= iv.last && all_known; ++i) all_known = known_bad(i);
      if (all_known && static_cast<double>(iv.size()) <= o_.max_bridge_s) continue;
      dropouts.push_back(iv);
    }
    const auto outs = runs_of(out);
    std::size_t n_nan = 0, n_out = 0;
    for (const auto& iv : dropouts) n_nan += iv.size();
    for (const auto& iv : outs) n_out += iv.size();
    // A sensor dead over most of the run cannot be cleaned: nothing would be left to fit.
    const bool dead = 2 * (n_nan + n_out) > n_;
    for (const auto& iv : dropouts) {
      const double dur = static_cast<double>(iv.size());
      add(s.name, QualityKind::dropout, iv, dur, "s",
          s.name + " (" + s.column + ") has no reading for " + num(dur, 0) + " s" +
              (dead ? " (" + num(100.0 * static_cast<double>(n_nan + n_out) / static_cast<double>(n_), 0) + "% of the run lost)" : ""),
          dead ? "check the thermistor's connection; the run cannot be fitted with " + s.name
               : "bridge it (--quality clean) or re-record the interval",
          !dead, dur <= o_.max_bridge_s);
    }
    for (const auto& iv : outs) {
      double worst = x[iv.first];
      for (std::size_t i = iv.first; i <= iv.last; ++i)
        if (std::abs(x[i] - 20.0) > std::abs(worst - 20.0)) worst = x[i];
      add(s.name, QualityKind::out_of_range, iv, worst, "degC",
          s.name + " (" + s.column + ") reads " + num(worst) + " degC for " + std::to_string(iv.size()) +
              " s, outside a coil's physical range " + num(o_.min_temp_c, 0) + ".." + num(o_.max_temp_c, 0) + " degC" +
              (worst < -270.0 ? " (an open thermistor reads absolute zero)" : ""),
          dead ? "check the thermistor and its converter; the run cannot be fitted with " + s.name
               : "skip the interval (--quality clean: its samples flagged, temperatures bridged) or re-record it",
          !dead, false);
    }
    for (std::size_t i = 0; i < n_; ++i) bad[i] = nan[i] || out[i];
    // Stuck: exact repeats of an in-range reading while another temperature moves.
    // Runs of one value (a mask of "equals its neighbour" would merge 20.00, 20.00, 20.01,
    // 20.01, ... into one run: a coarse thermistor on a slow ramp would be stuck for the whole run).
    std::vector<Interval> repeats;
    for (std::size_t i = 1; i < n_; ++i) {
      if (bad[i] || bad[i - 1] || known_bad(i) || x[i] != x[i - 1]) continue;
      if (!repeats.empty() && repeats.back().last == i - 1 && x[repeats.back().first] == x[i]) repeats.back().last = i;
      else repeats.push_back({i - 1, i});
    }
    std::vector<Witness> witnesses;
    bool prepared = false;
    for (const auto& iv : repeats) {
      const double dur = static_cast<double>(iv.size());
      if (dur < o_.stuck_min_s) continue;
      if (!prepared) witnesses = witnesses_of(s, bad), prepared = true;
      // The evidence that s should have moved: each witness's move over the interval shifted
      // back by s's lag behind it (a coil's centre follows the air minutes late, so at a ramp's
      // start it legitimately stays put), the largest over the witnesses (docs/data-quality.md).
      double move = 0.0;
      const Witness* mover = nullptr;
      for (const auto& w : witnesses) {
        const double m = w.lags ? shifted_departure(*w.x, iv, w.lag_s, x[iv.first]) : shifted_move(*w.x, iv, w.lag_s);
        if (m > move) move = m, mover = &w;
      }
      if (move <= o_.stuck_move_c || !mover) continue;
      for (std::size_t i = iv.first; i <= iv.last; ++i) bad[i] = 1;
      const bool whole = 2 * iv.size() > n_;
      // A leading witness is named by its shift with the margin, a following one by its lag.
      const std::string evidence =
          mover->lags ? mover->name + " (" + num(std::abs(mover->lag_s - o_.stuck_lag_margin_s), 0) + " s later, its lag behind " +
                            s.name + ") moves away from it by "
                      : mover->name + " (" + num(std::abs(mover->lag_s), 0) + " s " + (mover->lag_s >= 0 ? "earlier" : "later") +
                            ", its lead on " + s.name + " with a margin) moves by ";
      add(s.name, QualityKind::stuck, iv, dur, "s",
          s.name + " (" + s.column + ") repeats " + num(x[iv.first]) + " degC exactly for " + num(dur, 0) + " s while " +
              evidence + num(move) + " degC",
          whole ? "check the thermistor and its converter: " + s.name + " is stuck over most of the run"
                : "skip the interval (--quality clean: its samples flagged, temperatures bridged) or re-record it",
          !whole, false);
    }
  }

  // White noise per window from second differences (a ramp's slope cancels), robust, degC.
  // Returns the median over the windows.
  double noisy(const Sensor& s, const std::vector<char>& bad) {
    const auto& x = *s.x;
    const auto w = static_cast<std::size_t>(std::max(30.0, o_.noise_window_s));
    std::vector<char> loud(n_, 0);
    std::vector<double> levels;
    double worst = 0.0;
    for (std::size_t a = 0; a + 3 <= n_; a += w) {
      const std::size_t b = std::min(n_, a + w);
      std::vector<double> d2;
      for (std::size_t i = a + 1; i + 1 < b; ++i) {
        if (bad[i - 1] || bad[i] || bad[i + 1] || known_bad(i - 1) || known_bad(i) || known_bad(i + 1)) continue;
        d2.push_back(x[i + 1] - 2 * x[i] + x[i - 1]);
      }
      if (d2.size() < 20) continue;
      // White noise sigma: second differences have std sigma * sqrt(6).
      const double level = robust_std(d2) / std::sqrt(6.0);
      levels.push_back(level);
      if (level > s.max_noise_c) {
        for (std::size_t i = a; i < b; ++i) loud[i] = 1;
        worst = std::max(worst, level);
      }
    }
    std::size_t n_loud = 0;
    for (char c : loud) n_loud += c != 0;
    const bool whole = 2 * n_loud > n_;
    for (const auto& iv : runs_of(loud)) {
      double level = 0.0;
      std::vector<double> d2;
      for (std::size_t i = iv.first + 1; i + 1 <= iv.last; ++i)
        if (!bad[i - 1] && !bad[i] && !bad[i + 1]) d2.push_back(x[i + 1] - 2 * x[i] + x[i - 1]);
      level = robust_std(d2) / std::sqrt(6.0);
      add(s.name, QualityKind::noisy, iv, level, "degC",
          s.name + " (" + s.column + ") has a white noise of " + num(level, 3) + " degC (1 sigma, from second differences) over " +
              std::to_string(iv.size()) + " s, above " + num(s.max_noise_c, 3) + " degC",
          whole ? "check the thermistor's wiring and shielding, and its converter's filter: " + s.name + " is noisy over most of the run"
                : "skip the interval (--quality clean) or check the wiring",
          !whole, false);
    }
    (void)worst;
    return median(levels);
  }

  // Gyro: dropouts, spikes about a running median, saturation (exact repeats at an extreme).
  void gyro() {
    const auto& y = run_.gyro_dph;
    std::vector<char> nan(n_, 0);
    for (std::size_t i = 0; i < n_; ++i)
      if (!known_bad(i) && !std::isfinite(y[i])) nan[i] = 1;
    std::size_t n_nan = 0;
    for (char c : nan) n_nan += c != 0;
    const bool dead = 2 * n_nan > n_;
    for (const auto& iv : runs_of(nan)) {
      const double dur = static_cast<double>(iv.size());
      add("gyro", QualityKind::dropout, iv, dur, "s", "gyro_dph has no reading for " + num(dur, 0) + " s",
          dead ? "check the gyro's link; most of the run has no output" : "skip the interval (--quality clean) or re-record it", !dead,
          dur <= o_.max_bridge_s);
    }
    // Saturation: exact repeats at the run's extreme value.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < n_; ++i)
      if (std::isfinite(y[i]) && !known_bad(i)) lo = std::min(lo, y[i]), hi = std::max(hi, y[i]);
    std::vector<char> pinned(n_, 0);
    for (std::size_t i = 1; i < n_; ++i)
      if (std::isfinite(y[i]) && y[i] == y[i - 1] && (y[i] == lo || y[i] == hi)) pinned[i - 1] = pinned[i] = 1;
    std::vector<char> sat(n_, 0);
    for (const auto& iv : runs_of(pinned)) {
      const double dur = static_cast<double>(iv.size());
      if (dur < o_.saturation_min_s) continue;
      for (std::size_t i = iv.first; i <= iv.last; ++i) sat[i] = 1;
      add("gyro", QualityKind::saturation, iv, y[iv.first], "deg/h",
          "gyro_dph is pinned at " + num(y[iv.first], 3) + " deg/h, the run's " + (y[iv.first] == hi ? "maximum" : "minimum") +
              ", for " + num(dur, 0) + " s: the gyro or its converter saturates",
          "check the gyro's range and mode; skip the interval (--quality clean)", 2 * iv.size() <= n_, false);
    }
    // Spikes: beyond spike_sigma robust sigmas of the output about its 31 s running median.
    // The window (the usable samples within +-15 s) is kept sorted as it slides: one value out,
    // one in, each placed by binary search, the median its middle element, the same value as
    // sorting each window (nth_element on every window was a third of `fogctl allan`'s time on
    // 864,000 samples).
    constexpr std::size_t half = 15;
    const auto usable = [&](std::size_t j) { return std::isfinite(y[j]) && !known_bad(j) && !sat[j]; };
    std::vector<double> resid(n_, kNaN), sorted;
    sorted.reserve(2 * half + 1);
    const auto enter = [&](std::size_t j) {
      if (j < n_ && usable(j)) sorted.insert(std::upper_bound(sorted.begin(), sorted.end(), y[j]), y[j]);
    };
    for (std::size_t j = 0; j <= half; ++j) enter(j);
    for (std::size_t i = 0; i < n_; ++i) {
      if (i > 0) {  // the window of i is [i - half, i + half], clipped to the run
        if (i >= half + 1 && usable(i - half - 1))
          sorted.erase(std::lower_bound(sorted.begin(), sorted.end(), y[i - half - 1]));
        enter(i + half);
      }
      if (!usable(i)) continue;
      resid[i] = y[i] - sorted[sorted.size() / 2];
    }
    std::vector<double> finite;
    for (double r : resid)
      if (std::isfinite(r)) finite.push_back(r);
    const double sigma = robust_std(finite);
    if (!(sigma > 0)) return;
    std::vector<char> spike(n_, 0);
    for (std::size_t i = 0; i < n_; ++i) spike[i] = std::isfinite(resid[i]) && std::abs(resid[i]) > o_.spike_sigma * sigma;
    for (const auto& iv : runs_of(spike)) {
      double peak = 0.0;
      for (std::size_t i = iv.first; i <= iv.last; ++i)
        if (std::abs(resid[i]) > std::abs(peak)) peak = resid[i];
      const double dur = static_cast<double>(iv.size());
      const bool isolated = dur <= o_.max_spike_s;
      add("gyro", QualityKind::spike, iv, peak / sigma, "sigma",
          "gyro_dph departs by " + num(peak, 3) + " deg/h (" + num(std::abs(peak) / sigma, 0) +
              " robust sigmas of its noise, " + num(sigma, 3) + " deg/h) from its 31 s running median for " + num(dur, 0) +
              " s; beyond " + num(o_.spike_sigma, 0) + " sigmas",
          isolated ? "dropped from the fit (--quality check cleans an isolated spike)"
                   : "a burst, not a spike: check the gyro and the bench log; skip the interval (--quality clean)",
          true, isolated);
    }
  }

  // The rate of a temperature, degC/min, over its good samples (bad ones bridged); empty when
  // it has no good sample.
  std::vector<double> rate(const std::string& name, const std::vector<double>& x) {
    const auto it = good_.find(name);
    if (it == good_.end()) return {};
    auto b = bridged(x, it->second);
    if (b.empty() || !std::isfinite(b[0])) return {};
    return derivative_per_min(b, 1.0);
  }
  std::vector<double> level(const std::string& name, const std::vector<double>& x) {
    const auto it = good_.find(name);
    if (it == good_.end()) return {};
    auto b = bridged(x, it->second);
    if (b.empty() || !std::isfinite(b[0])) return {};
    return b;
  }

  // T1 and T2 on the settled parts of holds (both rates under settled_rate for settled_min_s):
  // a uniform coil reads the same on both.
  void offset() {
    const auto t1 = level("T1", run_.t1_c), t2 = level("T2", run_.t2_c);
    const auto r1 = rate("T1", run_.t1_c), r2 = rate("T2", run_.t2_c);
    if (t1.empty() || t2.empty()) return;
    std::vector<char> calm(n_, 0);
    for (std::size_t i = 0; i < n_; ++i)
      calm[i] = std::abs(r1[i]) < o_.settled_rate_c_per_min && std::abs(r2[i]) < o_.settled_rate_c_per_min &&
                good_["T1"][i] && good_["T2"][i];
    std::vector<double> d12, d1a, d2a;
    std::optional<Interval> span;
    const auto ta = run_.has_chamber() ? level("Ta", run_.chamber_c) : std::vector<double>{};
    for (const auto& iv : runs_of(calm)) {
      if (static_cast<double>(iv.size()) < o_.settled_min_s) continue;
      for (std::size_t i = iv.first; i <= iv.last; ++i) {
        d12.push_back(t1[i] - t2[i]);
        if (!ta.empty()) d1a.push_back(t1[i] - ta[i]), d2a.push_back(t2[i] - ta[i]);
      }
      if (!span) span = iv;
      span->last = iv.last;
    }
    if (!span) return;
    const double off = median(d12);
    rep_.hold_offset_c = off;
    if (std::abs(off) <= o_.max_offset_c) return;
    // Which one is off: the one further from the air, when the air is recorded and tells.
    std::string who = "T1/T2";
    if (!d1a.empty()) {
      const double a1 = std::abs(median(d1a)), a2 = std::abs(median(d2a));
      if (a1 > a2 + o_.max_offset_c / 2) who = "T1";
      else if (a2 > a1 + o_.max_offset_c / 2) who = "T2";
    }
    add(who, QualityKind::offset, *span, off, "degC",
        "T1 - T2 is " + num(off) + " degC (median over " + std::to_string(d12.size()) +
            " s of settled holds), where a uniform coil reads the same on both; the bound is " + num(o_.max_offset_c) + " degC" +
            (who == "T1/T2" ? "" : "; " + who + " is the one off the chamber air"),
        "check the thermistors' calibration (an offset enters grad = T1 - T2 as a constant the model takes for drift)", false, false);
  }

  // Lags of the rates: Ta behind the setpoint, T2 behind Ta (the wall follows the air), T1
  // behind T2 (the centre follows the wall), within the coil's bounds; each out-of-bounds
  // pattern names the thermistor that explains it.
  void lags() {
    const auto r1 = rate("T1", run_.t1_c), r2 = rate("T2", run_.t2_c);
    if (r1.empty() || r2.empty()) return;
    double peak = 0.0;
    for (double v : r1) peak = std::max(peak, std::abs(v));
    if (peak < o_.min_rate_c_per_min) return;  // no ramp: nothing to lag
    const int k = static_cast<int>(o_.max_lag_scan_s);
    const auto core = lag_behind(r2, r1, k);
    std::optional<double> wall, air;
    if (run_.has_chamber()) {
      const auto ra = rate("Ta", run_.chamber_c);
      if (!ra.empty()) {
        wall = lag_behind(ra, r2, k);
        if (run_.has_setpoint()) {
          std::vector<char> all_good(n_, 1);
          for (std::size_t i = 0; i < n_; ++i) all_good[i] = std::isfinite(run_.setpoint_c[i]);
          auto sp = bridged(run_.setpoint_c, all_good);
          if (!sp.empty() && std::isfinite(sp[0])) air = lag_behind(derivative_per_min(sp, 1.0), ra, k);
        }
      }
    }
    if (core) rep_.core_lag_s = *core;
    if (wall) rep_.wall_lag_s = *wall;
    if (air) rep_.air_lag_s = *air;
    const Interval all{0, n_ - 1};
    auto says = [&](const std::string& who, double v, const std::string& what) {
      add(who, QualityKind::lag, all, v, "s", what,
          "check how " + who + " is mounted (its thermal contact) and its converter's filter; the data cannot say what the coil did",
          false, false);
    };
    auto s0 = [](const std::optional<double>& v) { return v ? num(*v, 0) : std::string("?"); };
    const bool air_bad = air && (*air > o_.max_air_lag_s || *air < o_.min_air_lag_s);
    if (air_bad)
      says("Ta", *air, "the chamber air's reading (chamber_c) lags the setpoint's rate by " + s0(air) + " s, outside " +
                           num(o_.min_air_lag_s, 0) + ".." + num(o_.max_air_lag_s, 0) + " s");
    // The ratio of the two lags, when both are measured, the air's reading is sound and the
    // wall's lag is long enough to divide by.
    // (a flag and a value, not an optional: g++ 12 at -O1 calls an optional's value maybe
    // uninitialized here, an error in the checking build)
    const bool has_ratio = core && wall && !air_bad && *wall > 30.0;
    const double ratio = has_ratio ? *core / *wall : 0.0;
    const bool core_long = core && (*core > o_.max_core_lag_s || (has_ratio && ratio > o_.max_core_wall_ratio));
    const bool core_short = core && (*core < o_.min_core_lag_s || (has_ratio && ratio < o_.min_core_wall_ratio));
    const bool wall_long = wall && !air_bad && *wall > o_.max_wall_lag_s;
    const bool wall_lead = wall && !air_bad && *wall < o_.min_wall_lag_s;
    const std::string figures = "T1 lags T2 by " + s0(core) + " s" + (wall ? ", T2 lags the air by " + s0(wall) + " s" : "") +
                                " (cross-correlation of the rates); the coil allows " + num(o_.min_core_lag_s, 0) + ".." +
                                num(o_.max_core_lag_s, 0) + " s for the first" +
                                (wall ? ", " + num(o_.min_wall_lag_s, 0) + ".." + num(o_.max_wall_lag_s, 0) + " s for the second" : "") +
                                (has_ratio ? " and a ratio of " + num(o_.min_core_wall_ratio, 1) + ".." + num(o_.max_core_wall_ratio, 1) +
                                                 " between them (here " + num(ratio, 2) + ")"
                                       : "");
    if (core_long && !wall_long)
      says("T1", *core, figures + ": T1 lags the coil it sits in");
    else if (wall_long || core_short)
      says("T2", wall_long ? *wall : *core, figures + ": T2 lags the coil's outer wall it should read (or T1 is not at the coil's centre)");
    else if (wall_lead && !air_bad)
      says("Ta", *wall, figures + ": the wall leads the air that heats it, so the air's reading lags");
  }

  const RunData& run_;
  const QualityOptions& o_;
  std::size_t n_;
  QualityReport rep_;
  std::map<std::string, std::vector<char>> good_;
};

}  // namespace

std::string_view to_string(QualityKind k) {
  switch (k) {
    case QualityKind::time_unit: return "time_unit";
    case QualityKind::time_step: return "time_step";
    case QualityKind::dropout: return "dropout";
    case QualityKind::stuck: return "stuck";
    case QualityKind::out_of_range: return "out_of_range";
    case QualityKind::noisy: return "noisy";
    case QualityKind::offset: return "offset";
    case QualityKind::lag: return "lag";
    case QualityKind::spike: return "spike";
    case QualityKind::saturation: return "saturation";
  }
  return "?";
}

std::string QualityFlag::message() const {
  return sensor + " " + std::string(to_string(kind)) + " at " + num(start_s, 0) + ".." + num(end_s, 0) + " s: " + evidence + "; " +
         remedy;
}

std::expected<void, std::string> QualityOptions::validate() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!(std::isfinite(min_temp_c) && std::isfinite(max_temp_c) && min_temp_c < max_temp_c))
    return std::unexpected("min_temp_c must be below max_temp_c (degC), got " + num(min_temp_c) + " and " + num(max_temp_c));
  const std::pair<const char*, double> must_be_positive[] = {
      {"stuck_min_s", stuck_min_s}, {"stuck_move_c", stuck_move_c}, {"stuck_lag_margin_s", stuck_lag_margin_s}, {"max_bridge_s", max_bridge_s},
      {"max_noise_c", max_noise_c}, {"max_air_noise_c", max_air_noise_c}, {"noise_window_s", noise_window_s},
      {"max_offset_c", max_offset_c}, {"settled_rate_c_per_min", settled_rate_c_per_min}, {"settled_min_s", settled_min_s},
      {"min_rate_c_per_min", min_rate_c_per_min}, {"max_lag_scan_s", max_lag_scan_s}, {"spike_sigma", spike_sigma},
      {"max_spike_s", max_spike_s}, {"saturation_min_s", saturation_min_s}};
  for (const auto& [name, v] : must_be_positive)
    if (!positive(v)) return std::unexpected(std::string(name) + " must be positive, got " + num(v));
  if (!(min_wall_lag_s < max_wall_lag_s)) return std::unexpected(std::string("min_wall_lag_s must be below max_wall_lag_s (s)"));
  if (!(min_core_lag_s < max_core_lag_s)) return std::unexpected(std::string("min_core_lag_s must be below max_core_lag_s (s)"));
  if (!(min_air_lag_s < max_air_lag_s)) return std::unexpected(std::string("min_air_lag_s must be below max_air_lag_s (s)"));
  if (!(min_core_wall_ratio < max_core_wall_ratio))
    return std::unexpected(std::string("min_core_wall_ratio must be below max_core_wall_ratio"));
  if (max_lag_scan_s <= std::max({max_wall_lag_s, max_core_lag_s, -min_wall_lag_s, -min_core_lag_s}))
    return std::unexpected(std::string("max_lag_scan_s must exceed every lag bound (s), else a lag beyond a bound is never seen"));
  return {};
}

QualityReport assess_quality(const RunData& run, const QualityOptions& options) { return Assessor(run, options).run(); }

Cleaning clean_run(const RunData& run, const QualityReport& report, CleanPolicy policy) {
  Cleaning c;
  c.run = run;
  if (!c.run.has_flags()) c.run.flags.assign(run.size(), 0);
  for (const auto& f : report.flags) {
    const bool clean = policy == CleanPolicy::all ? f.cleanable : f.clean_by_default;
    if (!clean || f.last >= run.size()) {
      c.remaining.push_back(f);
      continue;
    }
    const std::uint8_t bit = f.kind == QualityKind::dropout ? flag::missing : flag::out_of_range;
    for (std::size_t i = f.first; i <= f.last; ++i) c.run.flags[i] |= bit;
    const std::size_t count = f.last - f.first + 1;
    c.done.push_back(f.sensor + " " + std::string(to_string(f.kind)) + " at " + num(f.start_s, 0) + ".." + num(f.end_s, 0) + " s: " +
                     std::to_string(count) + " sample" + (count == 1 ? "" : "s") + " flagged " +
                     (bit == flag::missing ? "missing" : "out of range") +
                     " (skipped by the fit and Table 1, temperatures bridged by linear interpolation)");
    c.cleaned.push_back(f);
  }
  return c;
}

std::vector<std::string> identification_warnings(const Model& m, const RunData& run) {
  std::vector<std::string> out;
  for (std::size_t j = 0; j < m.terms.size(); ++j) {
    const auto& t = m.terms[j];
    if (std::abs(t.coef) > t.se_dph_per_unit) continue;
    // A partner it is collinear with (coef_corr holds [mu0, beta_1..m]).
    std::string partner;
    const auto& c = m.fit.coef_corr;
    for (std::size_t b = 0; b < m.terms.size() && j + 1 < c.size(); ++b)
      if (b != j && b + 1 < c[j + 1].size() && std::abs(c[j + 1][b + 1]) > 0.9)
        partner = "; it is correlated with " + m.terms[b].name() + " (r = " + num(c[j + 1][b + 1]) +
                  "): only their combination is determined (a hold right after a fast ramp separates them)";
    out.push_back("the coefficient of " + t.name() + " is " + num(t.coef, 4) + " +- " + num(t.se_dph_per_unit, 4) + " " +
                  coef_unit(*t.term.expr) + " (1 sigma): its standard error exceeds its value, so this run does not determine it" +
                  partner);
  }
  if (run.size() < 3 || m.terms.empty()) return out;
  // Excitation: the span and the rate of T1 over the run's good samples.
  std::vector<char> good(run.size(), 0);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < run.size(); ++i) {
    good[i] = std::isfinite(run.t1_c[i]) && !run.flagged(i);
    if (good[i]) lo = std::min(lo, run.t1_c[i]), hi = std::max(hi, run.t1_c[i]);
  }
  if (!(hi >= lo)) return out;
  const auto t1 = bridged(run.t1_c, good);
  const auto r1 = derivative_per_min(t1, 1.0);
  double peak = 0.0;
  std::size_t ramp_s = 0;
  constexpr double kRampRate = 0.1;  // degC/min: a ramp, against thermistor noise of 0.002 degC/min in d(T1)
  for (double v : r1) {
    peak = std::max(peak, std::abs(v));
    ramp_s += std::abs(v) >= kRampRate;
  }
  constexpr double kMinSpan = 2.0;  // degC: a few times a thermistor's calibration uncertainty
  if (hi - lo < kMinSpan)
    out.push_back("T1 spans only " + num(hi - lo) + " degC over the run (" + num(lo) + ".." + num(hi) +
                  " degC, under " + num(kMinSpan, 0) + "): no temperature excitation, the thermal terms are not identified; fit on a run with ramps");
  else if (peak < kRampRate)
    out.push_back("T1's rate never reaches " + num(kRampRate, 1) + " degC/min (peak " + num(peak, 3) +
                  "): no ramp, the rate terms are not identified");
  bool any_auto = false;
  for (const auto& t : m.terms) any_auto = any_auto || t.term.lag.automatic;
  if (any_auto && ramp_s < static_cast<std::size_t>(m.max_lag_s) && peak >= kRampRate)
    out.push_back("the ramps (|d(T1)| >= " + num(kRampRate, 1) + " degC/min) total " + std::to_string(ramp_s) +
                  " s, shorter than the lag range 0.." + std::to_string(m.max_lag_s) +
                  " s scanned: the run is too short for the lag range, the lag is not identified");
  return out;
}

}  // namespace fogbench::model
