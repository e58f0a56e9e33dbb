// fogbenchd's HTTP and WebSocket server (web_server.hpp, docs/web.md). Rooms: HttpSession reads
// one request at a time with Beast's parser (limits on headers and body, a deadline) and routes
// it; WsSession is a protocol session over a WebSocket: each text message is one request line for
// the same Handler the command socket uses, its replies and the pushed `sample`/`event` lines go
// back as text messages. Everything runs on the daemon's loop thread.
#include "web_server.hpp"
#include "admission.hpp"

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <deque>
#include <list>

#include <spdlog/spdlog.h>

#include "fogbench/protocol/framing.hpp"
#include "web_assets.hpp"

namespace fogbench::daemon::web {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;

struct WebServer::Impl : std::enable_shared_from_this<WebServer::Impl> {
  asio::io_context& io;
  Handler& handler;
  WebConfig config;
  std::string control_token;
  Hooks hooks;
  std::optional<tcp::acceptor> acceptor;
  std::list<std::weak_ptr<net::SessionBase>> websockets;
  std::uint64_t requests = 0;
  // HTTP connections open (a WebSocket's until its upgrade; then it is a session), counted
  // against socket.max_clients with the sockets' sessions. Refused ones are not counted.
  std::size_t http_open = 0;
  bool stopped = false;

  Impl(asio::io_context& i, Handler& h, WebConfig c, std::string t, Hooks k)
      : io(i), handler(h), config(std::move(c)), control_token(std::move(t)), hooks(std::move(k)) {}

  void accept();
  // The HTTP connections open, each with how to close it (on stop).
  std::list<std::pair<std::weak_ptr<void>, std::function<void()>>> closers;
};

namespace {

// A peer "ADDRESS:PORT" without its port (IPv6 addresses keep their colons).
std::string address_of(const std::string& peer) {
  const auto colon = peer.rfind(':');
  return colon == std::string::npos ? peer : peer.substr(0, colon);
}

// A WebSocket carrying the command protocol: one JSON request per text message, one reply per
// request (in order: the next message is read once the reply is queued), pushed messages after
// `subscribe`. Bounded like the socket's sessions: a client that stops reading is dropped.
class WsSession : public net::SessionBase, public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, Handler& handler, std::string peer, std::string control_token)
      : ws_(std::move(socket)), timer_(ws_.get_executor()), handler_(handler), peer_(std::move(peer)) {
    state_.may_control = false;
    state_.control_token = std::move(control_token);
    state_.address = address_of(peer_);
  }

  void start(http::request<http::string_body> req) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& res) {
      res.set(http::field::server, std::string("fogbenchd/") + FOGBENCH_DAEMON_VERSION);
    }));
    ws_.read_message_max(protocol::kMaxLineBytes);
    ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
      if (ec) {
        spdlog::info("web client {}: WebSocket handshake failed: {}", self->peer_, ec.message());
        return self->close();
      }
      self->send(net::wire(Handler::hello()));
      self->read();
    });
  }

  void push(const std::shared_ptr<const std::string>& line) override {
    if (state_.subscribed) send(line);
  }
  void close() override {
    if (closed_) return;
    closed_ = true;
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(ws_).socket().close(ec);
    timer_.cancel();
    ticket.reset();
  }
  bool subscribed() const override { return state_.subscribed; }
  bool is_closed() const override { return closed_; }
  // Served from its own reads, never through the socket's Turns.
  bool serve_one() override { return false; }
  bool servable() const override { return false; }

 private:
  void read() {
    if (closed_) return;
    ws_.async_read(buf_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        if (ec == websocket::error::message_too_big)
          spdlog::warn("web client {}: message over {} bytes; closing", self->peer_, protocol::kMaxLineBytes);
        return self->close();
      }
      std::string line = beast::buffers_to_string(self->buf_.data());
      self->buf_.consume(self->buf_.size());
      if (!self->ws_.got_text()) {
        self->send(net::wire(Handler::error(nullptr, ErrorCode::bad_request,
                                            "binary message: the panel's protocol is JSON text, one request per message")));
        return self->read();
      }
      self->handler_.handle_line(line, self->state_, [self](Handler::Line reply) {
        self->send(std::move(reply));
        self->read();
      });
    });
  }

  void send(std::shared_ptr<const std::string> line) {
    if (closed_) return;
    queued_bytes_ += line->size();
    if (queued_bytes_ > net::kMaxQueuedBytes) {
      spdlog::warn("web client {}: {} bytes unread; dropping it", peer_, queued_bytes_);
      return close();
    }
    queue_.push_back(std::move(line));
    if (queue_.size() == 1) write();
  }

  void write() {
    auto self = shared_from_this();
    timer_.expires_after(net::kWriteDeadline);
    timer_.async_wait([self](boost::system::error_code ec) {
      if (!ec) {
        spdlog::warn("web client {}: write deadline passed; closing", self->peer_);
        self->close();
      }
    });
    const auto& l = *queue_.front();
    // The protocol's line without its newline: one message is one JSON object.
    const std::size_t n = !l.empty() && l.back() == '\n' ? l.size() - 1 : l.size();
    ws_.text(true);
    ws_.async_write(asio::buffer(l.data(), n), [self](beast::error_code ec, std::size_t) {
      self->timer_.cancel();
      if (ec || self->closed_) return self->close();
      self->queued_bytes_ -= self->queue_.front()->size();
      self->queue_.pop_front();
      if (!self->queue_.empty()) self->write();
    });
  }

  websocket::stream<beast::tcp_stream> ws_;
  asio::steady_timer timer_;
  Handler& handler_;
  std::string peer_;
  SessionState state_;
  beast::flat_buffer buf_;
  std::deque<std::shared_ptr<const std::string>> queue_;
  std::size_t queued_bytes_ = 0;
  bool closed_ = false;
};

