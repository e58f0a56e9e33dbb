// The mock bench: sim::World stepped on a clock K times faster than real time and served as the
// bench's hardware. Its parts, each in its own file: the Modbus TCP server (chamber controller
// and thermistor module, libmodbus in a poll() loop on the calling thread; modbus_server.hpp),
// the gyros' CAN bus (an AF_UNIX SOCK_SEQPACKET socket, one struct can_frame per datagram;
// can_bus.hpp), the clock thread that steps the physics and sends the frames (bench_clock.hpp),
// and here the control socket, the signal handling and the loop. No client can block the clock:
// the two threads share only the served registers, the fault state and a status snapshot, under
// one mutex (shared_state.hpp), and the list of CAN readers, under the bus's own. Described for
// users in docs/mock-bench.md.
#pragma once

#include <nlohmann/json.hpp>

#include <expected>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fogbench/drivers/serial_frame.hpp"
#include "fogbench/sim/scale_factor.hpp"
#include "fogbench/sim/sim.hpp"
#include "ascii_chamber.hpp"
#include "layout.hpp"

namespace fogbench::mock {

// A gyro's warm-up after each power-on: dph * exp(-t/tau_s) added to its drift, t the simulated
// time since the power-on. dph 0: none.
struct Warmup {
  double dph = 0;
  double tau_s = 600;
};

struct BenchConfig {
  Endpoints where;                 // ports 0: ephemeral, resolved by create()
  bool gateway = false;            // the thermistor module answers on the chamber's port
  // The chamber controller's protocol on its port: Modbus (the map), or an ASCII dialect
  // answered from the same registers (ascii_chamber.hpp).
  ChamberDialect dialect = ChamberDialect::modbus;
  std::string control_path;        // empty: no control socket
  double time_scale = 1.0;         // simulated seconds per wall second
  double duration_s = 0;           // stop after this many simulated seconds; 0: when told
  // The clock moves only when a client asks ({"cmd":"advance"} on the control socket): the
  // daemon paces the world, so a busy host slows both down together instead of pulling them
  // apart. time_scale then only describes the pace the client is expected to keep.
  bool paced = false;
  double frame_noise_dph = 0;      // extra white noise per frame (electronics), 1 sigma, deg/h
  // The gyros' frames carry the status bit `warming_up` for their first second after a power-on
  // (false: a gyro kind without it; docs/can-frames.md "Power-on").
  bool startup_flag = true;
  std::vector<Warmup> warmup;      // per unit (missing: none)
  sim::SimConfig sim;              // the physics; sim.units in the order of `units`
  std::vector<UnitLayout> units;
  ServedMap map;
  std::vector<nlohmann::json> start_faults;  // fault commands applied before serving
  // The first unit's frames also as binary serial frames on a pty linked here (serial_gyro.hpp);
  // empty: none.
  std::string serial_gyro_link;
  std::optional<drivers::serial::FrameFormat> serial_frame;
  nlohmann::json serial_frame_json;  // the layout as given, for the served drivers_config
  // A rate table (rate_table.hpp) on this TCP port (0: ephemeral, resolved by create()); empty:
  // none. Its time is the wall clock since the start times time_scale (paced or not).
  std::optional<int> rate_table_port;
  // What the table's rate becomes in each unit's gyro output (axis 0, the one on the table's
  // axis), at its true inner-coil temperature; served in the ready line (scale_factor_truth).
  // No temperature-rate term: the bench gives the truth 0 degC/min (keep
  // temp_rate_ppm_per_c_per_min 0).
  sim::ScaleFactorTruth sf_truth;
};

class Bench {
 public:
  // Checks the configuration, builds the world, binds every socket and blocks SIGINT and SIGTERM
  // in the calling thread (run() takes them from a signalfd). Call before starting any thread.
  static std::expected<std::unique_ptr<Bench>, std::string> create(BenchConfig config);
  ~Bench();
  Bench(const Bench&) = delete;
  Bench& operator=(const Bench&) = delete;

  // What is served, for the one JSON line on stdout: ports, socket paths, units and their node
  // ids, and a drivers configuration that reads all of it.
  nlohmann::json ready_line() const;

  // Starts the clock and serves until SIGINT/SIGTERM, {"cmd":"stop"} or the configured
  // duration; then closes every socket and removes the socket files. Returns the exit status.
  int run();

  struct Impl;

 private:
  explicit Bench(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace fogbench::mock
