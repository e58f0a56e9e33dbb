// Internal: the lag scan. For a regressor x delayed by i seconds, i = 0..L, every sum the
// normal equations need is a cross-correlation of x with a fixed series, so all lags cost a
// few FFTs (O(N log N)) instead of one least-squares solve per lag (O(N L)).
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace fogbench::model::detail {

// The transforms of a series' overlap-save blocks, end to end; made and read by LagScanner only.
using Spectrum = std::vector<std::complex<double>>;

// A regressor extended at the front by L copies of its first value (the steady hold before
// the run), so that x(t - i) = ext[t + L - i] exists for every t >= 0 and i <= L.
struct Lagged {
  std::vector<double> ext;      // length N + L
  mutable Spectrum spec;        // FFT of ext's blocks, computed on first use (while empty: clear() it
                                // when ext changes, and its capacity is reused)
};
Lagged make_lagged(std::span<const double> x, int max_lag);

class LagScanner {
 public:
  // w: the weight of each sample t = 0..N-1 (0 or 1: skipped samples have 0).
  LagScanner(std::size_t n, int max_lag, std::vector<double> w);

  std::size_t n() const { return n_; }
  int max_lag() const { return max_lag_; }
  const std::vector<double>& weights() const { return w_; }

  // New weights for the same N and L (a fit's next iteration): the buffers are reused.
  void set_weights(std::span<const double> w);

  // C[i] = sum_t u(t) x(t - i) for i = 0..L, u already weighted (length N).
  std::vector<double> corr(const Lagged& x, std::span<const double> u) const;
  // The same with u's spectrum computed once for several regressors.
  Spectrum spectrum_of_target(std::span<const double> u) const;
  std::vector<double> corr(const Lagged& x, const Spectrum& u_spec) const;
  // S[i] = sum_t w(t) v(t - i) for an extended series v (length N + L).
  std::vector<double> wsum(std::span<const double> v_ext) const;
  // The same three into the caller's buffers (resized, their capacity reused: a fit's
  // iterations allocate nothing once the buffers have their size). The same numbers.
  void spectrum_of_target(std::span<const double> u, Spectrum& out) const;
  void corr(const Lagged& x, const Spectrum& u_spec, std::vector<double>& out) const;
  void wsum(std::span<const double> v_ext, std::vector<double>& out) const;
  // spectrum_of_target(u) and wsum(v_ext) of a product u = a * b or v_ext = a * b (each sample's
  // product as an array of them holds it), made block by block: no run-length array of the
  // product (2.1 MB a call on a 3-day run). The same numbers.
  void spectrum_of_product(std::span<const double> a, std::span<const double> b, Spectrum& out) const;
  void wsum_product(std::span<const double> a_ext, std::span<const double> b_ext, std::vector<double>& out) const;
  // spectrum_of_target of u(t) = a(t) b(t - lag), b's first value standing in before its start.
  void spectrum_of_lagged_product(std::span<const double> a, std::span<const double> b, std::size_t lag, Spectrum& out) const;
  // Computes x's spectrum now (corr() would on first use): a Lagged read by several threads
  // at once must have it before it is shared.
  void ready(const Lagged& x) const { (void)spec_of(x); }
  // The spectrum corr() reads for an extension ext (a Lagged's ext: length N + L) into out
  // (resized), for a caller that sets it into a Lagged shared by threads under its own lock.
  void lagged_spectrum(std::span<const double> ext, Spectrum& out) const;

 private:
  const Spectrum& spec_of(const Lagged& x) const;
  // wsum's sparse path over v(j), j = 0..size-1 (an array's samples, or a product's).
  template <class At>
  void window_sums(std::size_t size, At v, std::vector<double>& out) const;
  void weights_changed();  // zeros_, sparse_zeros_ and w_spec_ from w_
  std::size_t n_;
  int max_lag_;
  std::size_t m_;                    // FFT length of a block, >= step_ + L
  std::size_t step_;                 // target samples per block
  std::size_t blocks_;               // ceil(N / step_)
  std::vector<double> w_;
  std::vector<std::size_t> zeros_;   // samples with weight 0 (sparse corrections)
  bool sparse_zeros_ = true;
  Spectrum w_spec_;                  // for dense weights
};

}  // namespace fogbench::model::detail
