// The regression kernel of the fits: the lag scan (least squares for every lag at once, sums by
// FFT), the solve at chosen lags (lsq.hpp's QR) and AR(p) on the rows with weight.
#include <Eigen/Dense>
#include <limits>
#include <optional>
#include <string>

#include "fit_internal.hpp"
#include "lsq.hpp"

namespace fogbench::model::detail {
namespace {

// make(), or the copy kept in map under key (made on first use) when map is given and keep;
// the map is read and changed under mu (another thread's copy, the same numbers, may come first).
template <class Map, class Key, class Make>
std::vector<double> memoized(Map* map, MemoMutex* mu, const Key& key, bool keep, Make make) {
  if (!map || !keep) return make();
  {
    std::lock_guard lock(mu->m);
    auto it = map->find(key);
    if (it != map->end()) return it->second;
  }
  std::vector<double> v = make();
  std::lock_guard lock(mu->m);
  map->emplace(key, v);
  return v;
}

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
  std::vector<double> wy(n);
  double ywy = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    wy[t] = w[t] * y[t];
    ywy += wy[t] * y[t];
  }
  // The fixed block, F' W F and F' W y, summed pair by pair over the columns in place.
  Eigen::MatrixXd Gff(static_cast<Eigen::Index>(nf), static_cast<Eigen::Index>(nf));
  Eigen::VectorXd bf(static_cast<Eigen::Index>(nf));
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
  std::vector<std::vector<double>> cvy(nv), gvv(nv * nv);
  std::vector<std::vector<std::vector<double>>> cvf(nv, std::vector<std::vector<double>>(nf));
  if (nv > 0) {
    // The key of a column when memo keeps it (empty: not kept).
    auto vkey = [&](std::size_t v) { return memo && v < varying_keys.size() ? varying_keys[v] : std::string(); };
    auto fkey = [&](std::size_t a) { return memo && a < fixed_keys.size() ? fixed_keys[a] : std::string(); };
    if (memo) {
      std::lock_guard lock(memo->mu.m);
      if (memo->cvf.size() > ScanMemo::max_pairs) memo->cvf.clear();
    }
    MemoMutex* mu = memo ? &memo->mu : nullptr;
    Spectrum own;
    auto wy_spectrum = [&]() -> const Spectrum& {
      if (!wy_spec) {
        own = sc.spectrum_of_target(wy);
        wy_spec = &own;
      }
      return *wy_spec;
    };
    std::vector<std::optional<Spectrum>> f_spec(nf);
    auto fixed_spectrum = [&](std::size_t a) -> const Spectrum& {
      if (!f_spec[a]) {
        std::vector<double> wf(n);
        for (std::size_t t = 0; t < n; ++t) wf[t] = w[t] * fixed[a].v[t];
        f_spec[a] = sc.spectrum_of_target(wf);
      }
      return *f_spec[a];
    };
    for (std::size_t v = 0; v < nv; ++v) {
      const std::string kv = vkey(v);
      cvy[v] = memoized(memo ? &memo->cvy : nullptr, mu, kv, !kv.empty(), [&] { return sc.corr(*varying[v], wy_spectrum()); });
      std::optional<std::vector<double>> ones_sum;
      for (std::size_t a = 0; a < nf; ++a) {
        if (fixed[a].constant()) {
          if (!ones_sum) ones_sum = memoized(memo ? &memo->ones : nullptr, mu, kv, !kv.empty(), [&] { return sc.wsum(varying[v]->ext); });
          cvf[v][a] = *ones_sum;
          for (double& s : cvf[v][a]) s *= fixed[a].c;
        } else {
          const std::string ka = fkey(a);
          cvf[v][a] = memoized(memo ? &memo->cvf : nullptr, mu, std::make_pair(kv, ka), !kv.empty() && !ka.empty(),
                           [&] { return sc.corr(*varying[v], fixed_spectrum(a)); });
        }
      }
      for (std::size_t u = v; u < nv; ++u) {
        const std::string ku = vkey(u);
        gvv[v * nv + u] = memoized(memo ? &memo->gvv : nullptr, mu, std::make_pair(kv, ku), !kv.empty() && !ku.empty(), [&] {
          std::vector<double> prod(varying[v]->ext.size());
          for (std::size_t j = 0; j < prod.size(); ++j) prod[j] = varying[v]->ext[j] * varying[u]->ext[j];
          return sc.wsum(prod);
        });
      }
    }
  }
  ScanResult best;
  Eigen::MatrixXd G(k, k);
  Eigen::VectorXd b(k);
  if (nv == 0) lo = hi = 0;
  for (int i = lo; i <= hi; ++i) {
    const auto li = static_cast<std::size_t>(i);
    G.topLeftCorner(nf, nf) = Gff;
    b.head(nf) = bf;
    for (std::size_t v = 0; v < nv; ++v) {
      b(nf + v) = cvy[v][li];
      for (std::size_t a = 0; a < nf; ++a) G(a, nf + v) = G(nf + v, a) = cvf[v][a][li];
      for (std::size_t u = v; u < nv; ++u) G(nf + v, nf + u) = G(nf + u, nf + v) = gvv[v * nv + u][li];
    }
    Eigen::LDLT<Eigen::MatrixXd> ldlt(G);
    if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-13) continue;
    const Eigen::VectorXd th = ldlt.solve(b);
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
