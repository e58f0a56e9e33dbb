// The regression kernel (see lsq.hpp): streaming Householder QR of the augmented design.
#include "lsq.hpp"

#include <cassert>
#include <cmath>

namespace fogbench::model::detail {
namespace {
// A column whose part orthogonal to the ones before it is below this share of its norm makes
// the design singular: at 1e-10 a coefficient keeps about 6 of double's 16 digits.
constexpr double kSingular = 1e-10;
// Rows folded at once: large enough that the fold's fixed cost is spread, small enough that
// the buffer stays in cache (256 rows x (k+1) doubles).
constexpr Eigen::Index kBlock = 256;
}  // namespace

LeastSquares::LeastSquares(std::size_t k)
    : k_(k),
      block_(kBlock),
      buf_(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(k) + 1 + kBlock, static_cast<Eigen::Index>(k) + 1)),
      col_ss_(k, 0.0) {}

void LeastSquares::add(std::span<const double> x, double y, double w) {
  assert(x.size() == k_);
  if (!(w > 0.0)) return;
  const double s = std::sqrt(w);
  const Eigen::Index row = static_cast<Eigen::Index>(k_) + 1 + pending_;
  for (std::size_t j = 0; j < k_; ++j) {
    buf_(row, static_cast<Eigen::Index>(j)) = s * x[j];
    col_ss_[j] += w * x[j] * x[j];
  }
  buf_(row, static_cast<Eigen::Index>(k_)) = s * y;
  sw_ += w;
  const double d = y - y_mean_;
  y_mean_ += w / sw_ * d;
  y_m2_ += w * d * (y - y_mean_);
  if (++pending_ == block_) fold();
}

void LeastSquares::fold() {
  if (pending_ == 0) return;
  const Eigen::Index kk = static_cast<Eigen::Index>(k_) + 1;
  qr_.compute(buf_.topRows(kk + pending_));
  buf_.topRows(kk) = qr_.matrixQR().topRows(kk).triangularView<Eigen::Upper>();
  pending_ = 0;
}

bool LeastSquares::singular() {
  if (sw_ < static_cast<double>(k_)) return true;
  for (std::size_t j = 0; j < k_; ++j) {
    const auto jj = static_cast<Eigen::Index>(j);
    if (!(std::abs(buf_(jj, jj)) > kSingular * std::sqrt(col_ss_[j]))) return true;
  }
  return false;
}

Eigen::MatrixXd LeastSquares::covariance(double s2) {
  fold();
  if (singular()) return {};
  const auto k = static_cast<Eigen::Index>(k_);
  const Eigen::MatrixXd rinv =
      buf_.topLeftCorner(k, k).triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(k, k));
  return s2 * rinv * rinv.transpose();
}

LeastSquaresResult LeastSquares::solve(double extra_params) {
  fold();
  LeastSquaresResult r;
  if (singular()) return r;
  const auto k = static_cast<Eigen::Index>(k_);
  const Eigen::VectorXd th = buf_.topLeftCorner(k, k).triangularView<Eigen::Upper>().solve(buf_.col(k).head(k));
  r.theta.assign(th.data(), th.data() + k);
  r.sse = buf_(k, k) * buf_(k, k);
  r.dof = sw_ - static_cast<double>(k_) - extra_params;
  r.sigma = r.dof > 0.0 ? std::sqrt(r.sse / r.dof) : 0.0;
  r.r2 = y_m2_ > 0.0 ? 1.0 - r.sse / y_m2_ : 0.0;
  r.cov = covariance(r.dof > 0.0 ? r.sse / r.dof : 0.0);
  r.se.resize(k_);
  for (std::size_t j = 0; j < k_; ++j) r.se[j] = std::sqrt(std::max(0.0, r.cov(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(j))));
  r.ok = true;
  return r;
}

}  // namespace fogbench::model::detail
