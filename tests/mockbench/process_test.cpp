// The mock bench as a process: its ready line, the control protocol, its scaled clock, a clean
// stop (socket files removed), refusal of bad options, and mbpoll as an independent Modbus
// client.
#include <catch2/catch.hpp>

#include <linux/can.h>
#include <sys/socket.h>
#include <sys/un.h>

#include <cstdio>
#include <cstring>
#include <memory>

#include "fogbench/drivers/chamber.hpp"
#include "mock_process.hpp"

using namespace fogbench::drivers;
using namespace mockbench;

namespace {

// Runs a shell command; its standard output, and its exit status in `status`.
std::string run(const std::string& command, int& status) {
  std::string out;
  FILE* p = ::popen(command.c_str(), "r");
  REQUIRE(p != nullptr);
  char buf[512];
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  const int rc = ::pclose(p);
  status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  return out;
}

}  // namespace

TEST_CASE("the ready line says what is served, and its drivers configuration parses") {
  MockProcess mock({"--units", "3", "--frame-rate-hz", "200"});
  const auto& r = mock.ready();
  CHECK(r["version"] == 1);
  CHECK(r["chamber"]["unit_id"] == 1);
  CHECK(r["thermistors"]["unit_id"] == 2);
  CHECK(r["chamber"]["port"].get<int>() > 0);
  CHECK(r["thermistors"]["port"].get<int>() > 0);
  CHECK(r["can_socket"] == (mock.dir() / "can.sock").string());
  REQUIRE(r["units"].size() == 3);
  CHECK(r["units"][2]["serial"] == "SIM-0003");
  CHECK(r["units"][2]["node_id"] == 259);
  CHECK(r["units"][2]["frame_rate_hz"] == 200);
  auto cfg = parse_drivers_config(r["drivers_config"], FOGBENCH_SOURCE_DIR "/drivers/maps");
  INFO((cfg ? std::string() : cfg.error().to_string()));
  REQUIRE(cfg.has_value());
  CHECK(cfg->units.size() == 3);
  CHECK(cfg->chamber.modbus.port == mock.chamber_port());
  CHECK(cfg->chamber.map.name == "fogbench mock chamber");
  // The third unit continues the example's pattern: rate mode, int16 at input 2 and 3.
  CHECK(cfg->units[2].gyro.mode == GyroMode::rate);
  CHECK(cfg->units[2].t1.reg.address == 2);
  CHECK(cfg->units[2].t2.reg.address == 3);
}

TEST_CASE("the control socket answers status and refuses bad requests with a reason") {
  MockProcess mock({"--effect", "0.05*T1"});
  const auto st = mock.status();
  CHECK(st["ok"] == true);
  CHECK(st["version"] == 1);
  for (const char* key : {"time_s", "setpoint_c", "air_c", "pv_c", "running", "units", "faults"}) {
    INFO(key);
    CHECK(st.contains(key));
  }
  REQUIRE(st["units"].size() == 2);
  CHECK(st["units"][1]["serial"] == "SIM-0002");
  CHECK(st["units"][1]["t1_c"].get<double>() == Approx(20.0).margin(0.05));

  auto refused = [&](const json& request, const std::string& says) {
    const auto reply = mock.control(request);
    INFO(request.dump() << " -> " << reply.dump());
    CHECK(reply["ok"] == false);
    CHECK(reply["error"].get<std::string>().find(says) != std::string::npos);
  };
  refused({{"cmd", "dance"}}, "unknown cmd 'dance'");
  refused({{"cmd", "fault"}, {"name", "melt"}}, "unknown fault 'melt'");
  refused({{"cmd", "fault"}, {"name", "stall_modbus"}}, "stall_modbus: ms: missing");
  refused({{"cmd", "fault"}, {"name", "lose_frames"}, {"fraction", 2}}, "fraction: expected 0..1");
  refused({{"cmd", "fault"}, {"name", "open_thermistor"}, {"unit", 9}}, "unit: expected an index 0..1");
  refused({{"cmd", "fault"}, {"name", "alarm"}, {"ms", 3}}, "alarm.ms: unknown field (known: on)");
  refused("just a string", "expected an object");
}

TEST_CASE("faults given at start are active from the first request") {
  MockProcess mock({"--fault", "alarm", "--fault", "open_thermistor=t2,unit=1", "--fault", "stall_modbus=5,device=thermistors"});
  const auto faults = mock.status()["faults"];
  REQUIRE(faults.size() == 3);
  CHECK(faults[0] == json({{"name", "stall_modbus"}, {"device", "thermistors"}, {"ms", 5}}));
  CHECK(faults[1]["name"] == "alarm");
  CHECK(faults[2] == json({{"name", "open_thermistor"}, {"unit", 1}, {"serial", "SIM-0002"}, {"sensor", "t2"}}));
  ModbusChamber chamber(mock.example_config().chamber);
  CHECK(*chamber.read_alarm() == true);
}