// The reply's HTTP status for POST /api: the protocol's error code says what went wrong.
http::status status_of(const std::string& reply) {
  if (reply.size() > 65536) return http::status::ok;  // errors are small; a large reply is a result
  const json j = json::parse(reply, nullptr, false);
  if (!j.is_object() || !j.contains("error") || !j["error"].is_object()) return http::status::ok;
  const std::string code = j["error"].value("code", "");
  if (code == "forbidden") return http::status::forbidden;
  if (code == "bad_json" || code == "bad_request" || code == "unknown_command" || code == "invalid_profile" ||
      code == "limits" || code == "unknown_serial" || code == "invalid_config")
    return http::status::bad_request;
  if (code == "not_found") return http::status::not_found;
  if (code == "busy") return http::status::conflict;
  if (code == "unavailable") return http::status::service_unavailable;
  return http::status::internal_server_error;
}

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  // `refused`: why the connection is refused (a listener's or an address's limit), empty when
  // admitted; a refused one's request is read and answered 503 with the reason.
  HttpSession(tcp::socket socket, std::shared_ptr<WebServer::Impl> server, std::string peer, std::shared_ptr<void> ticket,
              std::string refused)
      : stream_(std::move(socket)), server_(std::move(server)), peer_(std::move(peer)), ticket_(std::move(ticket)),
        why_refused_(std::move(refused)), refused_(!why_refused_.empty()) {
    if (why_refused_.ends_with("; closing")) why_refused_.resize(why_refused_.size() - 9);
    if (!refused_) ++server_->http_open;
    if (server_->hooks.first_request_timeout_s)
      read_deadline_ = std::min<std::chrono::steady_clock::duration>(
          kRequestDeadline, std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(*server_->hooks.first_request_timeout_s)));
  }
  ~HttpSession() {
    if (!refused_) --server_->http_open;
  }
  HttpSession(const HttpSession&) = delete;
  HttpSession& operator=(const HttpSession&) = delete;

  void start() { read(); }
  void close() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ec);
    stream_.close();
    ticket_.reset();
  }

 private:
  void read() {
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(kMaxHeaderBytes));
    parser_->body_limit(kMaxBodyBytes);
    stream_.expires_after(refused_ ? kRefusedDeadline : read_deadline_);
    http::async_read(stream_, buf_, *parser_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->on_read(ec);
    });
  }

  void on_read(beast::error_code ec) {
    if (ec == http::error::end_of_stream || ec == asio::error::eof || ec == beast::error::timeout ||
        ec == asio::error::operation_aborted || ec == asio::error::connection_reset)
      return close();
    if (ec == http::error::header_limit)
      return error(http::status::request_header_fields_too_large,
                   "request headers over " + std::to_string(kMaxHeaderBytes) + " bytes", 11, true);
    if (ec == http::error::body_limit)
      return error(http::status::payload_too_large, "request body over " + std::to_string(kMaxBodyBytes) + " bytes",
                   11, true);
    if (ec) {
      if (ec.category() == beast::error_code(http::error::bad_method).category())
        return error(http::status::bad_request, "bad HTTP request: " + ec.message(), 11, true);
      return close();
    }
    ++server_->requests;
    if (refused_)
      return error(http::status::service_unavailable, why_refused_ + "; retry later", 11, true);
    route(parser_->release());
  }

  void route(http::request<http::string_body> req) {
    std::string path(req.target());
    if (const auto q = path.find('?'); q != std::string::npos) path.resize(q);
    const auto method = req.method();
    if (path == "/ws") {
      if (!websocket::is_upgrade(req))
        return error(http::status::upgrade_required, "/ws is a WebSocket: connect with an Upgrade request",
                     req.version(), !req.keep_alive());
      // A page of another site may not open the panel's WebSocket in the operator's browser
      // (cross-site WebSocket hijacking: reads need no token), nor one of a site that rebinds its
      // own name to this address (DNS rebinding: Host and Origin then agree, on the wrong name).
      if (!allowed(req)) return;
      // This connection was counted against socket.max_clients when it was accepted: as a
      // WebSocket it is counted as a session instead.
      auto ws = std::make_shared<WsSession>(stream_.release_socket(), server_->handler, peer_, server_->control_token);
      ws->ticket = std::move(ticket_);
      if (server_->hooks.admit) server_->hooks.admit(ws);
      server_->websockets.remove_if([](const auto& w) { return w.expired(); });
      server_->websockets.push_back(ws);
      ws->start(std::move(req));
      return;
    }
    if (path == "/metrics") {
      if (method != http::verb::get) return not_allowed(req, "GET");
      if (!allowed(req)) return;
      return respond(req, http::status::ok, "text/plain; version=0.0.4; charset=utf-8",
                     server_->hooks.metrics ? server_->hooks.metrics() : std::string());
    }
    if (path == "/api") {
      if (method != http::verb::post) return not_allowed(req, "POST");
      if (!allowed(req)) return;
      auto state = std::make_shared<SessionState>();
      state->may_control = false;
      state->control_token = server_->control_token;
      state->address = address_of(peer_);
      auto self = shared_from_this();
      auto r = std::make_shared<http::request<http::string_body>>(std::move(req));
      server_->handler.handle_line(r->body(), *state, [self, state, r](Handler::Line reply) {
        self->respond(*r, status_of(*reply), "application/json", *reply);
      });
      return;
    }
    if (const Asset* a = find_asset(path == "/" ? "/index.html" : path)) {
      if (method != http::verb::get && method != http::verb::head) return not_allowed(req, "GET, HEAD");
      return respond(req, http::status::ok, std::string(a->content_type), std::string(a->body));
    }
    error(http::status::not_found, "no such path: " + path + " (the panel is at /, metrics at /metrics)",
          req.version(), !req.keep_alive());
  }

  // Whether the request may reach the bench's data (/ws, /api, /metrics): its Host names this
  // panel (an address, localhost or web.hosts) and its Origin, when a browser sent one, is that
  // Host. Answers 403 itself when not.
  bool allowed(const http::request<http::string_body>& req) {
    const std::string host(req[http::field::host]), origin(req[http::field::origin]);
    if (!web_host_allowed(server_->config, host)) {
      spdlog::warn("web client {}: request for host {} refused (not an address, localhost or web.hosts)", peer_, host);
      error(http::status::forbidden,
            "Host " + host + " is not a name of this panel (an IP address, localhost or one of web.hosts)",
            req.version(), true);
      return false;
    }
    if (!web_origin_allowed(server_->config, origin, host)) {
      spdlog::warn("web client {}: request from origin {} refused (host {})", peer_, origin, host);
      error(http::status::forbidden,
            std::string(req.target().starts_with("/ws") ? "WebSocket" : "request") + " from another origin (" + origin +
                ") refused",
            req.version(), true);
      return false;
    }
    return true;
  }

  void not_allowed(const http::request<http::string_body>& req, const char* allow) {
    auto res = make(http::status::method_not_allowed, "text/plain; charset=utf-8",
                    std::string(req.method_string()) + " is not allowed here (allowed: " + allow + ")\n", req.version(),
                    !req.keep_alive());
    res->set(http::field::allow, allow);
    send(std::move(res));
  }

  void error(http::status s, const std::string& message, unsigned version, bool close_after) {
    spdlog::debug("web client {}: {} {}", peer_, static_cast<int>(s), message);
    send(make(s, "text/plain; charset=utf-8", message + "\n", version, close_after));
  }

  void respond(const http::request<http::string_body>& req, http::status s, const std::string& type, std::string body) {
    auto res = make(s, type, std::move(body), req.version(), !req.keep_alive());
    if (req.method() == http::verb::head) {
      const auto n = res->body().size();
      res->body().clear();
      res->content_length(n);
    }
    send(std::move(res));
  }

  static std::shared_ptr<http::response<http::string_body>> make(http::status s, const std::string& type,
                                                                 std::string body, unsigned version, bool close_after) {
    auto res = std::make_shared<http::response<http::string_body>>(s, version);
    res->set(http::field::server, std::string("fogbenchd/") + FOGBENCH_DAEMON_VERSION);
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-store");
    res->set("X-Content-Type-Options", "nosniff");
    res->set("Content-Security-Policy",
             "default-src 'self'; connect-src 'self' ws: wss:; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
             "frame-ancestors 'none'");
    res->keep_alive(!close_after);
    res->body() = std::move(body);
    res->prepare_payload();
    return res;
  }

  void send(std::shared_ptr<http::response<http::string_body>> res) {
    const bool close_after = !res->keep_alive();
    stream_.expires_after(kRequestDeadline);
    http::async_write(stream_, *res, [self = shared_from_this(), res, close_after](beast::error_code ec, std::size_t) {
      if (ec || close_after) return self->close();
      self->read();
    });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buf_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<WebServer::Impl> server_;
  std::string peer_;
  std::shared_ptr<void> ticket_;  // its place under the limits; the WebSocket's after an upgrade
  std::string why_refused_;
  bool refused_ = false;
  std::chrono::steady_clock::duration read_deadline_ = kRequestDeadline;
};

}  // namespace

