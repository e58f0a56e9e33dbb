// The mock bench's Modbus TCP side: the listeners (chamber controller and thermistor module,
// or one gateway port serving both) and their clients, served with libmodbus from the bench's
// poll() loop. Requests are answered from the registers in SharedState; the faults there make a
// listener refuse connects (refuse_modbus) or a device answer late (stall_modbus).
#pragma once

#include <modbus/modbus.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <vector>

#include "faults.hpp"
#include "layout.hpp"
#include "poll_set.hpp"
#include "shared_state.hpp"

namespace fogbench::mock {

class ModbusServer {
 public:
  using Clock = std::chrono::steady_clock;

  ModbusServer(SharedState& shared, const Endpoints& where) : shared_(shared), where_(where) {}
  ~ModbusServer();
  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  // Opens the listeners (the thermistor module on the chamber's port when `gateway`); ports 0
  // become ephemeral ones, read back with chamber_port() and thermistor_port().
  // `chamber` false: the chamber is served in another dialect (ascii_chamber.hpp) and only the
  // thermistor module listens here (thermistor_port()).
  std::expected<void, std::string> open(bool gateway, bool chamber = true);
  int chamber_port() const { return listeners_.front().port; }
  int thermistor_port() const { return listeners_.back().port; }

  // Adds the listeners and clients to this round of the loop; returns when the next stalled
  // reply is due (time_point::max() for none).
  Clock::time_point watch(PollSet& set);
  // Sends the stalled replies due by `now`, then forgets closed clients. After each round.
  void after_round(Clock::time_point now);

  // Closes or reopens each listener as the refuse_modbus faults say.
  void update_listeners();
  // Closes the clients of `device`'s listener (every client when none).
  void drop_clients(std::optional<Device> device);
  std::size_t open_clients() const;
  void close();

 private:
  struct Listener {
    int port = 0;
    int fd = -1;
    std::vector<Device> devices;  // what it serves: the first answers unit id 255 too
  };
  struct Client {
    int fd = -1;
    std::size_t listener = 0;
    bool pending = false;  // a stalled reply waits: read no further request
    std::vector<std::uint8_t> query;
    int query_length = 0;
    Device device = Device::chamber;
    Clock::time_point due{};
  };

  std::expected<void, std::string> open_listener(Listener& l);
  bool refused(const Listener& l) const;  // with shared_.mutex held
  void accept(std::size_t listener);
  std::optional<Device> device_for_unit(const Listener& l, int unit_id) const;
  void close_client(Client& c, const char* why);
  void read_request(Client& c);
  void reply(Client& c, const std::uint8_t* query, int length, Device device);

  SharedState& shared_;
  Endpoints where_;
  std::vector<Listener> listeners_;
  std::vector<Client> clients_;
  modbus_t* ctx_ = nullptr;  // receives and replies on whichever client socket is set
};

}  // namespace fogbench::mock
