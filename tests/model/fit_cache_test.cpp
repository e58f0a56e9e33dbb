// The refits diagnose makes through one FitCache (model/src/fit_internal.hpp): the cache keeps
// the columns, the paper step's lag scans' sums (PaperPrep::memo), the collinearity checks'
// sums and columns handed to it (put); a refit through a cache warmed by other term lists must
// give exactly the numbers fit() computes alone.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../../model/src/fit_internal.hpp"

using namespace fogbench::model;
using namespace fogbench::model::detail;

namespace {

// 8000 s: a 600 s hold at 20 degC, then T1 and T2 on two sines (T2 ahead), the gyro
// mu0 + 0.03 T1(t - 40) + 0.01 T2 + white noise; no chamber or power-on column.
RunData run_of(std::size_t n, unsigned seed) {
  RunData r;
  r.name = "cache";
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, 0.1);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    const double u = t < 600 ? 0.0 : t - 600;
    r.time_s.push_back(t);
    r.t1_c.push_back(20.0 + 8.0 * std::sin(2 * M_PI * u / 3000.0) + 2.0 * std::sin(2 * M_PI * u / 1100.0));
    r.t2_c.push_back(20.0 + 8.0 * std::sin(2 * M_PI * (u + 60) / 3000.0) + 1.5 * std::sin(2 * M_PI * (u + 40) / 700.0) * (u > 0));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = i >= 40 ? i - 40 : 0;
    r.gyro_dph.push_back(-8.0 + 0.03 * (r.t1_c[j] - 20.0) + 0.01 * (r.t2_c[i] - 20.0) + e(rng));
  }
  return r;
}

void same_model(const Model& got, const Model& want) {
  REQUIRE(got.terms.size() == want.terms.size());
  CHECK(got.mu0_dph == want.mu0_dph);
  CHECK(got.fit.bic == want.fit.bic);
  CHECK(got.fit.rss == want.fit.rss);
  for (std::size_t j = 0; j < want.terms.size(); ++j) {
    INFO("term " << j);
    CHECK(got.terms[j].term.lag.seconds == want.terms[j].term.lag.seconds);
    CHECK(got.terms[j].coef == want.terms[j].coef);
    CHECK(got.terms[j].se_dph_per_unit == want.terms[j].se_dph_per_unit);
  }
}

}  // namespace

TEST_CASE("fit_with through a warmed FitCache gives fit()'s numbers exactly (paper method)") {
  const RunData run = run_of(8000, 3);
  FitOptions fo;
  fo.method = Method::paper;
  fo.max_lag_s = 300;
  // Columns kept apart from their lag extensions (pad 0), or each in its extension for the
  // fits' max lag (diagnose's cache: the column a view of the extension's tail).
  const int pad_lag_s = GENERATE(0, 300);
  INFO("pad " << pad_lag_s << " s");
  FitCache cache(run, fo.tref_c, 8, nullptr, pad_lag_s);
  cache.whole_run_whiteness = false;
  // The base's terms beside one candidate after another, some at two lags, as diagnose's step
  // refits them: every sum the memos keep is used again by a later list.
  const std::vector<std::string> lists{"d(T1)@auto + grad@auto + T2@0",       "d(T1)@auto + grad@auto + T2@120",     "d(T1)@auto + grad@auto + lp(T2,300)@10", "d(T1)@auto + grad@auto + T2@0",
                                       "d(T1)@auto + grad@auto + d(T2)@0",    "d(T1)@auto + grad@auto + lp(T2,300)@10", "d(T1)@auto + grad@auto + T2@120"};
  for (const auto& text : lists) {
    INFO(text);
    auto tl = parse_terms(text);
    REQUIRE(tl);
    const Term cand = tl->terms.back();
    // The candidate's column handed in as diagnose does (evaluated on the run's signals).
    auto sig = run_signals(run, fo.tref_c);
    REQUIRE(sig);
    auto x = evaluate(*cand.expr, sig->view());
    REQUIRE(x);
    cache.put(cand, *x);
    auto want = fit(run, *tl, fo);
    auto got = fit_with(run, *tl, fo, cache);
    REQUIRE(want);
    REQUIRE(got);
    same_model(*got, *want);
  }
  CHECK_FALSE(cache.collinear.mean.empty());
}

