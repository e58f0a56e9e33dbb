// Fuzzes the profile language (profiles/include/fogbench/profiles/profile.hpp): the whole input
// is a profile's text. Every text must give a Profile or a ProfileError that can be printed; a
// Profile must have a finite nominal length, pass or fail the limit check with a message, and
// have a nominal timeline that keeps to the hull of its temperatures and, once within a
// chamber's limits, to those limits (the property the limit check exists for).
#include <algorithm>
#include <cmath>
#include <variant>

#include "common.hpp"
#include "fogbench/profiles/profile.hpp"

using namespace fogbench::profiles;

namespace {

// A few points per step at most: enough to reach every step's branch, bounded in time.
constexpr double kMaxPoints = 2000.0;

void check_timeline(const Profile& p, const ChamberLimits* within) {
  const double total_s = p.nominal_duration_s();
  const double dt_s = std::max(total_s / kMaxPoints, 1.0);
  const auto points = nominal_setpoints(p, dt_s);
  FUZZ_CHECK(!points.empty(), "no nominal point for a parsed profile");
  FUZZ_CHECK(static_cast<double>(points.size()) <= kMaxPoints + 2, "%zu points for dt %g s over %g s", points.size(), dt_s, total_s);

  // The temperatures the profile names: every nominal setpoint lies between them.
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& s : p.steps) {
    if (const auto* sp = std::get_if<SetpointStep>(&s.action)) lo = std::min(lo, sp->temp_c), hi = std::max(hi, sp->temp_c);
    if (const auto* r = std::get_if<RampStep>(&s.action)) lo = std::min(lo, r->target_c), hi = std::max(hi, r->target_c);
  }
  double prev_t = -INFINITY;
  for (const auto& pt : points) {
    FUZZ_CHECK(pt.time_s > prev_t, "nominal time not increasing: %g after %g", pt.time_s, prev_t);
    prev_t = pt.time_s;
    FUZZ_CHECK(pt.step_index < p.steps.size(), "step index %zu of %zu steps", pt.step_index, p.steps.size());
    FUZZ_CHECK(std::isfinite(pt.setpoint_c), "nominal setpoint %g at %g s", pt.setpoint_c, pt.time_s);
    // A ramp interpolates: allow the rounding of start + rate * t.
    const double tol = 1e-9 * std::max({1.0, std::fabs(lo), std::fabs(hi)});
    FUZZ_CHECK(pt.setpoint_c >= lo - tol && pt.setpoint_c <= hi + tol,
               "nominal setpoint %.17g at %g s outside the profile's temperatures [%g, %g]",
               pt.setpoint_c, pt.time_s, lo, hi);
    if (within)
      FUZZ_CHECK(pt.setpoint_c >= within->min_c - tol && pt.setpoint_c <= within->max_c + tol,
                 "limits passed but nominal setpoint %.17g at %g s is outside [%g, %g]",
                 pt.setpoint_c, pt.time_s, within->min_c, within->max_c);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto text = fogbench::fuzz::as_text(data, size);
  auto p = parse_profile(text, "fuzz.profile");
  if (!p) {
    const ProfileError& e = p.error();
    FUZZ_CHECK(!e.message.empty(), "an error without a message");
    FUZZ_CHECK(e.line >= 1 || (e.line == 0 && e.column == 0), "error at line %d column %d", e.line, e.column);
    FUZZ_CHECK(e.line == 0 || e.column >= 1, "error at line %d column %d", e.line, e.column);
    (void)e.to_string();
    (void)e.excerpt();
    return 0;
  }
  FUZZ_CHECK(!p->steps.empty() && p->steps[0].kind() == StepKind::setpoint,
             "a parsed profile must open with a setpoint");
  for (const auto& s : p->steps) FUZZ_CHECK(s.line >= 1, "step at line %d", s.line);
  const double total_s = p->nominal_duration_s();
  FUZZ_CHECK(std::isfinite(total_s) && total_s >= 0.0, "nominal duration %g s", total_s);

  // The golden bench's chamber (tests/golden/config.json) and a wide one.
  const ChamberLimits limits[] = {{-40.0, 60.0, 3.0}, {-1e6, 1e6, 1e6}};
  for (const auto& l : limits) {
    auto ok = check_limits(*p, l);
    if (!ok) {
      FUZZ_CHECK(!ok.error().message.empty(), "a limit error without a message");
      (void)ok.error().to_string();
      (void)ok.error().excerpt();
    }
    check_timeline(*p, ok ? &l : nullptr);
  }
  // Refused limits are refused, not trusted.
  FUZZ_CHECK(!check_limits(*p, {10.0, -10.0, 1.0}), "min_c > max_c accepted");
  FUZZ_CHECK(!check_limits(*p, {-10.0, 10.0, 0.0}), "a zero rate limit accepted");
  FUZZ_CHECK(!check_limits(*p, {-10.0, NAN, 1.0}), "a NaN limit accepted");
  return 0;
}
