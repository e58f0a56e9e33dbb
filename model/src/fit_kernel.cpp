// The regression kernel of the fits: the lag scan (least squares for every lag at once, sums by
// FFT), the solve at chosen lags (lsq.hpp's QR) and AR(p) on the rows with weight.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "fit_internal.hpp"
#include "lsq.hpp"

namespace fogbench::model::detail {
namespace {

// make(out), or the copy kept in map under key (made on first use) when map is given and keep;
// the map is read and changed under mu (another thread's copy, the same numbers, may come first).
// out is the caller's buffer (its capacity reused when nothing is kept).
template <class Map, class Key, class Make>
void memoized(Map* map, MemoMutex* mu, const Key& key, bool keep, std::vector<double>& out, Make make) {
  if (!map || !keep) {
    make(out);
    return;
  }
  {
    std::lock_guard lock(mu->m);
    auto it = map->find(key);
    if (it != map->end()) {
      out.assign(it->second.begin(), it->second.end());
      return;
    }
  }
  make(out);
  std::lock_guard lock(mu->m);
  map->emplace(key, out);
}

// LDLT's reciprocal condition number estimated as Eigen's rcond() does (Hager's ascent over the
// simplices with Higham's alternating-sign check: at most 10 solves), into buffers kept per
// thread: Eigen's own makes fresh vectors on every call, and the scan asks at every lag. Only
// compared with a threshold. l1_norm: the factored matrix's largest absolute column sum.
double rcond_estimate(const Eigen::LDLT<Eigen::MatrixXd>& dec, double l1_norm) {
  const Eigen::Index n = dec.rows();
  if (n == 0) return std::numeric_limits<double>::infinity();
  if (l1_norm == 0.0) return 0.0;
  if (n == 1) return 1.0;
  thread_local Eigen::VectorXd v, sign, old_sign;
  v.resize(n);
  sign.resize(n);
  old_sign.resize(n);
  v.setConstant(1.0 / static_cast<double>(n));
  v = dec.solve(v);
  double lower = v.lpNorm<1>(), old_lower = lower;
  Eigen::Index at = -1, old_at = -1;
  for (int k = 0; k < 4; ++k) {
    for (Eigen::Index i = 0; i < n; ++i) sign[i] = v[i] < 0.0 ? -1.0 : 1.0;
    if (k > 0 && sign == old_sign) break;
    v = dec.solve(sign);  // LDLT is self-adjoint: its adjoint's solve is its own
    v.cwiseAbs().maxCoeff(&at);
    if (at == old_at) break;
    v.setZero();
    v[at] = 1.0;
    v = dec.solve(v);
    lower = v.lpNorm<1>();
    if (lower <= old_lower) break;
    old_sign = sign;
    old_at = at;
    old_lower = lower;
  }
  double alternating = 1.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    v[i] = alternating * (1.0 + static_cast<double>(i) / static_cast<double>(n - 1));
    alternating = -alternating;
  }
  v = dec.solve(v);
  const double inverse_norm = std::max(lower, 2.0 * v.lpNorm<1>() / (3.0 * static_cast<double>(n)));
  return inverse_norm == 0.0 ? 0.0 : (1.0 / inverse_norm) / l1_norm;
}

// A symmetric matrix's largest absolute column sum.
double l1_norm(const Eigen::MatrixXd& g) {
  double best = 0.0;
  for (Eigen::Index c = 0; c < g.cols(); ++c) {
    double sum = 0.0;
    for (Eigen::Index r = 0; r < g.rows(); ++r) sum += std::abs(g(r, c));
    best = std::max(best, sum);
  }
  return best;
}

// scan()'s work space, one per thread, kept between calls: a fit's iterations scan the same
// shapes again and again, and fresh run-length buffers cost their page faults and zeroing.
struct ScanBuffers {
  std::vector<double> wy, ones;
  std::vector<std::vector<double>> cvy, cvf, gvv;  // [v], [v * nf + a], [v * nv + u]: all lags each
  Spectrum f_spec;                                 // w * one fixed column's spectrum (f_of: which)
  Spectrum own;                                    // w * y's spectrum when the caller has none
  Eigen::MatrixXd Gff, G;
  Eigen::VectorXd bf, b, th;
  Eigen::LDLT<Eigen::MatrixXd> ldlt;
};

}  // namespace

