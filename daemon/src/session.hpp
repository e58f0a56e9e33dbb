// One client connection of fogbenchd's command socket (an internal header of daemon/src/, used by
// server.cpp): a session reads lines with the protocol's framing, has the Handler answer them
// one at a time, and queues the replies and pushed messages with bounds; Turns lets sessions
// take turns on the loop so no number of clients can hold it; `refuse` answers a client over
// the connection cap. Templates over the socket type (unix or TCP), hence a header.
#pragma once

#include <boost/asio.hpp>
#include <chrono>
#include <deque>
#include <list>
#include <memory>
#include <optional>
#include <string>

#include <spdlog/spdlog.h>

#include "fogbench/daemon/handler.hpp"
#include "fogbench/protocol/framing.hpp"

namespace fogbench::daemon::net {

namespace asio = boost::asio;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

// A write that does not finish in this long means the client stopped reading: it is dropped.
constexpr auto kWriteDeadline = std::chrono::seconds(10);
// A subscriber that falls this far behind is dropped rather than buffering without bound.
constexpr std::size_t kMaxQueuedBytes = 16u << 20;
// A connection with more than this queued for it is not served (its next request waits) until
// the client has read it down: a client that asks and does not read holds at most this plus one
// reply (a page of 10,000 samples is about 2 MB), never a growing queue.
constexpr std::size_t kOutputHighWaterBytes = 256u << 10;
// Requests answered per turn of the loop over all connections, one per connection in turn:
// between turns the loop runs the acquisition timer and whatever I/O is ready, so clients that
// pipeline requests cannot hold it however many they are (docs/daemon.md, "Threads").
constexpr int kLinesPerTurn = 16;
inline std::shared_ptr<const std::string> wire(const json& message) { return Handler::to_line(message); }

// A client refused (admission.hpp: a listener's limit, or its address's): one `busy` error line
// naming the reason and the configuration key, then the connection is closed. The line is
// small enough for an empty socket buffer; a deadline closes it anyway if the write hangs.
template <class Socket>
void refuse(Socket socket, const std::string& why) {
  auto sock = std::make_shared<Socket>(std::move(socket));
  auto line = wire(Handler::error(nullptr, ErrorCode::busy, why));
  auto deadline = std::make_shared<asio::steady_timer>(sock->get_executor(), std::chrono::seconds(2));
  deadline->async_wait([sock](boost::system::error_code ec) {
    if (!ec) sock->close(ec);
  });
  asio::async_write(*sock, asio::buffer(*line), [sock, line, deadline](boost::system::error_code, std::size_t) {
    boost::system::error_code ec;
    sock->shutdown(Socket::shutdown_both, ec);
    sock->close(ec);
    deadline->cancel();
  });
}

class SessionBase {
 public:
  virtual ~SessionBase() = default;
  virtual void push(const std::shared_ptr<const std::string>& line) = 0;
  virtual void close() = 0;
  virtual bool subscribed() const = 0;
  virtual bool is_closed() const = 0;
  // For Turns: serves the connection's next request if a whole one has arrived (true), else
  // starts reading (false).
  virtual bool serve_one() = 0;
  // Whether it may be served now: no reply outstanding (replies keep the requests' order), not
  // reading, and the client has read its output down to kOutputHighWaterBytes.
  virtual bool servable() const = 0;
  bool in_turns = false;  // queued in Turns
  // Its place under the connection limits (admission.hpp): given back when it closes.
  std::shared_ptr<void> ticket;
};

// The fair loop: connections with a request to serve take turns, one request each, at most
// kLinesPerTurn in all per turn; the next turn is posted behind what became ready meanwhile
// (the acquisition timer, reads and writes, the analysis worker's replies).
class Turns {
 public:
  explicit Turns(asio::io_context& io) : io_(io) {}

  // The session may have become servable (a read, a reply, a drained output).
  void want(const std::shared_ptr<SessionBase>& s) {
    if (s->in_turns || !s->servable()) return;
    s->in_turns = true;
    ready_.push_back(s);
    if (!posted_) {
      posted_ = true;
      asio::post(io_, [this] { turn(); });
    }
  }

