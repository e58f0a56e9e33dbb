// Who may open a connection to fogbenchd (an internal header of daemon/src/, used by server.cpp
// and web_server.cpp; docs/reliability.md, "Connection limits"). Each listener has its own
// limit, so that the network cannot lock the operators out of the unix socket:
// - the unix socket: socket.unix_max_clients, its own share, never taken by TCP or web clients;
// - TCP and the web side (HTTP and WebSocket connections) together: socket.max_clients, as
//   before for those two (the unix socket is no longer counted in it);
// - one remote address over TCP and the web together: socket.max_clients_per_address.
// A connection admitted holds a Ticket; its place is free again when the ticket goes (the
// connection's close or end). Refusals are counted by RefusalLog, which says what to log: the
// first refusal of a quiet spell, then one line per interval with the count. No I/O here, no
// clock read: both are tested without a daemon (tests/daemon/admission_test.cpp).
#pragma once

#include <chrono>
#include <cstddef>
#include <expected>
#include <map>
#include <memory>
#include <optional>
#include <string>

namespace fogbench::daemon::net {

enum class Listener { unix_socket, tcp, web };

inline const char* to_string(Listener l) {
  switch (l) {
    case Listener::unix_socket: return "unix";
    case Listener::tcp: return "tcp";
    case Listener::web: return "web";
  }
  return "?";
}

// The acceptors' pause after a refusal while every network place is taken: at most 50 refusals
// a second per listener, each connection opened meanwhile waiting in the kernel's backlog
// (docs/reliability.md "Connection limits"; measured by bench_daemon_listeners).
inline constexpr std::chrono::milliseconds kFullNetworkPause{20};

struct AdmissionLimits {
  std::size_t unix_max = 64;          // socket.unix_max_clients
  std::size_t network_max = 256;      // socket.max_clients: TCP and web together
  std::size_t per_address_max = 32;   // socket.max_clients_per_address: TCP and web together
};

class Admission {
 public:
  // A place taken; given back when the last copy goes.
  using Ticket = std::shared_ptr<void>;

  explicit Admission(AdmissionLimits limits) : state_(std::make_shared<State>()) { state_->limits = limits; }

  // A place for a new connection on `listener` from `address` (an IP address; ignored for the
  // unix socket), or why not: the line the client is told ("too many ...; closing" naming the
  // configuration key).
  std::expected<Ticket, std::string> admit(Listener listener, const std::string& address) {
    State& s = *state_;
    if (listener == Listener::unix_socket) {
      if (s.unix_open >= s.limits.unix_max)
        return std::unexpected("too many clients on the unix socket (" + std::to_string(s.unix_open) +
                               " connected, socket.unix_max_clients); closing");
      ++s.unix_open;
      return Ticket(nullptr, [st = state_](void*) { --st->unix_open; });
    }
    if (s.network_open >= s.limits.network_max)
      return std::unexpected("too many network clients (" + std::to_string(s.network_open) +
                             " connected over TCP and the web, socket.max_clients); closing");
    std::size_t& mine = s.per_address[address];
    if (mine >= s.limits.per_address_max)
      return std::unexpected("too many connections from " + address + " (" + std::to_string(mine) +
                             " connected, socket.max_clients_per_address); closing");
    ++mine;
    ++s.network_open;
    ++(listener == Listener::tcp ? s.tcp_open : s.web_open);
    return Ticket(nullptr, [st = state_, address, listener](void*) {
      --st->network_open;
      --(listener == Listener::tcp ? st->tcp_open : st->web_open);
      if (auto it = st->per_address.find(address); it != st->per_address.end() && --it->second == 0)
        st->per_address.erase(it);
    });
  }

  std::size_t unix_open() const { return state_->unix_open; }
  std::size_t tcp_open() const { return state_->tcp_open; }
  std::size_t web_open() const { return state_->web_open; }
  std::size_t from(const std::string& address) const {
    auto it = state_->per_address.find(address);
    return it == state_->per_address.end() ? 0 : it->second;
  }
  const AdmissionLimits& limits() const { return state_->limits; }
  // Every network place taken (socket.max_clients): a TCP or web connection now is refused
  // whoever opens it. The acceptors then pause kFullNetworkPause before the next accept, so that
  // a flood of reconnections is refused at a bounded rate instead of taking the loop (an
  // address's own limit does not pause them: the others' connections must keep coming in).
  bool network_full() const { return state_->network_open >= state_->limits.network_max; }
  // A configuration reload: new connections are admitted by these; the open ones stay.
  void set_limits(AdmissionLimits limits) { state_->limits = limits; }

 private:
  // Shared with the tickets: a connection may outlive the server's own members on the way out.
  struct State {
    AdmissionLimits limits;
    std::size_t unix_open = 0, tcp_open = 0, web_open = 0, network_open = 0;
    std::map<std::string, std::size_t> per_address;
  };
  std::shared_ptr<State> state_;
};

// Refusals in the log at most once per interval: the first of a quiet spell in full, the others
// counted and reported by flush() at the interval's end, one line with the count per listener.
// 20,000 refusals a minute are two lines, not 20,000.
class RefusalLog {
 public:
  using Clock = std::chrono::steady_clock;
  explicit RefusalLog(Clock::duration every) : every_(every) {}
  // A configuration reload: the next interval is this long.
  void set_interval(Clock::duration every) { every_ = every; }

  // A refusal at `now`: the line to log now, if any. When a line is returned and no flush is
  // pending, the caller arms one at flush_due().
  std::optional<std::string> refused(Listener l, const std::string& peer, const std::string& why, Clock::time_point now) {
    if (!window_ || now - *window_ >= every_) {
      window_ = now;
      return std::string("client ") + peer + " (" + to_string(l) + ") refused: " + why +
             "; further refusals are counted and reported every " + seconds_text() + " s";
    }
    ++counts_[static_cast<int>(l)];
    last_ = why;
    return std::nullopt;
  }

  // When the interval started by the last line ends (none without a window).
  std::optional<Clock::time_point> flush_due() const {
    if (!window_) return std::nullopt;
    return *window_ + every_;
  }

  // The interval's end: a line with the count when there were refusals (a new interval starts,
  // so a steady stream is one line per interval), else nothing (the next refusal is logged in
  // full).
  std::optional<std::string> flush(Clock::time_point now) {
    const std::size_t n = counts_[0] + counts_[1] + counts_[2];
    if (n == 0) {
      window_.reset();
      return std::nullopt;
    }
    std::string line = std::to_string(n) + " more connections refused in the last " + seconds_text() +
                       " s (unix " + std::to_string(counts_[0]) + ", tcp " + std::to_string(counts_[1]) +
                       ", web " + std::to_string(counts_[2]) + "; the last: " + last_ + ")";
    counts_[0] = counts_[1] = counts_[2] = 0;
    window_ = now;
    return line;
  }

 private:
  std::string seconds_text() const {
    const double s = std::chrono::duration<double>(every_).count();
    std::string t = std::to_string(s);
    t.erase(t.find_last_not_of('0') + 1);
    if (!t.empty() && t.back() == '.') t.pop_back();
    return t;
  }

  Clock::duration every_;
  std::optional<Clock::time_point> window_;
  std::size_t counts_[3] = {0, 0, 0};
  std::string last_;
};

}  // namespace fogbench::daemon::net
