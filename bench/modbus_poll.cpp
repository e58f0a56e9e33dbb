// Benchmark: one poll cycle of the bench's Modbus devices on loopback, as the daemon makes it
// each second: the chamber (process value, setpoint, run, alarm, status through the mock map)
// and the thermistor module (T1 and T2 of 8 units), each against a libmodbus TCP server thread.
// Prints p50/p99/max latency in ms per device and per cycle.
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <vector>

#include "fogbench/drivers/chamber.hpp"
#include "fogbench/drivers/thermistor_module.hpp"

using namespace fogbench::drivers;
using Clock = std::chrono::steady_clock;

namespace {

// A minimal libmodbus TCP server on an ephemeral loopback port, serving one client.
class Server {
 public:
  Server(int registers, int input_registers) {
    ctx_ = modbus_new_tcp("127.0.0.1", 0);
    mapping_ = modbus_mapping_new(16, 16, registers, input_registers);
    listen_fd_ = modbus_tcp_listen(ctx_, 1);
    if (ctx_ == nullptr || mapping_ == nullptr || listen_fd_ < 0) {
      std::fprintf(stderr, "server set-up failed\n");
      std::exit(1);
    }
    sockaddr_in addr{};
    socklen_t len = sizeof addr;
    ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] {
      const int s = ::accept(listen_fd_, nullptr, nullptr);
      if (s < 0) return;
      client_ = s;
      modbus_set_socket(ctx_, s);
      std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
      for (;;) {
        const int rc = modbus_receive(ctx_, query);
        if (rc == -1) break;
        if (rc > 0) modbus_reply(ctx_, query, rc, mapping_);
      }
      ::close(s);
    });
  }
  ~Server() {
    ::shutdown(listen_fd_, SHUT_RDWR);
    if (client_ >= 0) ::shutdown(client_, SHUT_RDWR);
    thread_.join();
    ::close(listen_fd_);
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
  }
  std::uint16_t port() const { return port_; }
  modbus_mapping_t& mapping() { return *mapping_; }

 private:
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  std::atomic<int> client_{-1};
  std::uint16_t port_ = 0;
  std::thread thread_;
};

ModbusEndpoint local(std::uint16_t port) {
  ModbusEndpoint ep;
  ep.host = "127.0.0.1";
  ep.port = port;
  ep.response_timeout_ms = 500;
  return ep;
}

struct Stats {
  double p50 = 0, p99 = 0, max = 0, mean = 0;
};

Stats stats(std::vector<double> ms) {
  std::sort(ms.begin(), ms.end());
  Stats s;
  auto at = [&](double q) { return ms[static_cast<std::size_t>(q * static_cast<double>(ms.size() - 1))]; };
  s.p50 = at(0.50);
  s.p99 = at(0.99);
  s.max = ms.back();
  for (double v : ms) s.mean += v;
  s.mean /= static_cast<double>(ms.size());
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  const int cycles = argc > 1 ? std::atoi(argv[1]) : 2000;
  constexpr int units = 8;

  Server chamber_server(16, 16);
  {
    auto& m = chamber_server.mapping();
    const auto pv = std::bit_cast<std::uint32_t>(23.5f);
    m.tab_input_registers[0] = static_cast<std::uint16_t>(pv >> 16);
    m.tab_input_registers[1] = static_cast<std::uint16_t>(pv);
    m.tab_input_registers[2] = 0xF0B2;
    m.tab_input_registers[3] = 1;
  }
  Server module_server(0, 64);
  {
    auto& m = module_server.mapping();
    for (int i = 0; i < 2 * units; ++i) m.tab_input_registers[i] = static_cast<std::uint16_t>(2500 + i);
  }

  ChamberConfig ccfg;
  ccfg.modbus = local(chamber_server.port());
  auto map = load_register_map(FOGBENCH_SOURCE_DIR "/drivers/maps/mock.json");
  if (!map) {
    std::fprintf(stderr, "%s\n", map.error().to_string().c_str());
    return 1;
  }
  ccfg.map = *map;
  ModbusChamber chamber(ccfg);

  // 8 units, T1 and T2 as scaled int16 temperatures at input 0..15: one request per poll.
  std::vector<UnitConfig> unit_cfgs;
  for (int u = 0; u < units; ++u) {
    UnitConfig uc;
    uc.serial = "FOG-" + std::to_string(u + 1);
    uc.gyro.node_id = static_cast<std::uint16_t>(0x101 + u);
    uc.gyro.scale_dph_per_count = 1e-4;
    for (int t = 0; t < 2; ++t) {
      ThermistorChannelConfig ch;
      ch.reg.function = RegisterFunction::input;
      ch.reg.address = static_cast<std::uint16_t>(2 * u + t);
      ch.reg.type = ValueType::int16;
      ch.reg.scale = 0.01;
      (t == 0 ? uc.t1 : uc.t2) = ch;
    }
    unit_cfgs.push_back(uc);
  }
  ThermistorModule module({local(module_server.port())}, unit_cfgs);

  // Connect and warm up outside the measurement.
  if (auto r = chamber.poll(); !r) {
    std::fprintf(stderr, "%s\n", r.error().to_string().c_str());
    return 1;
  }
  if (auto r = module.read_all(); !r) {
    std::fprintf(stderr, "%s\n", r.error().to_string().c_str());
    return 1;
  }

  std::vector<double> chamber_ms, module_ms, cycle_ms;
  int failures = 0;
  for (int i = 0; i < cycles; ++i) {
    const auto t0 = Clock::now();
    auto c = chamber.poll();
    const auto t1 = Clock::now();
    auto t = module.read_all();
    const auto t2 = Clock::now();
    if (!c || !t) ++failures;
    for (const auto& u : *t) {
      if (!u.t1_c || !u.t2_c) ++failures;
    }
    chamber_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    module_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    cycle_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t0).count());
  }

  std::printf("Modbus TCP poll on loopback, %d cycles, %d units\n\n", cycles, units);
  std::printf("%-44s %8s %8s %8s %8s %9s\n", "what", "p50 ms", "p99 ms", "max ms", "mean ms", "requests");
  const auto row = [](const char* what, const Stats& s, int requests) {
    std::printf("%-44s %8.3f %8.3f %8.3f %8.3f %9d\n", what, s.p50, s.p99, s.max, s.mean, requests);
  };
  row("chamber poll (PV, SP, run, alarm, status)", stats(chamber_ms), 5);
  row("thermistors, 8 units x T1+T2 (16 sensors)", stats(module_ms),
      static_cast<int>(module.request_count()));
  row("whole cycle", stats(cycle_ms), 5 + static_cast<int>(module.request_count()));
  std::printf("\nfailed polls: %d\n", failures);
  return failures == 0 ? 0 : 1;
}