 private:
  void turn() {
    posted_ = false;
    int served = 0;
    while (served < kLinesPerTurn && !ready_.empty()) {
      auto s = std::move(ready_.front());
      ready_.pop_front();
      s->in_turns = false;
      if (s->servable() && s->serve_one()) ++served;
      want(s);  // to the back of the line, if it has more
    }
  }

  asio::io_context& io_;
  // Held here while waiting for a turn: a session between its read and its turn has no
  // operation in flight that would keep it alive.
  std::deque<std::shared_ptr<SessionBase>> ready_;
  bool posted_ = false;
};

template <class Socket>
class Session : public SessionBase, public std::enable_shared_from_this<Session<Socket>> {
 public:
  Session(Socket socket, Handler& handler, Turns& turns, std::string peer, bool may_control,
          std::string control_token)
      : socket_(std::move(socket)), timer_(socket_.get_executor()), handler_(handler), turns_(turns),
        peer_(std::move(peer)) {
    state_.may_control = may_control;
    state_.control_token = std::move(control_token);
  }

  // Who is at the other end of a unix socket (SessionState::peer_user).
  void set_peer_user(std::string user) { state_.peer_user = std::move(user); }
  // A network client's address, without its port (SessionState::address).
  void set_address(std::string address) { state_.address = std::move(address); }

  void start() {
    send(wire(Handler::hello()));
    read();
    arm_idle();
    arm_first_request();
  }

  // socket.first_request_timeout_s (TCP): a connection that sends no whole request this long
  // after it was accepted is closed, so silent connections do not hold the listener's places.
  void set_first_request_timeout(std::optional<double> seconds) { first_request_s_ = seconds; }

  // socket.idle_timeout_s: a client that is not subscribed and neither sends a request nor waits
  // for a reply this long is closed. None when empty.
  void set_idle_timeout(std::optional<double> seconds) { idle_s_ = seconds; }

  void push(const std::shared_ptr<const std::string>& line) override {
    if (state_.subscribed) send(line);
  }
  bool subscribed() const override { return state_.subscribed; }
  bool is_closed() const override { return closed_; }

  void close() override {
    if (closed_) return;
    closed_ = true;
    boost::system::error_code ec;
    socket_.shutdown(Socket::shutdown_both, ec);
    socket_.close(ec);
    timer_.cancel();
    idle_timer_.cancel();
    first_timer_.cancel();
    ticket.reset();
  }

  bool servable() const override {
    return !closed_ && !reading_ && !awaiting_reply_ && !close_after_write_ &&
           queued_bytes_ <= kOutputHighWaterBytes;
  }

  // One request: its reply comes at once, or from the analysis worker later; either way the
  // next request of this connection waits for it. No more is read from the client while whole
  // requests of it are waiting.
  bool serve_one() override {
    std::string line;
    for (;;) {
      const auto st = splitter_.next(line);
      if (st == protocol::LineSplitter::Status::incomplete) {
        read();
        return false;
      }
      if (st == protocol::LineSplitter::Status::too_long) {
        spdlog::warn("client {}: line over {} bytes; closing", peer_, protocol::kMaxLineBytes);
        close_after_write_ = true;
        send(wire(Handler::too_long()));
        return true;
      }
      if (!line.empty()) break;
    }
    last_request_ = Clock::now();
    if (!got_request_) {
      got_request_ = true;
      first_timer_.cancel();
    }
    awaiting_reply_ = true;
    handler_.handle_line(line, state_, [self = this->shared_from_this()](Handler::Line reply) {
      self->awaiting_reply_ = false;
      self->send(std::move(reply));
      self->turns_.want(self);
    });
    return true;
  }

 private:
  void arm_first_request() {
    if (!first_request_s_ || closed_) return;
    first_timer_.expires_after(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(*first_request_s_)));
    first_timer_.async_wait([this, self = this->shared_from_this()](boost::system::error_code ec) {
      if (ec || closed_ || got_request_) return;
      // Debug only: a flood of silent connections must not flood the log (docs/reliability.md).
      spdlog::debug("client {}: no request within {} s (socket.first_request_timeout_s); closing", peer_,
                    *first_request_s_);
      close();
    });
  }

