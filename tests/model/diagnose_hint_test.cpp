// diagnose_once's step hint (model/src/workbench_internal.hpp, internal to model/): diagnose hands
// a step the base it fitted and the floor it read on the same runs, so that the step does not
// compute them again. The hint must be the numbers the step computes itself: a step given it
// answers exactly as a step without it, with and without held-out runs, on one thread or two
// (the floor is then read beside the screen); and a run whose gyro holds a non-finite sample
// (which the step zeroes into a copy, unlike the hint's fit) ignores it.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../../model/src/workbench_internal.hpp"
#include "cycling_run.hpp"
#include "fogbench/model/json.hpp"

using namespace fogbench::model;
namespace wb = fogbench::model::workbench;

namespace {

RunData hint_run(std::size_t n, std::uint64_t seed) { return test::cycling_run(n, seed, "hint "); }

std::string answer(const std::expected<wb::Diagnosis, FitError>& d) {
  REQUIRE(d);
  return wb::to_json(*d).dump();
}

}  // namespace

TEST_CASE("diagnose_once: a step given diagnose's base and floor answers as one that computes them") {
  const RunData r = hint_run(9000, 3);
  const std::vector<RunData> held{hint_run(9000, 4)};
  FitOptions fo;
  fo.method = Method::paper;
  auto m = fit(r, *parse_terms("paper"), fo);
  REQUIRE(m);
  wb::DiagnoseOptions o;
  o.search = wb::DiagnoseOptions::Search::library;
  REQUIRE(o.failing.noise.read_floor);
  // The base and the floor as diagnose makes them: the model's terms refitted on the fit run,
  // the unit's floor read under it over the runs.
  auto base = fit(r, wb::terms_of(*m), wb::options_of(*m));
  REQUIRE(base);
  auto other = fit(held[0], wb::terms_of(*m), wb::options_of(*m));  // a base of the other run
  REQUIRE(other);
  for (const auto& [with_held, threads] : {std::pair{false, 1}, std::pair{true, 1}, std::pair{true, 2}}) {
    INFO("held-out runs " << with_held << ", threads " << threads);
    const std::span<const RunData> h = with_held ? std::span<const RunData>(held) : std::span<const RunData>();
    std::vector<RunData> all{r};
    all.insert(all.end(), h.begin(), h.end());
    auto floor = unit_noise_floor(*base, all, o.failing.noise.floor);
    REQUIRE(floor);
    o.threads = threads;
    const std::string own = answer(wb::wbi::diagnose_once(*m, r, h, o, {}, nullptr));
    CHECK(answer(wb::wbi::diagnose_once(*m, r, h, o, {}, nullptr, wb::wbi::StepHint{&*base, &*floor})) == own);
    // A wrong hint shows (so the comparison above can fail): the other run's base.
    if (threads == 1 && !with_held) CHECK(answer(wb::wbi::diagnose_once(*m, r, h, o, {}, nullptr, wb::wbi::StepHint{&*other, &*floor})) != own);
  }
}

TEST_CASE("diagnose_once: a fit run with a non-finite gyro sample ignores the hint") {
  RunData r = hint_run(9000, 5);
  FitOptions fo;
  fo.method = Method::paper;
  auto m = fit(r, *parse_terms("paper"), fo);
  REQUIRE(m);
  r.gyro_dph[5000] = std::numeric_limits<double>::quiet_NaN();
  wb::DiagnoseOptions o;
  o.search = wb::DiagnoseOptions::Search::library;
  // A hint from another run: used, it would change the answer (the case above); ignored, not.
  const RunData other_run = hint_run(9000, 6);
  auto other = fit(other_run, wb::terms_of(*m), wb::options_of(*m));
  REQUIRE(other);
  const std::vector<RunData> one{other_run};
  auto floor = unit_noise_floor(*other, one, o.failing.noise.floor);
  REQUIRE(floor);
  const std::string own = answer(wb::wbi::diagnose_once(*m, r, {}, o, {}, nullptr));
  CHECK(answer(wb::wbi::diagnose_once(*m, r, {}, o, {}, nullptr, wb::wbi::StepHint{&*other, &*floor})) == own);
}
