// The chamber driver over Modbus RTU: a libmodbus RTU server and the driver each open one end of
// a pair of pseudo-terminals bridged by a thread, so the serial path (framing, CRC, parity
// settings) runs without a serial port.
#include <catch2/catch.hpp>

#include <fcntl.h>
#include <modbus/modbus.h>
#include <poll.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <mutex>
#include <string>
#include <thread>

#include "fogbench/drivers/chamber.hpp"

using namespace fogbench::drivers;

namespace {

struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    REQUIRE(master >= 0);
    REQUIRE(::grantpt(master) == 0);
    REQUIRE(::unlockpt(master) == 0);
    slave = ::ptsname(master);
    // Raw mode on the master too, so no byte is translated on its way through.
    termios t{};
    ::tcgetattr(master, &t);
    ::cfmakeraw(&t);
    ::tcsetattr(master, TCSANOW, &t);
  }
  ~Pty() { ::close(master); }
};

// Copies bytes between two pty masters: what the driver writes reaches the server and back.
class Bridge {
 public:
  Bridge(int a, int b) : a_(a), b_(b), thread_([this] { run(); }) {}
  ~Bridge() {
    stop_ = true;
    thread_.join();
  }

 private:
  void run() {
    char buf[512];
    while (!stop_) {
      pollfd p[2] = {{a_, POLLIN, 0}, {b_, POLLIN, 0}};
      if (::poll(p, 2, 20) <= 0) continue;
      for (int i = 0; i < 2; ++i) {
        if (p[i].revents & POLLIN) {
          const ssize_t n = ::read(p[i].fd, buf, sizeof buf);
          if (n > 0) (void)!::write(i == 0 ? b_ : a_, buf, static_cast<std::size_t>(n));
        }
      }
    }
  }
  int a_, b_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace

TEST_CASE("chamber over RTU: setpoint written and process value read through a serial line") {
  Pty client_side, server_side;
  Bridge bridge(client_side.master, server_side.master);

  modbus_t* server = modbus_new_rtu(server_side.slave.c_str(), 19200, 'E', 8, 1);
  REQUIRE(server != nullptr);
  modbus_set_slave(server, 7);
  REQUIRE(modbus_connect(server) == 0);
  modbus_mapping_t* mapping = modbus_mapping_new(16, 16, 16, 16);
  const auto pv = std::bit_cast<std::uint32_t>(-55.5f);
  mapping->tab_input_registers[0] = static_cast<std::uint16_t>(pv >> 16);
  mapping->tab_input_registers[1] = static_cast<std::uint16_t>(pv);
  std::mutex mutex;
  std::atomic<bool> stop{false};
  std::thread serve([&] {
    modbus_set_indication_timeout(server, 0, 50000);  // wake up to notice `stop`
    std::uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
    while (!stop) {
      const int rc = modbus_receive(server, query);
      if (rc > 0) {
        std::lock_guard lock(mutex);
        modbus_reply(server, query, rc, mapping);
      }
    }
  });

  ChamberConfig cfg;
  cfg.modbus.transport = ModbusEndpoint::Transport::rtu;
  cfg.modbus.device = client_side.slave;
  cfg.modbus.baud = 19200;
  cfg.modbus.parity = 'E';
  cfg.modbus.unit_id = 7;
  cfg.modbus.response_timeout_ms = 1000;
  auto map = load_register_map(FOGBENCH_SOURCE_DIR "/drivers/maps/mock.json");
  REQUIRE(map.has_value());
  cfg.map = *map;
  ModbusChamber chamber(cfg);

  auto read = chamber.read_process_value_c();
  INFO((read ? std::string("ok") : read.error().to_string()));
  REQUIRE(read.has_value());
  CHECK(*read == -55.5);
  REQUIRE(chamber.write_setpoint_c(-40.25).has_value());
  {
    std::lock_guard lock(mutex);
    CHECK(mapping->tab_registers[0] == 0xC221);  // -40.25f = 0xC2210000 (see modbus_test.cpp)
    CHECK(mapping->tab_registers[1] == 0x0000);
  }

  // Another unit id on the line: the server stays silent and the driver times out.
  ChamberConfig other = cfg;
  other.modbus.unit_id = 8;
  other.modbus.response_timeout_ms = 100;
  ModbusChamber nobody(other);
  chamber.link().disconnect();  // one opener of the tty at a time
  auto silent = nobody.read_process_value_c();
  REQUIRE_FALSE(silent.has_value());
  CHECK(silent.error().code == ErrorCode::timeout);
  CHECK(silent.error().message.find("rtu " + client_side.slave + " 19200 8E1 unit 8") != std::string::npos);

  stop = true;
  serve.join();
  modbus_close(server);
  modbus_free(server);
  modbus_mapping_free(mapping);
}