// Normal equations, one solve per lag: all lags' sums cost a few FFTs, and only the lag of
// least SSE is kept (its coefficients come from solve_at), so their squared condition costs
// at most the choice between lags of nearly equal SSE.
ScanResult scan(const LagScanner& sc, std::span<const double> y, const Spectrum* wy_spec,
                const std::vector<Column>& fixed, const std::vector<const Lagged*>& varying, int lo, int hi,
                ScanMemo* memo, std::span<const std::string> fixed_keys, std::span<const std::string> varying_keys) {
  const std::size_t n = sc.n();
  const auto& w = sc.weights();
  const std::size_t nf = fixed.size(), nv = varying.size(), k = nf + nv;
  thread_local ScanBuffers B;
  std::vector<double>& wy = B.wy;
  wy.resize(n);
  double ywy = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    wy[t] = w[t] * y[t];
    ywy += wy[t] * y[t];
  }
  // The fixed block, F' W F and F' W y, summed pair by pair over the columns in place.
  Eigen::MatrixXd& Gff = B.Gff;
  Eigen::VectorXd& bf = B.bf;
  Gff.resize(static_cast<Eigen::Index>(nf), static_cast<Eigen::Index>(nf));
  bf.resize(static_cast<Eigen::Index>(nf));
  // sum_t w(t) u(t) v(t) for two columns (or w(t) v(t) with u constant, and so on).
  auto wdot = [&](const Column& u, const Column& v) {
    double sum = 0.0;
    if (u.constant() && v.constant()) {
      for (std::size_t t = 0; t < n; ++t) sum += w[t];
      return sum * u.c * v.c;
    }
    if (u.constant() || v.constant()) {
      const Column& x = u.constant() ? v : u;
      for (std::size_t t = 0; t < n; ++t) sum += w[t] * x.v[t];
      return sum * (u.constant() ? u.c : v.c);
    }
    for (std::size_t t = 0; t < n; ++t) sum += w[t] * u.v[t] * v.v[t];
    return sum;
  };
  for (std::size_t a = 0; a < nf; ++a) {
    double sb = 0.0;
    if (fixed[a].constant()) {
      for (std::size_t t = 0; t < n; ++t) sb += wy[t];
      sb *= fixed[a].c;
    } else {
      for (std::size_t t = 0; t < n; ++t) sb += fixed[a].v[t] * wy[t];
    }
    bf(static_cast<Eigen::Index>(a)) = sb;
    for (std::size_t c = a; c < nf; ++c)
      Gff(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(c)) = Gff(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(a)) =
          wdot(fixed[a], fixed[c]);
  }
  // Lag-dependent sums, each for all lags at once.
  auto& cvy = B.cvy;
  auto& cvf = B.cvf;
  auto& gvv = B.gvv;
  if (cvy.size() < nv) cvy.resize(nv);
  if (cvf.size() < nv * nf) cvf.resize(nv * nf);
  if (gvv.size() < nv * nv) gvv.resize(nv * nv);
  if (nv > 0) {
    // The key of a column when memo keeps it (empty: not kept).
    auto vkey = [&](std::size_t v) { return memo && v < varying_keys.size() ? varying_keys[v] : std::string(); };
    auto fkey = [&](std::size_t a) { return memo && a < fixed_keys.size() ? fixed_keys[a] : std::string(); };
    if (memo) {
      std::lock_guard lock(memo->mu.m);
      if (memo->cvf.size() > ScanMemo::max_pairs) memo->cvf.clear();
    }
    MemoMutex* mu = memo ? &memo->mu : nullptr;
    auto wy_spectrum = [&]() -> const Spectrum& {
      if (!wy_spec) {
        sc.spectrum_of_target(wy, B.own);
        wy_spec = &B.own;
      }
      return *wy_spec;
    };
    // A fixed column's spectrum is made when a sum needs it (not memoized) and serves every
    // varying column before the next fixed column's takes its buffer: one spectrum per thread
    // at a time rather than one per fixed column (2.3 MB each on a 3-day run; issue 30). Each
    // sum is computed as before, only in another order: the same numbers.
    std::size_t f_of = nf;  // the fixed column B.f_spec holds (nf: none)
    auto fixed_spectrum = [&](std::size_t a) -> const Spectrum& {
      if (f_of != a) {
        // w * the column, made block by block as the transform loads it (no run-length array).
        sc.spectrum_of_product(w, std::span<const double>(fixed[a].v, n), B.f_spec);
        f_of = a;
      }
      return B.f_spec;
    };
    for (std::size_t a = 0; a < nf; ++a) {
      if (fixed[a].constant()) continue;
      const std::string ka = fkey(a);
      for (std::size_t v = 0; v < nv; ++v) {
        const std::string kv = vkey(v);
        memoized(memo ? &memo->cvf : nullptr, mu, std::make_pair(kv, ka), !kv.empty() && !ka.empty(), cvf[v * nf + a],
                 [&](std::vector<double>& out) { sc.corr(*varying[v], fixed_spectrum(a), out); });
      }
    }
    for (std::size_t v = 0; v < nv; ++v) {
      const std::string kv = vkey(v);
      memoized(memo ? &memo->cvy : nullptr, mu, kv, !kv.empty(), cvy[v],
               [&](std::vector<double>& out) { sc.corr(*varying[v], wy_spectrum(), out); });
      bool have_ones = false;
      for (std::size_t a = 0; a < nf; ++a) {
        if (!fixed[a].constant()) continue;
        std::vector<double>& c = cvf[v * nf + a];
        if (!have_ones) {
          memoized(memo ? &memo->ones : nullptr, mu, kv, !kv.empty(), B.ones,
                   [&](std::vector<double>& out) { sc.wsum(varying[v]->ext, out); });
          have_ones = true;
        }
        c.assign(B.ones.begin(), B.ones.end());
        for (double& s : c) s *= fixed[a].c;
      }
      for (std::size_t u = v; u < nv; ++u) {
        const std::string ku = vkey(u);
        memoized(memo ? &memo->gvv : nullptr, mu, std::make_pair(kv, ku), !kv.empty() && !ku.empty(), gvv[v * nv + u],
                 [&](std::vector<double>& out) { sc.wsum_product(varying[v]->ext, varying[u]->ext, out); });
      }
    }
  }
  ScanResult best;
  Eigen::MatrixXd& G = B.G;
  Eigen::VectorXd& b = B.b;
  G.resize(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k));
  b.resize(static_cast<Eigen::Index>(k));
  if (nv == 0) lo = hi = 0;
  for (int i = lo; i <= hi; ++i) {
    const auto li = static_cast<std::size_t>(i);
    G.topLeftCorner(nf, nf) = Gff;
    b.head(nf) = bf;
    for (std::size_t v = 0; v < nv; ++v) {
      b(nf + v) = cvy[v][li];
      for (std::size_t a = 0; a < nf; ++a) G(a, nf + v) = G(nf + v, a) = cvf[v * nf + a][li];
      for (std::size_t u = v; u < nv; ++u) G(nf + v, nf + u) = G(nf + u, nf + v) = gvv[v * nv + u][li];
    }
    Eigen::LDLT<Eigen::MatrixXd>& ldlt = B.ldlt;
    ldlt.compute(G);
    if (ldlt.info() != Eigen::Success || rcond_estimate(ldlt, l1_norm(G)) < 1e-13) continue;
    B.th = ldlt.solve(b);
    const Eigen::VectorXd& th = B.th;
    const double sse = ywy - b.dot(th);
    if (sse < best.sse) {
      best.sse = sse;
      best.lag = i;
      best.theta.assign(th.data(), th.data() + k);
      best.ok = true;
    }
  }
  return best;
}

