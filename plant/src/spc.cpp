// The fleet statistics (spc.hpp). Pure.
#include "fogbench/plant/spc.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace fogbench::plant::spc {

std::string to_string(Rule r) {
  switch (r) {
    case Rule::beyond_3_sigma: return "we1_beyond_3_sigma";
    case Rule::two_of_three: return "we2_two_of_three_beyond_2_sigma";
    case Rule::four_of_five: return "we3_four_of_five_beyond_1_sigma";
    case Rule::eight_one_side: return "we4_eight_on_one_side";
    case Rule::moving_range: return "moving_range_above_limit";
  }
  return "?";
}

std::vector<Signal> western_electric(std::span<const double> x, double center, double sigma) {
  std::vector<Signal> out;
  const std::size_t n = x.size();
  auto z = [&](std::size_t i) { return sigma > 0 ? (x[i] - center) / sigma : 0.0; };
  for (std::size_t i = 0; i < n; ++i) {
    const double zi = z(i);
    if (std::abs(zi) > 3) out.push_back({Rule::beyond_3_sigma, i, i, zi > 0 ? 1 : -1});
    for (int side : {1, -1}) {
      // Rule 2: of the last three (this one among them and beyond), two beyond 2 sigma.
      if (i >= 2 && side * zi > 2) {
        int k = 0;
        for (std::size_t j = i - 2; j <= i; ++j) k += side * z(j) > 2;
        if (k >= 2) out.push_back({Rule::two_of_three, i, i - 2, side});
      }
      // Rule 3: of the last five, four beyond 1 sigma.
      if (i >= 4 && side * zi > 1) {
        int k = 0;
        for (std::size_t j = i - 4; j <= i; ++j) k += side * z(j) > 1;
        if (k >= 4) out.push_back({Rule::four_of_five, i, i - 4, side});
      }
      // Rule 4: the last eight on this side.
      if (i >= 7) {
        bool all = true;
        for (std::size_t j = i - 7; j <= i && all; ++j) all = side * z(j) > 0;
        if (all) out.push_back({Rule::eight_one_side, i, i - 7, side});
      }
    }
  }
  return out;
}

ImrChart imr_chart(std::span<const double> x, std::size_t begin, std::size_t end) {
  if (end > x.size() || begin >= end || end - begin < 2)
    throw std::invalid_argument("the baseline window needs at least 2 values inside the series");
  ImrChart c;
  c.baseline_begin = begin;
  c.baseline_end = end;
  c.mr.assign(x.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 1; i < x.size(); ++i) c.mr[i] = std::abs(x[i] - x[i - 1]);
  double sum = 0, mrs = 0;
  for (std::size_t i = begin; i < end; ++i) sum += x[i];
  for (std::size_t i = begin + 1; i < end; ++i) mrs += c.mr[i];
  c.center = sum / static_cast<double>(end - begin);
  c.mr_bar = mrs / static_cast<double>(end - begin - 1);
  c.sigma = c.mr_bar / kD2;
  c.ucl = c.center + 3 * c.sigma;
  c.lcl = c.center - 3 * c.sigma;
  c.mr_ucl = kD4 * c.mr_bar;
  c.signals = western_electric(x, c.center, c.sigma);
  for (std::size_t i = 1; i < x.size(); ++i)
    if (c.mr[i] > c.mr_ucl) c.signals.push_back({Rule::moving_range, i, i - 1, 0});
  std::stable_sort(c.signals.begin(), c.signals.end(), [](const Signal& a, const Signal& b) {
    return a.index != b.index ? a.index < b.index : static_cast<int>(a.rule) < static_cast<int>(b.rule);
  });
  return c;
}

Summary summarize(std::span<const double> x) {
  Summary s;
  s.n = x.size();
  if (x.empty()) return s;
  std::vector<double> v(x.begin(), x.end());
  std::sort(v.begin(), v.end());
  s.min = v.front();
  s.max = v.back();
  s.median = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  if (v.size() >= 2) {
    double ss = 0;
    for (double a : v) ss += (a - s.mean) * (a - s.mean);
    s.sd = std::sqrt(ss / static_cast<double>(v.size() - 1));
  }
  return s;
}

namespace {

// The regularised incomplete beta I_x(a, b) by its continued fraction (Lentz).
double betacf(double a, double b, double x) {
  constexpr double kTiny = 1e-300, kEps = 1e-15;
  const double qab = a + b, qap = a + 1, qam = a - 1;
  double c = 1, d = 1 - qab * x / qap;
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1 / d;
  double h = d;
  for (int m = 1; m <= 500; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
    d = 1 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1 / d;
    h *= d * c;
    aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
    d = 1 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1) < kEps) break;
  }
  return h;
}

double lgam(double v) {
  int sign = 0;
  return ::lgamma_r(v, &sign);
}

double incomplete_beta(double a, double b, double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  const double bt = std::exp(lgam(a + b) - lgam(a) - lgam(b) + a * std::log(x) + b * std::log1p(-x));
  if (x < (a + 1) / (a + b + 2)) return bt * betacf(a, b, x) / a;
  return 1 - bt * betacf(b, a, 1 - x) / b;
}

}  // namespace

double student_t_cdf(double t, double dof) {
  const double x = dof / (dof + t * t);
  const double tail = 0.5 * incomplete_beta(dof / 2, 0.5, x);
  return t >= 0 ? 1 - tail : tail;
}

double student_t_quantile(double p, double dof) {
  if (!(p > 0 && p < 1) || !(dof > 0)) return std::numeric_limits<double>::quiet_NaN();
  double lo = -1e3, hi = 1e3;
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (student_t_cdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Comparison welch(std::span<const double> a, std::span<const double> b, double level) {
  if (a.size() < 2 || b.size() < 2) throw std::invalid_argument("Welch's comparison needs two values in each group");
  Comparison c;
  c.a = summarize(a);
  c.b = summarize(b);
  c.level = level;
  const double va = c.a.sd * c.a.sd / static_cast<double>(c.a.n);
  const double vb = c.b.sd * c.b.sd / static_cast<double>(c.b.n);
  c.diff = c.a.mean - c.b.mean;
  c.se = std::sqrt(va + vb);
  c.dof = (va + vb) * (va + vb) /
          (va * va / static_cast<double>(c.a.n - 1) + vb * vb / static_cast<double>(c.b.n - 1));
  if (!(c.se > 0)) {  // both constant: no spread to compare against
    c.dof = static_cast<double>(c.a.n + c.b.n - 2);
    c.t_crit = student_t_quantile(0.5 + level / 2, c.dof);
    c.low = c.high = c.diff;
    c.t = c.diff == 0 ? 0 : std::copysign(std::numeric_limits<double>::infinity(), c.diff);
    c.p_value = c.diff == 0 ? 1 : 0;
    return c;
  }
  c.t_crit = student_t_quantile(0.5 + level / 2, c.dof);
  c.low = c.diff - c.t_crit * c.se;
  c.high = c.diff + c.t_crit * c.se;
  c.t = c.diff / c.se;
  c.p_value = 2 * (1 - student_t_cdf(std::abs(c.t), c.dof));
  return c;
}

}  // namespace fogbench::plant::spc
