// FFT cross-correlations for the lag scan, on FFTW (a plan per length, cached).
#include "lagscan.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cassert>
#include <complex>
#include <map>
#include <memory>
#include <mutex>

namespace fogbench::model::detail {
namespace {

// A real transform of even length m is done as a complex one of length m/2 (the even and odd
// samples as real and imaginary parts) plus a twiddle pass: FFTW plans a complex transform
// in a tenth of the time it takes for its r2c/c2r pair (0.2 ms against 2.4 ms at m = 8,192,
// most of a short fit), and runs it as fast.
//
// FFTW's planner is not thread-safe; its execute functions are. Plans are made once per
// length under this mutex and reused with fftw_malloc'ed arrays (same alignment) forever.
struct Plans {
  fftw_plan forward, backward;               // complex, length m/2, out of place
  std::vector<std::complex<double>> twiddle;  // exp(-2 pi i f / m), f = 0..m/2
};
std::mutex plan_mutex;
std::map<std::size_t, Plans>& plan_cache() {
  static std::map<std::size_t, Plans> cache;
  return cache;
}

const Plans& plans_for(std::size_t m) {
  assert(m % 2 == 0);
  std::lock_guard lock(plan_mutex);
  auto& cache = plan_cache();
  auto it = cache.find(m);
  if (it != cache.end()) return it->second;
  const std::size_t half = m / 2;
  auto* in = static_cast<fftw_complex*>(fftw_malloc(sizeof(fftw_complex) * half));
  auto* out = static_cast<fftw_complex*>(fftw_malloc(sizeof(fftw_complex) * (half + 1)));
  const int len = static_cast<int>(half);
  Plans p{fftw_plan_dft_1d(len, in, out, FFTW_FORWARD, FFTW_ESTIMATE),
          fftw_plan_dft_1d(len, in, out, FFTW_BACKWARD, FFTW_ESTIMATE), {}};
  fftw_free(in);
  fftw_free(out);
  constexpr double two_pi = 6.283185307179586476925286766559;
  p.twiddle.resize(half + 1);
  for (std::size_t f = 0; f <= half; ++f)
    p.twiddle[f] = std::polar(1.0, -two_pi * static_cast<double>(f) / static_cast<double>(m));
  return cache.emplace(m, std::move(p)).first->second;
}

// Smallest even length >= n whose prime factors are 2, 3, 5 and 7 (FFTW is fast on those).
std::size_t good_length(std::size_t n) {
  for (std::size_t m = std::max<std::size_t>(n + n % 2, 2);; m += 2) {
    std::size_t r = m;
    for (std::size_t p : {2u, 3u, 5u, 7u})
      while (r % p == 0) r /= p;
    if (r == 1) return m;
  }
}

// Work arrays for one transform length, kept per thread: allocating and faulting in fresh
// pages for every transform cost as much as the transform itself.
struct Buffers {
  explicit Buffers(std::size_t m)
      : real(static_cast<double*>(fftw_malloc(sizeof(double) * m))),
        cplx(static_cast<fftw_complex*>(fftw_malloc(sizeof(fftw_complex) * (m / 2 + 1)))) {}
  ~Buffers() {
    fftw_free(real);
    fftw_free(cplx);
  }
  Buffers(const Buffers&) = delete;
  Buffers& operator=(const Buffers&) = delete;
  double* real;
  fftw_complex* cplx;
};

Buffers& buffers_for(std::size_t m) {
  thread_local std::size_t size = 0;
  thread_local std::unique_ptr<Buffers> b;
  if (size != m) {
    b = std::make_unique<Buffers>(m);
    size = m;
  }
  return *b;
}

// The FFT of each block of a series of `size` samples, laid end to end: block b is
// x[b*step, b*step + take), zero-padded to m; load(lo, hi, dst) writes x[lo, hi) to dst (a series
// held as an array, or a product of two made block by block: no run-length array for it).
// s is resized (its capacity reused).
template <class Load>
void forward_blocks_of(std::size_t size, Load load, std::size_t m, std::size_t step, std::size_t take, std::size_t blocks,
                       Spectrum& s) {
  assert(take <= m);
  Buffers& b = buffers_for(m);
  const Plans& plan = plans_for(m);
  const std::size_t half = m / 2, bins = half + 1;
  s.resize(blocks * bins);
  auto* packed = reinterpret_cast<fftw_complex*>(b.real);  // z[j] = x[2j] + i x[2j+1]
  for (std::size_t k = 0; k < blocks; ++k) {
    const std::size_t lo = std::min(k * step, size);
    const std::size_t hi = std::min(lo + take, size);
    load(lo, hi, b.real);
    std::fill(b.real + (hi - lo), b.real + m, 0.0);
    fftw_execute_dft(plan.forward, packed, b.cplx);
    // Z = E + i O, with E and O the transforms of the even and odd samples:
    // E[f] = (Z[f] + conj Z[-f]) / 2, O[f] = (Z[f] - conj Z[-f]) / 2i, X[f] = E[f] + w^f O[f].
    std::complex<double>* out = s.data() + k * bins;
    for (std::size_t f = 0; f <= half; ++f) {
      const std::size_t a = f == half ? 0 : f, c = f == 0 ? 0 : half - f;
      const std::complex<double> z{b.cplx[a][0], b.cplx[a][1]}, zc{b.cplx[c][0], -b.cplx[c][1]};
      const std::complex<double> even = 0.5 * (z + zc), odd = std::complex<double>(0.0, -0.5) * (z - zc);
      out[f] = even + plan.twiddle[f] * odd;
    }
  }
}

void forward_blocks(std::span<const double> x, std::size_t m, std::size_t step, std::size_t take, std::size_t blocks,
                    Spectrum& s) {
  forward_blocks_of(
      x.size(),
      [&](std::size_t lo, std::size_t hi, double* dst) {
        std::copy(x.begin() + static_cast<std::ptrdiff_t>(lo), x.begin() + static_cast<std::ptrdiff_t>(hi), dst);
      },
      m, step, take, blocks, s);
}

// The same of the product a(t) b(t), each product made as it is loaded (the numbers of a
// product array, without the array).
void forward_blocks_product(std::span<const double> a, std::span<const double> b, std::size_t m, std::size_t step,
                            std::size_t take, std::size_t blocks, Spectrum& s) {
  assert(a.size() == b.size());
  forward_blocks_of(
      a.size(),
      [&](std::size_t lo, std::size_t hi, double* dst) {
        for (std::size_t t = lo; t < hi; ++t) dst[t - lo] = a[t] * b[t];
      },
      m, step, take, blocks, s);
}

// The same of a(t) b(t - lag), b's first value standing in before its start.
void forward_blocks_lagged_product(std::span<const double> a, std::span<const double> b, std::size_t lag, std::size_t m,
                                   std::size_t step, std::size_t take, std::size_t blocks, Spectrum& s) {
  forward_blocks_of(
      a.size(),
      [&](std::size_t lo, std::size_t hi, double* dst) {
        for (std::size_t t = lo; t < hi; ++t) dst[t - lo] = a[t] * b[t >= lag ? t - lag : 0];
      },
      m, step, take, blocks, s);
}

// c[k] = sum_t u(t) x(t + k) for k = 0..kmax, from the block spectra of x and u: the blocks'
// products are summed before one inverse transform (the correlation is linear in them).
// out[i] = c[kmax - i], i = 0..kmax (lag i of the scan is shift k = kmax - i); out is resized.
void correlate_reversed(const Spectrum& x, const Spectrum& u, std::size_t m, std::size_t kmax, std::vector<double>& out) {
  assert(x.size() == u.size());
  assert(kmax < m);
  Buffers& b = buffers_for(m);
  const Plans& plan = plans_for(m);
  const std::size_t half = m / 2, bins = half + 1;
  thread_local std::vector<std::complex<double>> sum;
  sum.assign(bins, {0.0, 0.0});
  for (std::size_t off = 0; off < x.size(); off += bins)
    for (std::size_t f = 0; f < bins; ++f) sum[f] += x[off + f] * std::conj(u[off + f]);
  // The inverse of the forward packing: Z[f] = E[f] + i O[f] with E[f] = X[f] + conj X[m/2-f]
  // and O[f] = (X[f] - conj X[m/2-f]) conj(w^f), each twice the half-length transform, so that
  // the result is m times the signal, as FFTW's c2r gives it.
  auto* packed = reinterpret_cast<fftw_complex*>(b.real);
  for (std::size_t f = 0; f < half; ++f) {
    const std::complex<double> xf = sum[f], xc = std::conj(sum[half - f]);
    const std::complex<double> z = (xf + xc) + std::complex<double>(0.0, 1.0) * ((xf - xc) * std::conj(plan.twiddle[f]));
    packed[f][0] = z.real();
    packed[f][1] = z.imag();
  }
  fftw_execute_dft(plan.backward, packed, b.cplx);  // b.cplx[j] = m (x[2j] + i x[2j+1])
  out.resize(kmax + 1);
  const double scale = 1.0 / static_cast<double>(m);
  for (std::size_t k = 0; k <= kmax; ++k) out[kmax - k] = b.cplx[k / 2][k % 2] * scale;
}

}  // namespace

Lagged make_lagged(std::span<const double> x, int max_lag) {
  Lagged l;
  l.ext.assign(static_cast<std::size_t>(max_lag), x.empty() ? 0.0 : x[0]);
  l.ext.insert(l.ext.end(), x.begin(), x.end());
  return l;
}

LagScanner::LagScanner(std::size_t n, int max_lag, std::vector<double> w)
    : n_(n), max_lag_(max_lag), w_(std::move(w)) {
  // Overlap-save: a run longer than one block is cut into blocks of `step_` samples of the
  // target, each correlated with the next step_ + L samples of the regressor in a transform
  // of m_ points. Small fixed transforms are planned far faster than one of the run's length
  // (FFTW took ~4 ms to plan 87,480 points, a third of a day's paper fit) and cost no more.
  const auto L = static_cast<std::size_t>(max_lag_);
  const std::size_t whole = good_length(n_ + L);
  std::size_t block = 8192;
  while (block < 4 * (L + 1)) block *= 2;
  if (whole <= block) {
    m_ = whole;
    step_ = std::max<std::size_t>(n_, 1);
    blocks_ = 1;
  } else {
    m_ = block;
    step_ = block - L;
    blocks_ = (n_ + step_ - 1) / step_;
  }
  weights_changed();
}

void LagScanner::set_weights(std::span<const double> w) {
  w_.assign(w.begin(), w.end());
  weights_changed();
}

void LagScanner::weights_changed() {
  assert(w_.size() == n_);
  zeros_.clear();
  for (std::size_t t = 0; t < n_; ++t)
    if (w_[t] == 0.0) zeros_.push_back(t);
  // Sparse corrections cost |zeros| * L; past N/(8 log N) or so an FFT is cheaper.
  sparse_zeros_ = zeros_.size() * static_cast<std::size_t>(max_lag_ + 1) < 4 * n_;
  if (!sparse_zeros_) spectrum_of_target(w_, w_spec_);
}

const Spectrum& LagScanner::spec_of(const Lagged& x) const {
  if (x.spec.empty()) lagged_spectrum(x.ext, x.spec);
  return x.spec;
}

void LagScanner::lagged_spectrum(std::span<const double> ext, Spectrum& out) const {
  forward_blocks(ext, m_, step_, step_ + static_cast<std::size_t>(max_lag_), blocks_, out);
}

void LagScanner::spectrum_of_target(std::span<const double> u, Spectrum& out) const {
  assert(u.size() == n_);
  forward_blocks(u, m_, step_, step_, blocks_, out);
}

void LagScanner::spectrum_of_product(std::span<const double> a, std::span<const double> b, Spectrum& out) const {
  assert(a.size() == n_ && b.size() == n_);
  forward_blocks_product(a, b, m_, step_, step_, blocks_, out);
}

void LagScanner::spectrum_of_lagged_product(std::span<const double> a, std::span<const double> b, std::size_t lag,
                                            Spectrum& out) const {
  assert(a.size() == n_ && (n_ == 0 || (!b.empty() && b.size() + lag >= n_)));
  forward_blocks_lagged_product(a, b, lag, m_, step_, step_, blocks_, out);
}

Spectrum LagScanner::spectrum_of_target(std::span<const double> u) const {
  Spectrum s;
  spectrum_of_target(u, s);
  return s;
}

void LagScanner::corr(const Lagged& x, const Spectrum& u_spec, std::vector<double>& out) const {
  correlate_reversed(spec_of(x), u_spec, m_, static_cast<std::size_t>(max_lag_), out);
}

std::vector<double> LagScanner::corr(const Lagged& x, const Spectrum& u_spec) const {
  std::vector<double> out;
  corr(x, u_spec, out);
  return out;
}

std::vector<double> LagScanner::corr(const Lagged& x, std::span<const double> u) const {
  return corr(x, spectrum_of_target(u));
}

std::vector<double> LagScanner::wsum(std::span<const double> v) const {
  std::vector<double> out;
  wsum(v, out);
  return out;
}

void LagScanner::wsum(std::span<const double> v, std::vector<double>& out) const {
  const auto L = static_cast<std::size_t>(max_lag_);
  assert(v.size() == n_ + L);
  if (!sparse_zeros_) {
    thread_local Spectrum vs;
    forward_blocks(v, m_, step_, step_ + L, blocks_, vs);
    correlate_reversed(vs, w_spec_, m_, L, out);
    return;
  }
  window_sums(v.size(), [&](std::size_t j) { return v[j]; }, out);
}

void LagScanner::wsum_product(std::span<const double> a, std::span<const double> b, std::vector<double>& out) const {
  const auto L = static_cast<std::size_t>(max_lag_);
  assert(a.size() == n_ + L && b.size() == a.size());
  if (!sparse_zeros_) {
    thread_local Spectrum vs;
    forward_blocks_product(a, b, m_, step_, step_ + L, blocks_, vs);
    correlate_reversed(vs, w_spec_, m_, L, out);
    return;
  }
  window_sums(a.size(), [&](std::size_t j) { return a[j] * b[j]; }, out);
}

template <class At>
void LagScanner::window_sums(std::size_t size, At v, std::vector<double>& out) const {
  const auto L = static_cast<std::size_t>(max_lag_);
  out.resize(L + 1);
  // All-ones window sums from prefix sums, minus the samples of weight zero. Of the prefix sums
  // (prefix[j] = v[0] + ... + v[j-1]) only those at j = k and j = k + N, k = 0..L, are read:
  // one running sum passes them and they are kept (the same additions in the same order as a
  // run-length array of them, without it).
  thread_local std::vector<double> at_k, at_kn;  // prefix[k], prefix[k + N]
  at_k.resize(L + 1);
  at_kn.resize(L + 1);
  double prefix = 0.0;
  for (std::size_t j = 0;; ++j) {
    if (j <= L) at_k[j] = prefix;
    if (j >= n_ && j - n_ <= L) at_kn[j - n_] = prefix;
    if (j == size) break;
    prefix = prefix + v(j);
  }
  for (std::size_t i = 0; i <= L; ++i) {
    const std::size_t k = L - i;
    double s = at_kn[k] - at_k[k];
    for (std::size_t t : zeros_) s -= v(t + k);
    out[i] = s;
  }
}

}  // namespace fogbench::model::detail
