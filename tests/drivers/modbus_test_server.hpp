// A libmodbus TCP server on 127.0.0.1 (ephemeral port) run in a thread, for testing the drivers'
// real libmodbus clients end to end. Serves one client at a time, accepts again after a client
// leaves, and stops by shutting its sockets down (modbus_receive blocks without a timeout).
#pragma once

#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <thread>

class ModbusTestServer {
 public:
  ModbusTestServer(int bits, int input_bits, int registers, int input_registers) {
    ctx_ = modbus_new_tcp("127.0.0.1", 0);  // port 0: the kernel picks a free one
    mapping_ = modbus_mapping_new(bits, input_bits, registers, input_registers);
    if (ctx_ == nullptr || mapping_ == nullptr) throw std::runtime_error("libmodbus allocation");
    listen_fd_ = modbus_tcp_listen(ctx_, 1);
    if (listen_fd_ < 0) throw std::runtime_error("modbus_tcp_listen");
    sockaddr_in addr{};
    socklen_t len = sizeof addr;
    ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] { serve(); });
  }

  ~ModbusTestServer() {
    stop();
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
  }

  std::uint16_t port() const { return port_; }

  // Reads or changes the served data while no request is being answered.
  template <class F>
  void with_mapping(F&& f) {
    std::lock_guard lock(mutex_);
    f(*mapping_);
  }

  // Closes the listening socket and the current client: afterwards connects are refused.
  void stop() {
    if (stopping_.exchange(true)) return;
    ::shutdown(listen_fd_, SHUT_RDWR);
    {
      std::lock_guard lock(client_mutex_);
      if (client_fd_ >= 0) ::shutdown(client_fd_, SHUT_RDWR);
    }
    thread_.join();
    ::close(listen_fd_);
  }

 private:
  void serve() {
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stopping_) {
      const int s = ::accept(listen_fd_, nullptr, nullptr);
      if (s < 0) break;
      {
        std::lock_guard lock(client_mutex_);
        client_fd_ = s;
      }
      if (!stopping_) {
        modbus_set_socket(ctx_, s);
        for (;;) {
          const int rc = modbus_receive(ctx_, query);
          if (rc == -1) break;  // the client closed, or stop() shut the socket down
          if (rc == 0) continue;  // a request for another unit id: ignored
          std::lock_guard lock(mutex_);
          modbus_reply(ctx_, query, rc, mapping_);
        }
      }
      {
        std::lock_guard lock(client_mutex_);
        client_fd_ = -1;
      }
      ::close(s);
    }
  }

  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  std::uint16_t port_ = 0;
  std::thread thread_;
  std::mutex mutex_;
  std::mutex client_mutex_;
  int client_fd_ = -1;
  std::atomic<bool> stopping_{false};
};
