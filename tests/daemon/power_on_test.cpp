// PowerWatch: the daemon's reading of power-ons and restarts from the frames it sees, without I/O.
#include <catch2/catch.hpp>

#include <optional>
#include <vector>

#include "fogbench/daemon/power_on.hpp"

using namespace fogbench::daemon;
using Edge = PowerWatch::Edge;

namespace {

// Feeds one period per entry (frames of one unit; -1: not read) from clock 1 s; returns the
// edges and the time since power-on after each period (NaN: unknown).
struct Trace {
  std::vector<Edge> edges;
  std::vector<std::optional<double>> since_s;
};
Trace feed(PowerWatch& w, const std::vector<int>& frames, double from_s = 1.0) {
  Trace t;
  double clock = from_s;
  for (int f : frames) {
    const std::optional<std::uint32_t> in[] = {f < 0 ? std::nullopt : std::optional<std::uint32_t>(f)};
    t.edges.push_back(w.update(clock, in)[0]);
    t.since_s.push_back(w.since_power_on_s(0, clock));
    clock += 1.0;
  }
  return t;
}

}  // namespace

TEST_CASE("power watch: a unit sending from the daemon's start has no known power-on") {
  PowerWatch w(1);
  auto t = feed(w, {100, 100, 100});
  for (std::size_t i = 0; i < 3; ++i) {
    CHECK(t.edges[i] == Edge::none);
    CHECK_FALSE(t.since_s[i].has_value());  // never guessed from the daemon's start
  }
  // One silent period is no power cycle (the bus connected late, a hiccup).
  t = feed(w, {0, 100}, 4.0);
  CHECK(t.edges == std::vector<Edge>{Edge::none, Edge::none});
}

TEST_CASE("power watch: frames after a silence of gap_s are a power-on, dated to their period's start") {
  PowerWatch w(1);
  // Clock 1, 2, 3 silent (off from the start: no edge), frames from the period ending at 4.
  auto t = feed(w, {0, 0, 0, 40, 100, 100});
  CHECK(t.edges == std::vector<Edge>{Edge::none, Edge::none, Edge::none, Edge::power_on, Edge::none, Edge::none});
  CHECK_FALSE(t.since_s[2].has_value());
  // On at 3 s (the start of the period ending at 4): 1 s at 4, 3 s at 6.
  CHECK(w.powered_on_at_s(0) == 3.0);
  CHECK(t.since_s[3] == 1.0);
  CHECK(t.since_s[5] == 3.0);

  SECTION("a power cycle: off after gap_s of silence, a restart when frames come back") {
    auto c = feed(w, {0, 0, 0, 0, 70, 100}, 7.0);
    // Silent at 7, 8 (off at 8: 2 s), 9, 10; frames again in the period ending at 11.
    CHECK(c.edges == std::vector<Edge>{Edge::none, Edge::power_off, Edge::none, Edge::none, Edge::restart, Edge::none});
    CHECK(c.since_s[0] == 4.0);             // still the power-on at 3 (silent for 1 s only)
    CHECK_FALSE(c.since_s[1].has_value());  // off: no time since power-on
    CHECK(w.powered_on_at_s(0) == 10.0);
    CHECK(c.since_s[4] == 1.0);
    CHECK(c.since_s[5] == 2.0);
  }
  SECTION("periods not read are no silence, but gap_s of them lose the power-on") {
    auto c = feed(w, {-1, 100, -1, -1, 100}, 7.0);
    CHECK(c.edges == std::vector<Edge>{Edge::none, Edge::none, Edge::none, Edge::lost, Edge::none});
    CHECK(c.since_s[1] == 5.0);
    CHECK_FALSE(c.since_s[4].has_value());  // a restart could have hidden in the 2 s not read
  }
}

TEST_CASE("power watch: a unit that comes on while it cannot be read has no known power-on") {
  PowerWatch w(1);
  auto t = feed(w, {0, 0, -1, -1, -1, 100});
  CHECK(t.edges[5] == Edge::none);
  CHECK_FALSE(t.since_s[5].has_value());
}

TEST_CASE("power watch: units are followed apart") {
  PowerWatch w(2);
  const std::optional<std::uint32_t> a[] = {100, 0};
  const std::optional<std::uint32_t> b[] = {100, 50};
  w.update(1, a);
  w.update(2, a);
  auto e = w.update(3, b);
  CHECK(e == std::vector<Edge>{Edge::none, Edge::power_on});
  CHECK_FALSE(w.since_power_on_s(0, 3).has_value());
  CHECK(w.since_power_on_s(1, 3) == 1.0);
}
