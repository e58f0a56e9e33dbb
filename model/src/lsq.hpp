// Internal: the regression kernel. Weighted linear least squares by a streaming Householder QR
// of the augmented design [X y]: rows arrive one at a time (no N x k matrix is kept, N is
// large and k small), are buffered in blocks and folded into a (k+1) x (k+1) triangle R. Its
// last diagonal entry is the root of the residual sum of squares; theta solves R_xx theta =
// r_xy. No normal equations: their condition is the square of the design's, which loses the
// digits NIST's Longley problem asks for (tests/model/strd_test.cpp).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <span>
#include <vector>

namespace fogbench::model::detail {

struct LeastSquaresResult {
  bool ok = false;               // false: no rows, fewer rows than columns, or a singular design
  std::vector<double> theta;     // the coefficients, in the columns' order
  std::vector<double> se;        // their 1-sigma standard errors, in the coefficients' units
  Eigen::MatrixXd cov;           // their covariance, s2 (X' W X)^-1
  double sse = 0.0;              // weighted residual sum of squares, in y's unit squared
  double dof = 0.0;              // sum of the weights (the rows) - columns - extra parameters
  double sigma = 0.0;            // residual standard deviation sqrt(sse / dof), in y's unit
  double r2 = 0.0;               // 1 - sse / (weighted sum of squares of y about its mean)
};

class LeastSquares {
 public:
  // k: the number of columns (a constant column, if any, is one of them).
  explicit LeastSquares(std::size_t k);

  // One row x (k values) with response y and weight w >= 0 (0: the row is skipped, NaN and all).
  void add(std::span<const double> x, double y, double w = 1.0);

  // The fit. extra_params: parameters estimated outside the regression (a searched lag, AR
  // coefficients) that also cost a degree of freedom in s2.
  LeastSquaresResult solve(double extra_params = 0.0);

  // For coefficients found elsewhere: their covariance s2 (X' W X)^-1 for the rows given so
  // far, with the caller's residual variance s2. Empty when the design is singular.
  Eigen::MatrixXd covariance(double s2);

  std::size_t columns() const { return k_; }
  double weight_sum() const { return sw_; }

 private:
  void fold();                   // folds the buffered rows into R
  bool singular();               // R's diagonal against the columns' norms

  std::size_t k_;
  Eigen::Index block_;           // rows buffered before a fold
  Eigen::MatrixXd buf_;          // top k+1 rows: R; then up to block_ new rows
  Eigen::Index pending_ = 0;     // new rows in buf_
  Eigen::HouseholderQR<Eigen::MatrixXd> qr_;
  std::vector<double> col_ss_;   // sum w x_j^2 of each column (the scale of the rank test)
  double sw_ = 0.0;              // sum of the weights
  double y_mean_ = 0.0, y_m2_ = 0.0;  // weighted running mean and centred sum of squares of y
};

}  // namespace fogbench::model::detail
