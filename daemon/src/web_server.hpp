// fogbenchd's web side (an internal header of daemon/src/, used by server.cpp): one HTTP server
// on the daemon's io_context (Boost.Beast) that serves the live panel's embedded files, the
// Prometheus metrics, a WebSocket carrying the command protocol's lines (the same Handler as the
// command socket, read-only unless a request carries the control token) and POST /api for one
// request. docs/web.md.
#pragma once

#include <utility>  // before Boost 1.74's asio: its awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <cstdint>
#include <expected>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/handler.hpp"
#include "session.hpp"

namespace fogbench::daemon::web {

// Requests over these limits get 431 / 413 and the connection is closed.
constexpr std::size_t kMaxHeaderBytes = 8 * 1024;
constexpr std::size_t kMaxBodyBytes = 64 * 1024;
// A request must arrive whole within this (slow clients do not hold a connection), unless
// socket.first_request_timeout_s is shorter; an answer must be written within it.
constexpr auto kRequestDeadline = std::chrono::seconds(30);
// A connection refused (a listener's or an address's limit) gets this long to send the request
// its 503 answers.
constexpr auto kRefusedDeadline = std::chrono::seconds(5);

class WebServer {
 public:
  struct Hooks {
    // A place for a new HTTP connection from an address (admission.hpp: socket.max_clients with
    // TCP, socket.max_clients_per_address), held as long as the connection (and its WebSocket)
    // lives; or the reason it is refused: its request is then answered 503 with that reason.
    std::function<std::expected<std::shared_ptr<void>, std::string>(const std::string& address, const std::string& peer)> take;
    // Whether every network place is taken (admission.hpp): after a refusal the acceptor then
    // pauses net::kFullNetworkPause before its next accept.
    std::function<bool()> full;
    // Each request (its headers and body) must arrive within this after the connection opened
    // or the last answer went (keep-alive): slow or silent clients do not hold places.
    std::optional<double> first_request_timeout_s;
    // A WebSocket session to register for pushed messages and the connection count.
    std::function<void(const std::shared_ptr<net::SessionBase>&)> admit;
    // The Prometheus exposition (GET /metrics).
    std::function<std::string()> metrics;
  };
  WebServer(boost::asio::io_context& io, Handler& handler, WebConfig config, std::string control_token, Hooks hooks);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds web.listen; the error names the address.
  std::expected<void, std::string> bind();
  std::uint16_t port() const;  // the bound port (web.listen's port 0: the kernel's pick)
  void start();                // accepts
  void stop();                 // closes the acceptor and every HTTP connection
  // WebSocket connections open now, and HTTP requests answered since start.
  std::size_t open_websockets();
  std::uint64_t requests() const;
  // HTTP connections open now (not yet a WebSocket; refused ones not counted).
  std::size_t open_http() const;

  struct Impl;

 private:
  std::shared_ptr<Impl> impl_;
};

}  // namespace fogbench::daemon::web
