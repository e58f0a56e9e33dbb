// The mock bench's CAN side read by the drivers' real GyroBus over the unix SEQPACKET
// transport: frames arrive at the configured rate without loss, their average is the physics'
// drift, and each CAN fault shows in the frame accounting the daemon records.
#include <catch2/catch.hpp>

#include <poll.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <thread>

#include "fogbench/drivers/can_frame.hpp"
#include "fogbench/drivers/config.hpp"
#include "fogbench/drivers/gyro_bus.hpp"
#include "mock_process.hpp"

using namespace fogbench::drivers;
using namespace mockbench;

namespace {

// The physics' drift at rest (sim::GyroTruth::mu0_dph): with the chamber and coils at rest
// every temperature term of the default truth is zero.
constexpr double mu0_dph = -8.097;

struct Totals {
  std::uint64_t frames = 0, used = 0, lost = 0, corrupt = 0;
  double sum_dph = 0;  // rate times frames used, summed over samples
  double mean_dph() const { return used > 0 ? sum_dph / static_cast<double>(used) : NAN; }
};

GyroBus open_bus(const MockProcess& mock, const DriversConfig& cfg) {
  std::vector<GyroChannelConfig> gyros;
  for (const auto& u : cfg.units) gyros.push_back(u.gyro);
  auto bus = GyroBus::open(cfg.gyro_bus, gyros);
  INFO((bus ? std::string() : bus.error().to_string()));
  REQUIRE(bus.has_value());
  // The bench accepts in its server loop: wait until it counts the client.
  REQUIRE(wait_for(5s, [&] { return mock.status()["can_clients"] == 1; }));
  return std::move(*bus);
}

// Reads frames as they come until `stop` holds (checked every 10 ms), closing a sample every
// 50 ms as the daemon closes one per (scaled) second, and adds them to `totals`.
void collect(GyroBus& bus, std::vector<Totals>& totals, const std::function<bool()>& stop,
             const std::function<void(const can_frame&)>& each = {}) {
  totals.resize(bus.unit_count());
  std::vector<can_frame> frames;
  auto last_close = std::chrono::steady_clock::now();
  auto close = [&] {
    const BusSample s = bus.close_samples();
    for (std::size_t u = 0; u < s.units.size(); ++u) {
      const auto& g = s.units[u];
      totals[u].frames += g.frames;
      totals[u].used += g.frames_used;
      totals[u].lost += g.frames_lost;
      totals[u].corrupt += g.frames_corrupt;
      if (g.rate_dph) totals[u].sum_dph += *g.rate_dph * g.frames_used;
    }
  };
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (!stop()) {
    REQUIRE(std::chrono::steady_clock::now() < deadline);
    pollfd p{bus.fd(), POLLIN, 0};
    ::poll(&p, 1, 10);
    auto n = bus.read_frames(frames);
    REQUIRE(n.has_value());
    if (each) {
      for (const auto& f : frames) each(f);
    }
    if (std::chrono::steady_clock::now() - last_close > 50ms) {
      close();
      last_close = std::chrono::steady_clock::now();
    }
  }
  close();
}

// Reads what is queued now, without waiting, and closes the sample into `totals`: the reader
// has then caught up with the bench.
void drain(GyroBus& bus, std::vector<Totals>& totals) {
  std::vector<can_frame> frames;
  while (true) {
    auto n = bus.read_frames(frames);
    REQUIRE(n.has_value());
    if (*n == 0) break;
  }
  collect(bus, totals, [] { return true; });  // stops at once: closes the sample just read
}

// Collects for `sim_s` simulated seconds of the bench's clock.
std::vector<Totals> collect_for(const MockProcess& mock, GyroBus& bus, double sim_s) {
  std::vector<Totals> totals;
  const double until = mock.sim_time() + sim_s;
  collect(bus, totals, [&] { return mock.sim_time() >= until; });
  return totals;
}

}  // namespace