TEST_CASE("fit_with through a warmed FitCache refuses collinear terms as fit() does") {
  const RunData run = run_of(6000, 4);
  FitOptions fo;
  fo.method = Method::paper;
  fo.max_lag_s = 200;
  FitCache cache(run, fo.tref_c);
  cache.whole_run_whiteness = false;
  auto ok = parse_terms("d(T1)@auto + grad@auto + T2@30");
  REQUIRE(ok);
  REQUIRE(fit_with(run, *ok, fo, cache));
  // grad = T1 - T2: with T1 and T2 beside it at the same lag, the three are one combination.
  auto bad = parse_terms("T1@30 + T2@30 + grad@30");
  REQUIRE(bad);
  auto want = fit(run, *bad, fo);
  auto got = fit_with(run, *bad, fo, cache);
  REQUIRE_FALSE(want);
  REQUIRE_FALSE(got);
  CHECK(got.error().code == want.error().code);
  CHECK(got.error().message == want.error().message);
  // And at different lags they are independent again, through the same cache.
  auto apart = parse_terms("T1@30 + T2@30 + grad@90");
  REQUIRE(apart);
  auto want2 = fit(run, *apart, fo);
  auto got2 = fit_with(run, *apart, fo, cache);
  REQUIRE(want2.has_value() == got2.has_value());
  if (want2) same_model(*got2, *want2);
}

TEST_CASE("fit_with through one FitCache shared by two threads gives fit()'s numbers exactly") {
  // diagnose's threads refit their candidates through one cache: each thread's refits read the
  // columns, sums and first step the other made, and a cache of 2 columns drops columns the
  // other thread may still read. Every refit must still be fit()'s, on both threads.
  const RunData run = run_of(6000, 5);
  FitOptions fo;
  fo.method = Method::paper;
  fo.max_lag_s = 200;
  const int pad_lag_s = GENERATE(0, 200);  // as in the first case; 200: each column in its extension
  INFO("pad " << pad_lag_s << " s");
  FitCache cache(run, fo.tref_c, 2, nullptr, pad_lag_s);
  cache.whole_run_whiteness = false;
  cache.standard_errors = false;
  const std::vector<std::string> lists{"d(T1)@auto + grad@auto + T2@0", "d(T1)@auto + grad@auto + T2@120", "d(T1)@auto + grad@auto + lp(T2,300)@10",
                                       "d(T1)@auto + grad@auto + d(T2)@0", "d(T1)@auto + grad@auto + T1@60", "d(T1)@auto + grad@auto + lp(T1,600)@0"};
  std::vector<Model> want;
  for (const auto& text : lists) {
    auto w = fit(run, *parse_terms(text), fo);
    REQUIRE(w);
    want.push_back(*w);
  }
  // Each thread refits every list four times over, the two in opposite orders, and keeps what it got.
  constexpr int rounds = 4;
  std::vector<std::vector<std::expected<Model, FitError>>> got(2);
  auto worker = [&](std::size_t k) {
    for (int r = 0; r < rounds; ++r)
      for (std::size_t i = 0; i < lists.size(); ++i) {
        const std::size_t j = k == 0 ? i : lists.size() - 1 - i;
        auto m = fit_with(run, *parse_terms(lists[j]), fo, cache);
        if (m) add_standard_errors(*m, cache);
        got[k].push_back(std::move(m));
      }
  };
  std::thread other(worker, 1);
  worker(0);
  other.join();
  for (std::size_t k = 0; k < 2; ++k) {
    REQUIRE(got[k].size() == rounds * lists.size());
    for (std::size_t g = 0; g < got[k].size(); ++g) {
      const std::size_t i = g % lists.size(), j = k == 0 ? i : lists.size() - 1 - i;
      INFO("thread " << k << ", " << lists[j]);
      REQUIRE(got[k][g]);
      same_model(*got[k][g], want[j]);
    }
  }
}

TEST_CASE("a FitCache that forgot a candidate's column keeps the others and refits with fit()'s numbers") {
  // diagnose drops a candidate's column (with its lag extension and spectrum) from the refits'
  // cache once the candidate is scored (FitCache::forget, issue 30's memory): the base's columns
  // stay, and a refit that needs the forgotten column again makes it again, the same numbers.
  const RunData run = run_of(6000, 6);
  FitOptions fo;
  fo.method = Method::paper;
  fo.max_lag_s = 200;
  FitCache cache(run, fo.tref_c, 8, nullptr, GENERATE(0, 200));
  cache.whole_run_whiteness = false;
  auto tl = parse_terms("d(T1)@auto + grad@auto + T2@30 + lp(T1,600)@0");
  REQUIRE(tl);
  auto want = fit(run, *tl, fo);
  REQUIRE(want);
  auto first = fit_with(run, *tl, fo, cache);
  REQUIRE(first);
  same_model(*first, *want);
  cache.trim();
  REQUIRE(cache.columns() == 4);
  cache.forget(tl->terms[2]);  // T2
  CHECK(cache.columns() == 3);
  cache.forget(tl->terms[2]);  // not there: nothing changes
  CHECK(cache.columns() == 3);
  // Two fixed columns beside the two varying ones: each fixed column's spectrum serves both
  // varying columns before the next one's is made (fit_kernel.cpp's scan).
  auto again = fit_with(run, *tl, fo, cache);
  REQUIRE(again);
  same_model(*again, *want);
  CHECK(cache.columns() == 4);
}