ScanResult solve_at(std::span<const double> y, std::span<const double> w, const std::vector<Column>& cols, int lag) {
  detail::LeastSquares ls(cols.size());
  std::vector<double> row(cols.size());
  for (std::size_t t = 0; t < y.size(); ++t) {
    if (w[t] == 0.0) continue;
    for (std::size_t j = 0; j < cols.size(); ++j) row[j] = cols[j].at(t);
    ls.add(row, y[t], w[t]);
  }
  const detail::LeastSquaresResult r = ls.solve();
  ScanResult out;
  out.lag = lag;
  if (!r.ok) return out;
  out.theta = r.theta;
  out.sse = r.sse;
  out.ok = true;
  return out;
}


// AR(p) by least squares over the rows whose p+1 samples all have weight 1, accumulating
// the p x p normal equations in one pass (no design matrix: N is large, p is small).
std::expected<ArFit, std::string> fit_ar_rows(std::span<const double> e, std::span<const double> w, int p) {
  const auto pu = static_cast<std::size_t>(p);
  Eigen::MatrixXd XtX = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd XtY = Eigen::VectorXd::Zero(p);
  double yty = 0.0;
  std::size_t rows = 0;
  std::size_t run = 0;  // consecutive good samples ending at t
  std::vector<double> lagv(pu);
  for (std::size_t t = 0; t < e.size(); ++t) {
    run = w[t] != 0.0 ? run + 1 : 0;
    if (run <= pu) continue;
    for (std::size_t j = 0; j < pu; ++j) lagv[j] = e[t - 1 - j];
    for (std::size_t a = 0; a < pu; ++a) {
      XtY(static_cast<Eigen::Index>(a)) += lagv[a] * e[t];
      for (std::size_t b = a; b < pu; ++b) XtX(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) += lagv[a] * lagv[b];
    }
    yty += e[t] * e[t];
    ++rows;
  }
  if (rows < 11 * pu) return std::unexpected("too few consecutive good samples for AR(" + std::to_string(p) + ")");
  XtX = XtX.selfadjointView<Eigen::Upper>();
  Eigen::LDLT<Eigen::MatrixXd> ldlt(XtX);
  if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-14) return std::unexpected(std::string("degenerate residual series"));
  const Eigen::VectorXd th = ldlt.solve(XtY);
  ArFit r;
  r.k.assign(th.data(), th.data() + p);
  r.sigma_a2 = std::max(0.0, (yty - XtY.dot(th)) / static_cast<double>(rows));
  return r;
}
}  // namespace fogbench::model::detail