TEST_CASE("the clock runs time-scale times faster than real time") {
  MockProcess mock({"--time-scale", "200"});
  // Each reading of the simulated time happened somewhere between sending the request and
  // getting the reply: bracket the elapsed wall time by those instants.
  auto timed = [&](double& sim_s) {
    const auto before = std::chrono::steady_clock::now();
    sim_s = mock.sim_time();
    return std::pair{before, std::chrono::steady_clock::now()};
  };
  double s0 = 0, s1 = 0;
  const auto [a0, b0] = timed(s0);
  std::this_thread::sleep_for(2s);
  const auto [a1, b1] = timed(s1);
  const double longest_s = std::chrono::duration<double>(b1 - a0).count();
  const double shortest_s = std::chrono::duration<double>(a1 - b0).count();
  // On an absolute schedule the clock is never ahead (one step of rounding); a loaded machine may
  // hold the clock thread back a little, and it catches up when it runs: 20% for that.
  CHECK(s1 - s0 <= 200.0 * longest_s + 1.0);
  CHECK(s1 - s0 >= 0.8 * 200.0 * shortest_s - 1.0);
}

TEST_CASE("fogbench-sim --paced: the clock moves only on advance, whose reply comes after every frame of those seconds") {
  MockProcess mock({"--paced", "--time-scale", "200"});
  // A raw CAN client, so every datagram is counted.
  const int can = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string path = mock.can_socket();
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  REQUIRE(::connect(can, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  REQUIRE(wait_for(5s, [&] { return mock.control({{"cmd", "status"}})["can_clients"] == 1; }));
  auto frames_waiting = [&] {
    int n = 0;
    ::can_frame f{};
    while (::recv(can, &f, sizeof f, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof f)) ++n;
    return n;
  };
  // Left alone, it does not move: at K = 200, 300 ms would be 60 simulated seconds.
  std::this_thread::sleep_for(300ms);
  CHECK(mock.sim_time() == 0.0);
  CHECK(frames_waiting() == 0);
  const json r = mock.control({{"cmd", "advance"}, {"seconds", 3}});
  INFO(r.dump());
  REQUIRE(r["ok"] == true);
  CHECK(r["time_s"] == 3.0);
  // 3 s x 100 frames/s x 2 units, all in the socket by the time the reply was read.
  CHECK(frames_waiting() == 600);
  std::this_thread::sleep_for(200ms);
  CHECK(frames_waiting() == 0);
  CHECK(mock.sim_time() == 3.0);
  CHECK(mock.control({{"cmd", "advance"}})["time_s"] == 4.0);
  CHECK(frames_waiting() == 200);
  ::close(can);

  MockProcess free_running({"--time-scale", "200"});
  CHECK(free_running.control({{"cmd", "advance"}})["error"] ==
        "advance: the bench keeps its own clock (start it with --paced)");
}

TEST_CASE("SIGTERM and the stop command end the bench cleanly and remove its sockets") {
  {
    MockProcess mock;
    ::kill(mock.pid(), SIGTERM);
    CHECK(mock.wait_exit(10s) == 0);
    CHECK_FALSE(fs::exists(mock.dir() / "can.sock"));
    CHECK_FALSE(fs::exists(mock.dir() / "control.sock"));
  }
  {
    MockProcess mock;
    CHECK(mock.control({{"cmd", "stop"}})["ok"] == true);
    CHECK(mock.wait_exit(10s) == 0);
    CHECK_FALSE(fs::exists(mock.dir() / "can.sock"));
  }
  {
    // --duration-s: the bench stops by itself after that much simulated time.
    MockProcess mock({"--time-scale", "1000", "--duration-s", "500"});
    CHECK(mock.wait_exit(20s) == 0);
  }
}

TEST_CASE("bad options are refused with a message and exit status 2") {
  int status = 0;
  const std::string bin = FOGBENCH_SIM_BIN;
  run(bin + " --effect 'T9' --modbus-port 0 --thermistor-port 0 2>&1", status);
  CHECK(status == 2);
  auto out = run(bin + " --fault 'melt' --modbus-port 0 --thermistor-port 0 2>&1", status);
  CHECK(status == 2);
  CHECK(out.find("unknown fault 'melt'") != std::string::npos);
  out = run(bin + " --units 40 2>&1", status);  // refused by the option parser itself
  CHECK(status == 2);
  CHECK(out.find("--units") != std::string::npos);
  run(bin + " --help", status);
  CHECK(status == 0);
  out = run(bin + " --modbus-port 1502 --thermistor-port 1502 2>&1", status);
  CHECK(status == 2);
  CHECK(out.find("--gateway") != std::string::npos);
}

TEST_CASE("mbpoll reads the process value the drivers read (independent Modbus client)") {
  int status = 0;
  run("command -v mbpoll", status);
  // scripts/deps installs mbpoll: a machine without it fails here rather than passing unchecked.
  if (status != 0) FAIL("mbpoll is not installed (apt-get install mbpoll): the cross-check cannot run");
  MockProcess mock;
  ModbusChamber chamber(mock.example_config().chamber);
  auto pv = chamber.read_process_value_c();
  REQUIRE(pv.has_value());
  // Input register 1 in mbpoll's 1-based numbering is protocol address 0; -B: high word first.
  const auto out = run("mbpoll -m tcp -p " + std::to_string(mock.chamber_port()) +
                           " -a 1 -r 1 -c 1 -t 3:float -B -1 -o 2 127.0.0.1", status);
  INFO(out);
  REQUIRE(status == 0);
  const auto at = out.find("[1]:");
  REQUIRE(at != std::string::npos);
  const double mb = std::stod(out.substr(at + 4));
  // Both at rest at 20 degC; the reading's noise is 0.02 degC (1 sigma) per simulated second.
  CHECK(mb == Approx(*pv).margin(0.15));
  CHECK(mb == Approx(20.0).margin(0.1));
}