TEST_CASE("gyro frames arrive at the frame rate without loss and average to the physics' drift") {
  // K = 50 at 100 frames per simulated second: 5,000 frames/s per unit on the socket.
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  std::vector<Totals> before;
  drain(bus, before);
  const double t0 = mock.sim_time();
  auto totals = collect_for(mock, bus, 100);
  drain(bus, totals);
  const double t1 = mock.sim_time();
  const auto st = mock.status();
  for (std::size_t u = 0; u < 2; ++u) {
    INFO("unit " << u << " (" << (u == 0 ? "rate" : "increment") << " mode)");
    CHECK(totals[u].lost == 0);
    CHECK(totals[u].corrupt == 0);
    CHECK(totals[u].used == totals[u].frames);
    // 100 frames per simulated second. The window is the simulated time between two status
    // replies, each just after the reader caught up: what the bench sends during a reply's
    // round trip is the error, a simulated second or two, up to five when a loaded machine
    // delays a reply by 0.1 s at K = 50. 10% over 100 s.
    CHECK(static_cast<double>(totals[u].frames) == Approx(100.0 * (t1 - t0)).epsilon(0.1));
    // The gyro streams: any 100 consecutive frames average to the drift plus the 1 s AR(2) noise
    // (sigma 0.146 deg/h), so the mean over ~100 s is mu0 plus the mean of 100 such values:
    // 0.015 deg/h (1 sigma). 0.1 deg/h is over six
    // sigma and still covers one rare 2.5 deg/h outlier (0.025 over 100 s) and, in increment
    // mode, the 2.88 deg/h count quantised per second (at most 0.0144 deg/h of bias).
    CHECK(totals[u].mean_dph() == Approx(mu0_dph).margin(0.1));
  }
  CHECK(st["can_frames_dropped"] == 0);
}

TEST_CASE("fault lose_frames: a fraction of one unit's frames is lost, seen as frames_lost") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  mock.fault({{"name", "lose_frames"}, {"unit", 0}, {"fraction", 0.3}});
  auto totals = collect_for(mock, bus, 40);
  CHECK(totals[1].lost == 0);
  REQUIRE(totals[0].lost > 0);
  // 0.3 of ~4000 frames: binomial sigma 29 frames, under 0.01 of the total; 0.05 is generous.
  const double lost_fraction = static_cast<double>(totals[0].lost) / static_cast<double>(totals[0].lost + totals[0].frames);
  CHECK(lost_fraction == Approx(0.3).margin(0.05));
  CHECK(totals[0].corrupt == 0);
}

TEST_CASE("fault lose_burst: exactly that many frames of one unit go missing") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  std::vector<Totals> totals;
  const double start = mock.sim_time();
  collect(bus, totals, [&] { return mock.sim_time() >= start + 5; });
  mock.fault({{"name", "lose_burst"}, {"unit", "SIM-0002"}, {"count", 20}});
  // Until the burst is spent (it leaves the status' faults) and a few seconds after.
  double spent_at = -1;
  collect(bus, totals, [&] {
    const auto st = mock.status();
    if (spent_at < 0 && st["faults"].empty()) spent_at = st["time_s"].get<double>();
    return spent_at >= 0 && st["time_s"].get<double>() > spent_at + 3;
  });
  CHECK(totals[0].lost == 0);
  CHECK(totals[1].lost == 20);  // fewer than 256 in a row: the sequence counter tells exactly
}

TEST_CASE("fault corrupt_frames: corrupted frames fail the CRC and are counted, not lost") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  mock.fault({{"name", "corrupt_frames"}, {"fraction", 0.2}});
  auto totals = collect_for(mock, bus, 30);
  for (std::size_t u = 0; u < 2; ++u) {
    INFO("unit " << u);
    CHECK(totals[u].corrupt > 0);
    CHECK(totals[u].lost == 0);  // a corrupt frame explains its gap in the sequence
    // The good frames still average to the drift: over ~2400 frames of 30 s the AR noise
    // leaves 0.146/sqrt(30) = 0.027 deg/h (1 sigma); 0.3 deg/h is ten sigma.
    CHECK(totals[u].mean_dph() == Approx(mu0_dph).margin(0.3));
  }
  CHECK(mock.status()["units"][0]["frames_corrupted"].get<int>() > 0);
}

