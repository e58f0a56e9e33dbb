// Clients for the web tests: raw HTTP over a TCP socket (so malformed requests can be sent as
// bytes) and a WebSocket client on Boost.Beast. Every wait has a deadline: an operation runs on
// its own io_context with run_for, and what has not finished by then is cancelled.
#pragma once

#include <utility>  // before Boost 1.74's asio (std::exchange)

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace fogbench::web_test {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using namespace std::chrono_literals;

// An HTTP exchange: the status (0: no answer), the headers and the body.
struct HttpReply {
  int status = 0;
  std::string head, body;
  bool closed = false;  // the server closed the connection after it
};

// Sends `bytes` to 127.0.0.1:port and reads one response (or until the deadline).
inline HttpReply http_raw(std::uint16_t port, const std::string& bytes, std::chrono::milliseconds timeout = 20s) {
  HttpReply r;
  asio::io_context io;
  beast::tcp_stream s(io);
  beast::error_code ec;
  s.socket().connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port), ec);
  if (ec) return r;
  beast::flat_buffer buf;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64u << 20);
  bool done = false;
  asio::async_write(s, asio::buffer(bytes), [&](beast::error_code e, std::size_t) {
    // A server may answer and close before it has read everything sent: read the reply anyway.
    (void)e;
    http::async_read(s, buf, parser, [&](beast::error_code e2, std::size_t) {
      done = true;
      if (e2) return;
      r.status = static_cast<int>(parser.get().result_int());
      for (const auto& f : parser.get()) r.head += std::string(f.name_string()) + ": " + std::string(f.value()) + "\n";
      r.body = parser.get().body();
      r.closed = !parser.get().keep_alive();
    });
  });
  io.run_for(timeout);
  if (!done) s.close();
  return r;
}

inline HttpReply http_get(std::uint16_t port, const std::string& target) {
  return http_raw(port, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
}
inline HttpReply http_post(std::uint16_t port, const std::string& target, const std::string& body) {
  return http_raw(port, "POST " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Type: application/json\r\n"
                        "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body);
}

// A WebSocket client: text messages in and out, each wait with a deadline.
class WsClient {
 public:
  WsClient(const std::string& host, std::uint16_t port, const std::string& path) : ws_(io_) {
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().connect(tcp::endpoint(asio::ip::make_address(host), port), ec);
    if (ec) return;
    bool done = false;
    ws_.async_handshake(host + ":" + std::to_string(port), path, [&](beast::error_code e) {
      done = true;
      ok_ = !e;
      if (e) error_ = e.message();
    });
    run(done, 30s);
  }
  bool ok() const { return ok_; }
  const std::string& error() const { return error_; }

  bool send(const std::string& text, bool binary = false) {
    if (!ok_) return false;
    ws_.text(!binary);
    beast::error_code ec;
    ws_.write(asio::buffer(text), ec);
    if (ec) ok_ = false;
    return !ec;
  }
  // The next message; nullopt on timeout or when the connection closed.
  std::optional<std::string> read(std::chrono::milliseconds timeout = 30s) {
    if (!ok_) return std::nullopt;
    beast::flat_buffer b;
    bool done = false;
    beast::error_code rec;
    ws_.async_read(b, [&](beast::error_code e, std::size_t) {
      rec = e;
      done = true;
    });
    if (!run(done, timeout) || rec) {
      ok_ = false;
      error_ = done ? rec.message() : "timeout";
      return std::nullopt;
    }
    return beast::buffers_to_string(b.data());
  }
  // Sends a request and reads until the message whose id matches (others are skipped).
  nlohmann::json call(nlohmann::json req, std::chrono::milliseconds timeout = 30s) {
    const auto id = next_id_++;
    req["id"] = id;
    if (!send(req.dump())) return nullptr;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      auto m = read(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()));
      if (!m) return nullptr;
      auto j = nlohmann::json::parse(*m, nullptr, false);
      if (j.is_object() && j.contains("id") && j["id"] == id) return j;
    }
    return nullptr;
  }

 private:
  bool run(bool& done, std::chrono::milliseconds timeout) {
    io_.restart();
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!done && std::chrono::steady_clock::now() < deadline) io_.run_one_for(deadline - std::chrono::steady_clock::now());
    if (!done) {
      beast::get_lowest_layer(ws_).socket().close();
      io_.restart();
      io_.run_for(1s);  // the cancelled operation completes
      ok_ = false;
      return false;
    }
    return true;
  }

  asio::io_context io_;
  websocket::stream<beast::tcp_stream> ws_;
  bool ok_ = false;
  std::string error_;
  std::int64_t next_id_ = 1;
};

}  // namespace fogbench::web_test