void WebServer::Impl::accept() {
  acceptor->async_accept([self = shared_from_this()](boost::system::error_code ec, tcp::socket s) {
    if (self->stopped || ec == asio::error::operation_aborted) return;
    if (ec) {
      // Out of descriptors: wait a little rather than spin (as the command socket does).
      spdlog::warn("web accept: {}", ec.message());
      auto t = std::make_shared<asio::steady_timer>(self->io, std::chrono::milliseconds(250));
      t->async_wait([self, t](boost::system::error_code) {
        if (!self->stopped) self->accept();
      });
      return;
    }
    boost::system::error_code e2;
    const auto ep = s.remote_endpoint(e2);
    std::string peer = e2 ? std::string("web") : ep.address().to_string() + ":" + std::to_string(ep.port());
    // Past socket.max_clients (TCP and the web together) or the address's limit: the request is
    // answered 503 with the reason and the connection closed (the server logs refusals, counted).
    std::shared_ptr<void> ticket;
    std::string refused;
    if (self->hooks.take) {
      auto t = self->hooks.take(e2 ? std::string("?") : ep.address().to_string(), peer);
      if (t) ticket = std::move(*t);
      else refused = t.error();
    }
    auto h = std::make_shared<HttpSession>(std::move(s), self, std::move(peer), std::move(ticket), std::move(refused));
    self->closers.remove_if([](const auto& p) { return p.first.expired(); });
    self->closers.emplace_back(h, [w = std::weak_ptr<HttpSession>(h)] {
      if (auto x = w.lock()) x->close();
    });
    h->start();
    if (refused.empty() || !self->hooks.full || !self->hooks.full()) return self->accept();
    auto t = std::make_shared<asio::steady_timer>(self->io, net::kFullNetworkPause);
    t->async_wait([self, t](boost::system::error_code) {
      if (!self->stopped) self->accept();
    });
  });
}