TEST_CASE("fault gyro_spike: the mean shifts by the spike while it lasts, then returns") {
  MockProcess mock({"--time-scale", "20"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  const double scale_dph = cfg.units[0].gyro.scale_dph_per_count;
  std::vector<Totals> before;
  const double start = mock.sim_time();
  collect(bus, before, [&] { return mock.sim_time() >= start + 30; });

  mock.fault({{"name", "gyro_spike"}, {"dph", 50.0}, {"duration_s", 100000}});
  // Frames already queued still carry the old values: skip to the first spiked frame of the
  // rate-mode unit (-8 + 50 deg/h against 1.46 deg/h of per-frame noise: unmistakable).
  bool spiked = false;
  std::vector<Totals> skipped;
  collect(bus, skipped, [&] { return spiked; }, [&](const can_frame& f) {
    auto g = can::decode(f);
    if (g && g->node_id == 257 && g->counts * scale_dph > 20.0) spiked = true;
  });
  std::vector<Totals> during;
  const double from = mock.sim_time();
  collect(bus, during, [&] { return mock.sim_time() >= from + 30; });
  mock.fault({{"name", "gyro_spike"}, {"on", false}});

  for (std::size_t u = 0; u < 2; ++u) {
    INFO("unit " << u);
    // 30 s means: 0.146/sqrt(30) = 0.027 deg/h (1 sigma); 0.2 is seven sigma. No unspiked
    // frame follows the first spiked one: the bench sends a second's frames of every unit
    // before it steps to the next.
    CHECK(before[u].mean_dph() == Approx(mu0_dph).margin(0.2));
    CHECK(during[u].mean_dph() == Approx(mu0_dph + 50.0).margin(0.2));
    CHECK(during[u].lost == 0);
  }
}

TEST_CASE("a hidden --effect shifts every unit's drift by its term") {
  // At rest at 30 degC every temperature sits 10 degC above the truth's tref (20 degC): the
  // default terms (rates and the gradient) are zero and "1*T1" adds 1 deg/h/degC x 10 degC.
  // The lumped coil: the distributed one adds its own absolute-temperature term at 30 degC.
  MockProcess mock({"--time-scale", "50", "--start-c", "30", "--effect", "1*T1", "--coil", "lumped"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  auto totals = collect_for(mock, bus, 60);
  for (std::size_t u = 0; u < 2; ++u) {
    INFO("unit " << u);
    // 60 s of AR noise: 0.146/sqrt(60) = 0.019 deg/h (1 sigma); 0.1 as in the test at rest.
    CHECK(totals[u].mean_dph() == Approx(mu0_dph + 10.0).margin(0.1));
  }
}

namespace {

// The rate in deg/h of a unit's mean counts (rate or increment mode).
double rate_dph(const DriversConfig& cfg, std::size_t u, double mean_counts) {
  return cfg.units[u].gyro.mean_counts_to_rate_dph(mean_counts);
}

}  // namespace

TEST_CASE("fogbench-sim --fault power_off=D: a unit's frames start D s into the session, its counter at 0, its warm-up after") {
  // SIM-0002 (increment mode) powered on at 20 s; every unit warms up by 10 exp(-t/20) deg/h.
  MockProcess mock({"--time-scale", "50", "--fault", "power_off=20,unit=1", "--warmup-dph", "10", "--warmup-tau-s", "20"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  const auto early = mock.status();
  REQUIRE(early["time_s"].get<double>() < 18);  // the bench starts in well under a wall second
  CHECK(early["units"][1]["powered"] == false);
  CHECK(early["units"][1]["frames_sent"] == 0);
  CHECK(early["units"][1]["gyro_dph"].is_null());
  CHECK(early["units"][0]["powered"] == true);

  std::vector<std::int32_t> counts;  // SIM-0002's frames in order
  std::vector<std::uint8_t> sequence;
  std::vector<Totals> totals;
  collect(bus, totals, [&] { return counts.size() >= 2600; }, [&](const can_frame& f) {
    auto g = can::decode(f);
    if (g && g->node_id == 258) {
      counts.push_back(g->counts);
      sequence.push_back(g->sequence);
    }
  });
  const auto st = mock.status();
  CHECK(st["units"][1]["powered"] == true);
  CHECK(st["units"][1]["powered_on_at_s"] == 20.0);
  CHECK(st["units"][0]["powered_on_at_s"] == 0.0);
  // 100 frames per second from 20 s: the frames sent match the time since (one second either
  // way for the status' snapshot).
  const double on_s = st["time_s"].get<double>() - 20.0;
  CHECK(st["units"][1]["frames_sent"].get<double>() == Approx(100.0 * on_s).margin(100));
  REQUIRE(sequence.size() >= 2600);
  CHECK(sequence[0] == 0);  // the counter starts at power-on
  CHECK(sequence[1] == 1);
  CHECK(totals[1].lost == 0);

  // The warm-up: the mean of frames 0..499 (the first 5 s on) is mu0 + 10 * (20/5)(1 - e^-0.25)
  // = -8.097 + 8.848 = 0.751 deg/h; frames 2000..2499 (20..25 s on) mu0 + 40 (e^-1 - e^-1.25)
  // = -4.842 deg/h. 5 s of AR noise: 0.146/sqrt(5) = 0.065 deg/h (1 sigma); the increment
  // mode's quantisation carries over, within one count (2.88 deg/h) per 500 frames. 0.3 is
  // over four sigma.
  auto mean_of = [&](std::size_t from, std::size_t to) {
    double s = 0;
    for (std::size_t i = from; i < to; ++i) s += counts[i];
    return rate_dph(cfg, 1, s / static_cast<double>(to - from));
  };
  CHECK(mean_of(0, 500) == Approx(mu0_dph + 10.0 * 4.0 * (1 - std::exp(-0.25))).margin(0.3));
  CHECK(mean_of(2000, 2500) == Approx(mu0_dph + 40.0 * (std::exp(-1.0) - std::exp(-1.25))).margin(0.3));
}

TEST_CASE("fault power_cycle: a unit's frames stop for off_s, then restart with the counter at 0") {
  MockProcess mock({"--time-scale", "50"});
  auto cfg = mock.example_config();
  auto bus = open_bus(mock, cfg);
  std::vector<Totals> totals;
  const double start = mock.sim_time();
  collect(bus, totals, [&] { return mock.sim_time() >= start + 5; });
  mock.fault({{"name", "power_cycle"}, {"unit", "SIM-0001"}, {"off_s", 4}});
  // Off from the next second for 4 s: the status shows it unpowered within two seconds.
  REQUIRE(wait_for(5s, [&] { return mock.status()["units"][0]["powered"] == false; }));
  const auto off = mock.status();
  REQUIRE(off["faults"].size() == 1);
  const double on_at = off["faults"][0]["until_s"].get<double>();
  CHECK(off["faults"][0]["name"] == "power_off");
  CHECK(on_at - off["faults"][0]["from_s"].get<double>() == 4.0);
  // SIM-0001's frames from the cut on: the first after the gap (SIM-0002 sent over 200 frames,
  // 2 s, since SIM-0001's previous one) has sequence 0.
  std::optional<std::uint8_t> first_after;
  int others_since = 0;
  const double cut_s = mock.sim_time();
  collect(bus, totals, [&] { return first_after.has_value() || mock.sim_time() > cut_s + 15; }, [&](const can_frame& f) {
    auto g = can::decode(f);
    if (!g || first_after) return;
    if (g->node_id == 258) ++others_since;
    if (g->node_id != 257) return;
    if (others_since > 200) first_after = g->sequence;
    others_since = 0;
  });
  REQUIRE(first_after.has_value());
  CHECK(*first_after == 0);
  const auto after = mock.status();
  CHECK(after["units"][0]["powered"] == true);
  CHECK(after["units"][0]["powered_on_at_s"] == on_at);
  CHECK(after["units"][1]["powered_on_at_s"] == 0.0);  // the other unit was not cycled
}

TEST_CASE("fogbench-sim --axes 3: each axis on node id + axis, its own bias and noise, recovered per axis", "[three_axis]") {
  MockProcess mock({"--time-scale", "50", "--axes", "3", "--axis-bias-dph", "2"});
  const auto& served = mock.ready()["drivers_config"];
  auto parsed = parse_drivers_config(served, FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((parsed ? std::string() : parsed.error().to_string()));
  REQUIRE(parsed.has_value());
  REQUIRE(parsed->units.size() == 2);
  CHECK(parsed->units[0].gyro.node_id == 257);
  CHECK(parsed->units[1].gyro.node_id == 261);
  std::vector<GyroChannelConfig> gyros;
  for (const auto& u : parsed->units) {
    CHECK(u.gyro.axes == 3);
    gyros.push_back(u.gyro);
  }
  // The truth: each axis's bias, drawn from the seed, served in the ready line.
  std::vector<std::vector<double>> bias;
  for (const auto& u : mock.ready()["units"]) bias.push_back(u["axis_bias_dph"].get<std::vector<double>>());
  REQUIRE(bias.size() == 2);
  REQUIRE(bias[0].size() == 3);
  CHECK(bias[0][0] == 0.0);
  // Drawn, not fixed: the axes differ from each other by more than the test's margin.
  CHECK(std::abs(bias[0][1] - bias[0][2]) > 0.2);

  auto bus = GyroBus::open(parsed->gyro_bus, gyros);
  REQUIRE(bus.has_value());
  REQUIRE(wait_for(5s, [&] { return mock.status()["can_clients"] == 1; }));

  // Per unit and axis: frames, lost, corrupt, and the used-weighted mean rate.
  struct Axis {
    std::uint64_t frames = 0, used = 0, lost = 0, corrupt = 0;
    double sum_dph = 0;
  };
  std::vector<std::array<Axis, 3>> axes(2);
  // The y-minus-x difference of each sample: were the axes' noises one stream, it would be the
  // constant bias difference.
  std::vector<double> y_minus_x;
  auto add = [&](Axis& a, const GyroSample& g) {
    a.frames += g.frames;
    a.used += g.frames_used;
    a.lost += g.frames_lost;
    a.corrupt += g.frames_corrupt;
    if (g.rate_dph) a.sum_dph += *g.rate_dph * g.frames_used;
  };
  std::vector<can_frame> frames;
  const double until = mock.sim_time() + 100;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  bool first = true;
  while (mock.sim_time() < until) {
    REQUIRE(std::chrono::steady_clock::now() < deadline);
    pollfd p{bus->fd(), POLLIN, 0};
    ::poll(&p, 1, 20);
    REQUIRE(bus->read_frames(frames).has_value());
    std::this_thread::sleep_for(200ms);  // ~10 simulated s per sample at K = 50
    REQUIRE(bus->read_frames(frames).has_value());
    const BusSample s = bus->close_samples();
    if (first) {  // the frames queued before the reader started: a partial sample
      first = false;
      continue;
    }
    REQUIRE(s.extra_axes.size() == 2);
    for (std::size_t u = 0; u < 2; ++u) {
      REQUIRE(s.extra_axes[u].size() == 2);
      add(axes[u][0], s.units[u]);
      add(axes[u][1], s.extra_axes[u][0]);
      add(axes[u][2], s.extra_axes[u][1]);
    }
    if (s.units[0].rate_dph && s.extra_axes[0][0].rate_dph) y_minus_x.push_back(*s.extra_axes[0][0].rate_dph - *s.units[0].rate_dph);
  }
  for (std::size_t u = 0; u < 2; ++u) {
    for (std::size_t k = 0; k < 3; ++k) {
      INFO("unit " << u << " axis " << k);
      const Axis& a = axes[u][k];
      CHECK(a.lost == 0);
      CHECK(a.corrupt == 0);
      REQUIRE(a.used > 5000);
      // As the one-axis test above: ~100 s of the 1 s AR noise, 0.015 deg/h (1 sigma), each
      // axis about the drift plus its own bias.
      CHECK(a.sum_dph / static_cast<double>(a.used) == Approx(mu0_dph + bias[u][k]).margin(0.1));
    }
  }
  // Independent noise per axis: the difference of the axes' ~10 s means wanders (sigma about
  // 0.146 * sqrt(2 / 10) = 0.065 deg/h), where shared noise would leave it constant.
  REQUIRE(y_minus_x.size() >= 4);
  const auto [lo, hi] = std::minmax_element(y_minus_x.begin(), y_minus_x.end());
  CHECK(*hi - *lo > 0.01);
  CHECK(mock.status()["can_frames_dropped"] == 0);
}

TEST_CASE("fogbench-sim --axis-effect: the y and z axes carry their own drift, x none", "[three_axis]") {
  // At rest at 30 degC (lumped coil: no field term) T1 - tref is 10 degC: y's "1*T1" adds
  // 10 deg/h, z's "-0.5*T1" -5 deg/h, x nothing; no drawn biases (--axis-bias-dph 0).
  MockProcess mock({"--time-scale", "50", "--axes", "3", "--axis-bias-dph", "0", "--start-c", "30", "--coil", "lumped",
                    "--axis-effect", "y=1*T1", "--axis-effect", "z=-0.5*T1"});
  CHECK(mock.ready()["units"][0]["axis_effects"]["y"] == "1*T1");
  const auto& served = mock.ready()["drivers_config"];
  auto parsed = parse_drivers_config(served, FOGBENCH_SOURCE_DIR "/drivers/maps");
  REQUIRE(parsed.has_value());
  std::vector<GyroChannelConfig> gyros;
  for (const auto& u : parsed->units) gyros.push_back(u.gyro);
  auto bus = GyroBus::open(parsed->gyro_bus, gyros);
  REQUIRE(bus.has_value());
  REQUIRE(wait_for(5s, [&] { return mock.status()["can_clients"] == 1; }));
  std::array<double, 3> sum{};
  std::array<std::uint64_t, 3> used{};
  auto add = [&](std::size_t k, const GyroSample& g) {
    if (g.rate_dph) sum[k] += *g.rate_dph * static_cast<double>(g.frames_used);
    used[k] += g.frames_used;
  };
  std::vector<can_frame> frames;
  const double until = mock.sim_time() + 60;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  bool first = true;
  while (mock.sim_time() < until) {
    REQUIRE(std::chrono::steady_clock::now() < deadline);
    pollfd p{bus->fd(), POLLIN, 0};
    ::poll(&p, 1, 20);
    REQUIRE(bus->read_frames(frames).has_value());
    std::this_thread::sleep_for(200ms);
    REQUIRE(bus->read_frames(frames).has_value());
    const BusSample s = bus->close_samples();
    if (first) {  // the frames queued before the reader started: a partial sample
      first = false;
      continue;
    }
    REQUIRE(s.extra_axes.size() == 2);
    add(0, s.units[0]);
    add(1, s.extra_axes[0][0]);
    add(2, s.extra_axes[0][1]);
  }
  // 60 s of AR noise: 0.146/sqrt(60) = 0.019 deg/h (1 sigma); 0.1 as in the one-axis --effect test.
  const std::array<double, 3> own = {0.0, 10.0, -5.0};
  for (std::size_t k = 0; k < 3; ++k) {
    INFO("axis " << k);
    REQUIRE(used[k] > 2000);
    CHECK(sum[k] / static_cast<double>(used[k]) == Approx(mu0_dph + own[k]).margin(0.1));
  }
}
