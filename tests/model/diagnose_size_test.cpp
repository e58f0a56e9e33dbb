// diagnose's bounds on what it is given: the size check (check_diagnose_size, on the runs' names and
// lengths, so that a run of 10 million samples is refused without making one), diagnose refusing
// runs over its limit, and many held-out runs at once (32), read side by side without a copy when
// the caller gives them in one array with the fit run first, as fogctl does: the same answer as
// from runs held apart (then copied).
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cycling_run.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/model/workbench.hpp"

using namespace fogbench::model;
namespace wb = fogbench::model::workbench;

namespace {

RunData size_test_run(std::size_t n, std::uint64_t seed) { return test::cycling_run(n, seed, "run "); }

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("check_diagnose_size refuses a run of 10 million samples, naming it, its samples and the limit") {
  const std::vector<wb::RunSize> one{{"ten-day x 12", 10'000'000}};
  const auto c = wb::check_diagnose_size(one, 2'000'000);
  REQUIRE_FALSE(c);
  INFO(c.error());
  CHECK(has(c.error(), "fit run 'ten-day x 12' has 10000000 samples"));
  CHECK(has(c.error(), "limit of 2000000 samples"));
  // At the limit it passes, one sample over it does not.
  const std::vector<wb::RunSize> at{{"a", 1'500'000}, {"b", 500'000}};
  CHECK(wb::check_diagnose_size(at, 2'000'000));
  const std::vector<wb::RunSize> over{{"a", 1'500'000}, {"b", 500'001}};
  CHECK_FALSE(wb::check_diagnose_size(over, 2'000'000));
}

TEST_CASE("check_diagnose_size refuses 32 held-out runs that hold too many samples together, the largest named first") {
  std::vector<wb::RunSize> runs{{"fit", 86'400}};
  for (int i = 0; i < 32; ++i) runs.push_back({"held " + std::to_string(i), i == 7 ? std::size_t{864'000} : std::size_t{86'400}});
  // 86,400 * 32 + 864,000 = 3,628,800 samples in all.
  const auto c = wb::check_diagnose_size(runs, 2'000'000);
  REQUIRE_FALSE(c);
  INFO(c.error());
  CHECK(has(c.error(), "the 33 runs given hold 3628800 samples in all (held-out run 'held 7' 864000, fit run 'fit' 86400"));
  CHECK(has(c.error(), "and 29 more"));
  CHECK(has(c.error(), "limit of 2000000 samples"));
  CHECK(wb::check_diagnose_size(runs, 3'628'800));
}

TEST_CASE("diagnose refuses runs over max_samples before any work, and rejects a limit out of range") {
  const std::vector<RunData> runs{size_test_run(9000, 1), size_test_run(4000, 2)};
  auto m = fit(runs[0], *parse_terms("paper"));
  REQUIRE(m);
  wb::DiagnoseOptions o;
  o.search = wb::DiagnoseOptions::Search::library;
  o.max_samples = 12'000;  // 13,000 given
  auto d = wb::diagnose(*m, runs[0], std::span<const RunData>(runs).subspan(1), o);
  REQUIRE_FALSE(d);
  CHECK(d.error().code == FitError::Code::bad_options);
  INFO(d.error().message);
  CHECK(has(d.error().message, "the 2 runs given hold 13000 samples in all (fit run 'run 1' 9000, held-out run 'run 2' 4000)"));
  o.max_samples = 999;
  auto bad = wb::diagnose(*m, runs[0], {}, o);
  REQUIRE_FALSE(bad);
  CHECK(has(bad.error().message, "max_samples must be 1000 to 100000000"));
}

TEST_CASE("diagnose with 32 held-out runs scores every one, the same answer from runs side by side or apart") {
  // The fit run first, then 32 short held-out runs (one ramp each), in one array as fogctl
  // hands them over, and the same runs held apart (diagnose then puts them side by side itself).
  std::vector<RunData> together{size_test_run(9000, 100)};
  for (std::uint64_t s = 0; s < 32; ++s) together.push_back(size_test_run(2500, 200 + s));
  const RunData fit_run = together[0];
  const std::vector<RunData> apart(together.begin() + 1, together.end());
  auto m = fit(fit_run, *parse_terms("paper"));
  REQUIRE(m);
  wb::DiagnoseOptions o;
  o.search = wb::DiagnoseOptions::Search::library;
  o.threads = 2;
  auto d = wb::diagnose(*m, together[0], std::span<const RunData>(together).subspan(1), o);
  REQUIRE(d);
  REQUIRE(d->held_out_runs.size() == 32);
  CHECK(d->held_out_runs[31] == "run 231");
  REQUIRE_FALSE(d->candidates.empty());
  // The first candidate (T1 or its look-alike T2 on these runs) is scored on every held-out run.
  const wb::Candidate& top = d->candidates.front();
  CHECK(top.evaluated);
  REQUIRE(top.held_out.size() == 32);
  for (const auto& h : top.held_out) CHECK(h.scored);
  auto d2 = wb::diagnose(*m, fit_run, apart, o);
  REQUIRE(d2);
  CHECK(wb::to_json(*d2).dump() == wb::to_json(*d).dump());
}