  void arm_idle() {
    if (!idle_s_ || closed_) return;
    const auto idle = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(*idle_s_));
    idle_timer_.expires_at(last_request_ + idle);
    idle_timer_.async_wait([this, self = this->shared_from_this(), idle](boost::system::error_code ec) {
      if (ec || closed_) return;
      if (!state_.subscribed && !awaiting_reply_ && queue_.empty() && Clock::now() - last_request_ >= idle) {
        spdlog::info("client {}: idle for {} s; closing", peer_, *idle_s_);
        close();
        return;
      }
      if (state_.subscribed || awaiting_reply_ || !queue_.empty()) last_request_ = Clock::now();
      arm_idle();
    });
  }

  void read() {
    if (reading_ || closed_) return;
    reading_ = true;
    auto self = this->shared_from_this();
    socket_.async_read_some(asio::buffer(buf_), [this, self](boost::system::error_code ec, std::size_t n) {
      reading_ = false;
      if (ec == asio::error::eof && !closed_ && !queue_.empty()) {
        close_after_write_ = true;  // the client has said all: it gets its replies, then the end
        return;
      }
      if (ec || closed_) {
        close();
        return;
      }
      splitter_.feed(std::string_view(buf_.data(), n));
      turns_.want(self);
    });
  }

  void send(std::shared_ptr<const std::string> line) {
    if (closed_) return;
    queued_bytes_ += line->size();
    if (queued_bytes_ > kMaxQueuedBytes) {
      spdlog::warn("client {}: {} bytes unread; dropping it", peer_, queued_bytes_);
      close();
      return;
    }
    queue_.push_back(std::move(line));
    if (queue_.size() == 1) write();
  }

  void write() {
    auto self = this->shared_from_this();
    timer_.expires_after(kWriteDeadline);
    timer_.async_wait([this, self](boost::system::error_code ec) {
      if (!ec) {
        spdlog::warn("client {}: write deadline passed; closing", peer_);
        close();
      }
    });
    asio::async_write(socket_, asio::buffer(*queue_.front()),
                      [this, self](boost::system::error_code ec, std::size_t) {
                        timer_.cancel();
                        if (ec || closed_) {
                          close();
                          return;
                        }
                        queued_bytes_ -= queue_.front()->size();
                        queue_.pop_front();
                        if (!queue_.empty()) write();
                        else if (close_after_write_) close();
                        turns_.want(self);  // read down below the high water: served again
                      });
  }

  Socket socket_;
  asio::steady_timer timer_;
  Handler& handler_;
  Turns& turns_;
  std::string peer_;
  SessionState state_;
  protocol::LineSplitter splitter_;
  std::array<char, 65536> buf_{};
  std::deque<std::shared_ptr<const std::string>> queue_;
  std::size_t queued_bytes_ = 0;
  bool closed_ = false;
  bool close_after_write_ = false;
  bool reading_ = false;
  bool awaiting_reply_ = false;
  asio::steady_timer idle_timer_{socket_.get_executor()};
  std::optional<double> idle_s_;
  asio::steady_timer first_timer_{socket_.get_executor()};
  std::optional<double> first_request_s_;
  bool got_request_ = false;
  Clock::time_point last_request_ = Clock::now();
};

// The live connections of every transport (the unix and TCP sockets' sessions, the web side's
// WebSockets), as Asio's connection manager: the server adds each new session, publishes to all,
// counts the open ones and closes them all on the way out. It holds them weakly: a session lives
// as long as its own reads and writes.
class SessionSet {
 public:
  void add(const std::shared_ptr<SessionBase>& s) {
    drop_expired();
    sessions_.push_back(s);
  }
  // Connections open now.
  std::size_t open() {
    sessions_.remove_if([](const auto& w) {
      auto s = w.lock();
      return !s || s->is_closed();
    });
    return sessions_.size();
  }
  // One line to every session (each decides by its subscription whether to send it).
  void publish(const std::shared_ptr<const std::string>& line) {
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      if (auto s = it->lock()) {
        s->push(line);
        ++it;
      } else {
        it = sessions_.erase(it);
      }
    }
  }
  void close_all() {
    for (auto& w : sessions_)
      if (auto s = w.lock()) s->close();
    sessions_.clear();
  }

 private:
  void drop_expired() {
    sessions_.remove_if([](const auto& w) { return w.expired(); });
  }
  std::list<std::weak_ptr<SessionBase>> sessions_;
};

}  // namespace fogbench::daemon::net
