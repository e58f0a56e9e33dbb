// The covariance of overlapping Allan variance estimates under white, flicker and random-walk
// rate noise; see allan_cov.hpp.
#include "allan_cov.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fogbench::model::detail {

double AvarLaws::at(std::int64_t m) const {
  const auto md = static_cast<double>(m);
  return white / md + flicker + walk * md;
}

namespace {

// The angle x (the rate's running sum, (deg/h) s) seen through its generalized covariance at
// lags 0..reach samples: only combinations whose weights annihilate polynomials of degree 3
// have a covariance, and a product of two second differences (two Allan points' terms) does:
//   white rate of variance c0:  -c0 |h| / 2
//   flicker (AVAR cf):          cf h^2 ln|h| / (4 ln 2)
//   random walk (AVAR cw m):    cw |h|^3 / 4   (increments of variance 3 cw a second: q |h|^3 / 12)
// Each gives back its Allan variance: Var of (x(t+2m) - 2 x(t+m) + x(t)) / m is 2 AVAR(m).
std::vector<double> angle_gcov_table(const AvarLaws& law, std::size_t reach) {
  std::vector<double> k(reach + 1, 0.0);
  const double cf = law.flicker / (4.0 * std::numbers::ln2);
  for (std::size_t i = 1; i <= reach; ++i) {
    const auto h = static_cast<double>(i);
    k[i] = -0.5 * law.white * h + cf * h * h * std::log(h) + 0.25 * law.walk * h * h * h;
  }
  return k;
}

}  // namespace

std::vector<double> overlapping_avar_cov(const AvarLaws& law, std::span<const std::int64_t> ms, std::size_t len) {
  const std::size_t k = ms.size();
  std::vector<double> cov(k * k, 0.0);
  const auto L = static_cast<std::int64_t>(len);
  std::int64_t mmax = 1;
  for (auto m : ms) mmax = std::max(mmax, m);
  const std::vector<double> kt = angle_gcov_table(law, len + 4 * static_cast<std::size_t>(mmax) + 2);
  auto K = [&](std::int64_t h) { return kt[static_cast<std::size_t>(h < 0 ? -h : h)]; };
  constexpr double al[3] = {1.0, -2.0, 1.0};
  for (std::size_t i = 0; i < k; ++i) {
    for (std::size_t j = i; j < k; ++j) {
      const std::int64_t mi = ms[i], mj = ms[j];
      const std::int64_t ni = L - 2 * mi + 1, nj = L - 2 * mj + 1;
      if (mi < 1 || mj < 1 || ni < 2 || nj < 2) continue;
      // The second differences' cross-covariance c(d) = Cov(z_i(s), z_j(s + d)) vanishes for
      // white noise and the walk beyond |d| = 2 (mi + mj); the flicker's falls as 2 cf' mi mj /
      // d^2, whose squares past another 4 max(mi, mj) add under 1e-4 of the sum.
      const std::int64_t reach = 2 * (mi + mj) + 4 * std::max(mi, mj);
      const std::int64_t dlo = std::max(-(ni - 1), -reach), dhi = std::min(nj - 1, reach);
      double sum = 0.0;
      for (std::int64_t d = dlo; d <= dhi; ++d) {
        const std::int64_t pairs = std::min(ni, nj - d) - std::max<std::int64_t>(0, -d);
        if (pairs <= 0) continue;
        double c = 0.0;
        for (int p = 0; p < 3; ++p)
          for (int q = 0; q < 3; ++q) c += al[p] * al[q] * K(d + q * mj - p * mi);
        c /= static_cast<double>(mi) * static_cast<double>(mj);
        sum += static_cast<double>(pairs) * c * c;
      }
      // Each estimate is sum z^2 / (2 n); Cov(z_i^2, z_j^2) = 2 c^2 for Gaussian z.
      const double v = sum / (2.0 * static_cast<double>(ni) * static_cast<double>(nj));
      cov[i * k + j] = v;
      cov[j * k + i] = v;
    }
  }
  return cov;
}

double overlapping_avar_edf(const AvarLaws& law, std::int64_t m, std::size_t len) {
  const std::int64_t one[1] = {m};
  const double var = overlapping_avar_cov(law, one, len)[0];
  const double e = law.at(m);
  return var > 0.0 ? 2.0 * e * e / var : 0.0;
}

}  // namespace fogbench::model::detail