WebServer::WebServer(asio::io_context& io, Handler& handler, WebConfig config, std::string control_token, Hooks hooks)
    : impl_(std::make_shared<Impl>(io, handler, std::move(config), std::move(control_token), std::move(hooks))) {}

WebServer::~WebServer() {
  stop();
  impl_->acceptor.reset();  // before the io_context goes, whoever holds the Impl last
}

std::expected<void, std::string> WebServer::bind() {
  const std::string where = impl_->config.address + ":" + std::to_string(impl_->config.port);
  try {
    impl_->acceptor.emplace(impl_->io);
    const tcp::endpoint ep(asio::ip::make_address(impl_->config.address), impl_->config.port);
    impl_->acceptor->open(ep.protocol());
    impl_->acceptor->set_option(asio::socket_base::reuse_address(true));
    impl_->acceptor->bind(ep);
    impl_->acceptor->listen();
  } catch (const boost::system::system_error& e) {
    impl_->acceptor.reset();
    return std::unexpected("web.listen " + where + ": " + e.what());
  }
  return {};
}

std::uint16_t WebServer::port() const {
  boost::system::error_code ec;
  return impl_->acceptor ? impl_->acceptor->local_endpoint(ec).port() : 0;
}

void WebServer::start() {
  if (impl_->acceptor) impl_->accept();
}

void WebServer::stop() {
  if (impl_->stopped) return;
  impl_->stopped = true;
  boost::system::error_code ec;
  if (impl_->acceptor) impl_->acceptor->close(ec);
  for (auto& [w, close] : impl_->closers)
    if (!w.expired()) close();
  impl_->closers.clear();
  for (auto& w : impl_->websockets)
    if (auto s = w.lock()) s->close();
}

std::size_t WebServer::open_websockets() {
  impl_->websockets.remove_if([](const auto& w) {
    auto s = w.lock();
    return !s || s->is_closed();
  });
  return impl_->websockets.size();
}

std::uint64_t WebServer::requests() const { return impl_->requests; }

std::size_t WebServer::open_http() const { return impl_->http_open; }

}  // namespace fogbench::daemon::web
