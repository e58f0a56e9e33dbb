// A listener that answers a line protocol, on the bench's poll() loop: the ASCII chamber
// dialects (ascii_chamber.hpp) and the rate table (rate_table.hpp) serve through it on TCP, the
// control socket (control.hpp) on a unix stream socket. It accepts clients, cuts what they send
// into lines (a CR or an LF ends one, or only an LF where asked; a CR before the LF is dropped;
// empty lines are passed over), hands each line to the peer's answer and writes the reply back,
// at once or after the stall the answer asks for (in order behind any reply still held). What a
// client does not take at once waits for it (POLLOUT); a client that leaves more than
// max_unsent_bytes unread, sends more than max_line_bytes without a line end (told the
// overflow reply first, where there is one), or whose socket fails, is closed. The faults'
// plumbing stays the peer's: it closes the listener (refuse), the clients (drop), or stalls a
// reply.
#pragma once

#include <chrono>
#include <expected>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "poll_set.hpp"

namespace fogbench::mock {

class LineServer {
 public:
  using Clock = std::chrono::steady_clock;

  // The reply to one line (with its line end), and how long to hold it back, ms.
  struct Reply {
    std::string text;
    int stall_ms = 0;
  };
  // One line (its line end stripped, never empty) in, its reply out; called on the loop.
  using Answer = std::function<Reply(const std::string& line)>;

  static constexpr std::size_t max_line_bytes = 4096;
  static constexpr std::size_t max_unsent_bytes = 1 << 20;

  // A unix stream socket's path, for the second constructor.
  struct UnixPath {
    std::string path;
  };
  struct Options {
    bool lf_only = false;        // only an LF ends a line (the control socket's JSON lines)
    std::string overflow_reply;  // said to a client before closing it for a too long line
  };

  // `name` names the peer in the log and in the listener's errors ("chamber", "rate table").
  LineServer(std::string name, std::string host, int port, Answer answer)
      : name_(std::move(name)), host_(std::move(host)), port_(port), answer_(std::move(answer)) {}
  // On a unix stream socket at `where` (a stale socket file replaced, the file removed by
  // close()); refuse() is for TCP listeners only.
  LineServer(std::string name, UnixPath where, Answer answer, Options options)
      : name_(std::move(name)), port_(0), unix_path_(std::move(where.path)), answer_(std::move(answer)),
        options_(std::move(options)) {}
  ~LineServer() { close(); }
  LineServer(const LineServer&) = delete;
  LineServer& operator=(const LineServer&) = delete;

  // Port 0 becomes an ephemeral one, read back with port() (and kept, so a listener closed by
  // refuse() reopens on the same port).
  std::expected<void, std::string> open();
  int port() const { return port_; }
  // refuse: the listener closed (new connections refused), the clients kept; off: reopened.
  void refuse(bool on);
  // Adds the listener and the clients to `set`; returns when the first held reply is due.
  Clock::time_point watch(PollSet& set);
  // Writes the held replies due by `now`, then forgets the closed clients.
  void after_round(Clock::time_point now);
  // Tries once more to write what the clients have not taken (before close(), on the way out).
  void flush();
  void drop_clients();
  std::size_t open_clients() const;
  void close();

 private:
  struct Client {
    int fd = -1;
    std::string in;
    std::vector<std::pair<Clock::time_point, std::string>> replies;  // held back, in order
    std::string out;  // written, not yet taken by the client
  };
  void accept();
  void read(Client& c);
  void send(Client& c, const std::string& reply);
  static void write_out(Client& c);
  static void close_client(Client& c);

  std::string name_;
  std::string host_;
  int port_;
  std::string unix_path_;  // non-empty: a unix stream socket there instead of TCP
  Answer answer_;
  Options options_;
  int listen_fd_ = -1;
  std::vector<Client> clients_;
};

}  // namespace fogbench::mock
