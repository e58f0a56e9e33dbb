// PowerWatch: the daemon's reading of power-ons and restarts from the gyro's own evidence in its
// frames (a start-up frame: drivers::GyroSample::starts), never from the timing of the periods.
#include <catch2/catch.hpp>

#include <optional>
#include <vector>

#include "fogbench/daemon/power_on.hpp"

using namespace fogbench::daemon;
using Edge = PowerWatch::Edge;

namespace {

// One period of one unit: frames sent, of which start-up frames; `down`: the bus link was down.
struct P {
  int frames = 100;
  int starts = 0;
  bool down = false;
  bool read = true;
};
constexpr P quiet{0, 0, false, true};     // read, nothing came (a late bench, a paused loop, the gyro off)
constexpr P unread{0, 0, false, false};   // not read (the loop late, a paced world that did not step)
constexpr P down{0, 0, true, false};      // the bus link down: frames lost
constexpr P start{60, 1, false, true};    // frames of which one begins a start-up
constexpr P sending{100, 0, false, true};

// Feeds one period per entry from clock from_s, a second apart; returns the edges and the time
// since power-on after each period (empty: unknown).
struct Trace {
  std::vector<Edge> edges;
  std::vector<std::optional<double>> since_s;
};
Trace feed(PowerWatch& w, const std::vector<P>& periods, double from_s = 1.0) {
  Trace t;
  double clock = from_s;
  for (const P& p : periods) {
    const std::optional<GyroEvidence> in[] = {
        p.down ? std::nullopt
               : std::optional(GyroEvidence{static_cast<std::uint32_t>(p.frames), static_cast<std::uint32_t>(p.starts), p.read})};
    t.edges.push_back(w.update(clock, in)[0]);
    t.since_s.push_back(w.since_power_on_s(0, clock));
    clock += 1.0;
  }
  return t;
}

std::vector<Edge> nones(std::size_t n) { return std::vector<Edge>(n, Edge::none); }

}  // namespace

TEST_CASE("power watch: a unit sending from the daemon's start has no known power-on") {
  PowerWatch w(1);
  auto t = feed(w, {sending, sending, sending});
  CHECK(t.edges == nones(3));
  for (const auto& s : t.since_s) CHECK_FALSE(s.has_value());  // never guessed from the daemon's start
}

TEST_CASE("power watch: a start-up frame is a power-on, dated to its period's start") {
  PowerWatch w(1);
  // Off from the daemon's start (nothing read for 3 s: no edge), a start-up in the period ending at 4.
  auto t = feed(w, {quiet, quiet, quiet, start, sending, sending});
  CHECK(t.edges == std::vector<Edge>{Edge::none, Edge::none, Edge::none, Edge::power_on, Edge::none, Edge::none});
  CHECK_FALSE(t.since_s[2].has_value());
  // On at 3 s (the start of the period ending at 4): 1 s at 4, 3 s at 6.
  CHECK(w.powered_on_at_s(0) == 3.0);
  CHECK(t.since_s[3] == 1.0);
  CHECK(t.since_s[5] == 3.0);

  SECTION("a real restart gives exactly one edge, and the time since power-on starts again") {
    // The gyro off 4 s (no frames), then its start-up frames.
    auto c = feed(w, {quiet, quiet, quiet, quiet, start, sending}, 7.0);
    CHECK(c.edges == std::vector<Edge>{Edge::none, Edge::none, Edge::none, Edge::none, Edge::restart, Edge::none});
    CHECK(c.since_s[3] == 7.0);  // nothing said yet: a silence alone is no power-off
    CHECK(w.powered_on_at_s(0) == 10.0);
    CHECK(c.since_s[4] == 1.0);
    CHECK(c.since_s[5] == 2.0);
  }
  SECTION("late ticks and a paused loop give no edge: the time since power-on only grows") {
    // A loop paused 30 s, then the frames it missed in one burst; bunched, thin and empty periods.
    std::vector<P> late(30, quiet);
    late.push_back({3000, 0, false, true});
    for (int i = 0; i < 20; ++i) late.push_back(i % 3 == 0 ? unread : i % 3 == 1 ? quiet : P{i * 37 % 250, 0, false, true});
    auto c = feed(w, late, 7.0);
    CHECK(c.edges == nones(late.size()));
    for (std::size_t i = 0; i < c.since_s.size(); ++i) {
      REQUIRE(c.since_s[i].has_value());
      CHECK(*c.since_s[i] == 7.0 + static_cast<double>(i) - 3.0);  // on at 3 s, clock 7 + i
    }
  }
  SECTION("a bus link down for less than gap_s keeps the power-on, gap_s of it loses it") {
    auto c = feed(w, {down, sending, down, down, sending}, 7.0);
    CHECK(c.edges == std::vector<Edge>{Edge::none, Edge::none, Edge::none, Edge::lost, Edge::none});
    CHECK(c.since_s[1] == 5.0);
    CHECK_FALSE(c.since_s[4].has_value());  // a whole start-up could have hidden in the 2 s lost
    // Until the gyro tells again: its next start-up.
    auto d = feed(w, {start}, 12.0);
    CHECK(d.edges == std::vector<Edge>{Edge::restart});
    CHECK(d.since_s[0] == 1.0);
  }
}

TEST_CASE("power watch: a first start-up the daemon was not listening for is no known power-on") {
  // A paced world's first frames: its gyros' own start-up, but nothing was read before it (the
  // world stood still), so the daemon cannot tell it from a unit on before it listened.
  PowerWatch w(1);
  auto t = feed(w, {unread, unread, start, sending});
  CHECK(t.edges == nones(4));
  CHECK_FALSE(t.since_s[3].has_value());
  // Its next start-up is a restart the daemon sees.
  auto c = feed(w, {quiet, start}, 5.0);
  CHECK(c.edges == std::vector<Edge>{Edge::none, Edge::restart});
  CHECK(c.since_s[1] == 1.0);
}

TEST_CASE("power watch: a unit that comes on while the link is down is known by its start-up frames only") {
  PowerWatch w(1);
  auto t = feed(w, {quiet, quiet, down, down, down, sending, sending});
  CHECK(t.edges == nones(7));
  CHECK_FALSE(t.since_s[6].has_value());
}

TEST_CASE("power watch: units are followed apart") {
  PowerWatch w(2);
  const std::optional<GyroEvidence> a[] = {GyroEvidence{100, 0, true}, GyroEvidence{0, 0, true}};
  const std::optional<GyroEvidence> b[] = {GyroEvidence{100, 0, true}, GyroEvidence{50, 1, true}};
  w.update(1, a);
  w.update(2, a);
  auto e = w.update(3, b);
  CHECK(e == std::vector<Edge>{Edge::none, Edge::power_on});
  CHECK_FALSE(w.since_power_on_s(0, 3).has_value());
  CHECK(w.since_power_on_s(1, 3) == 1.0);
}
