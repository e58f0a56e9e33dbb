// systemd's STATUS= line while fogbenchd runs (docs/daemon.md, "Under systemd"): what
// `systemctl status fogbenchd` shows. An internal header of daemon/src/, used by server.cpp.
// A timer on the loop looks at the station every 0.5 s (wall) and sends the line when what it
// says changes in kind (a run starts or ends, a state, step or phase change, a plan's step) and
// otherwise at most every 5 s while it changes (a run's elapsed time). Not a per-tick hook: its
// cost does not grow with the time scale.
#pragma once

#include <utility>  // before Boost 1.74's asio: its awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::daemon {

class Station;
class PlanRunner;

// The line's text from the station's `status` reply and the running plan's `plan.status` reply
// (null: no plan running); `last_run` the newest stored run ({id, profile, state}, null: none),
// for the idle line. `key` receives what changes only at a phase change (for the rate limit).
std::string status_text(const nlohmann::json& status, const nlohmann::json& plan, const nlohmann::json& last_run,
                        std::string* key = nullptr);

class StatusNotifier {
 public:
  using Send = std::function<bool(std::string_view)>;
  static constexpr auto kLook = std::chrono::milliseconds(500);
  static constexpr auto kEvery = std::chrono::seconds(5);

  StatusNotifier(boost::asio::io_context& io, Station& station, PlanRunner* plans, Send send);
  void start();
  void stop();

 private:
  void look();
  void schedule();

  boost::asio::steady_timer timer_;
  Station& station_;
  PlanRunner* plans_;
  Send send_;
  std::string sent_key_, sent_text_;
  std::optional<std::chrono::steady_clock::time_point> sent_at_;
  nlohmann::json last_run_, last_ended_;  // the newest stored run; the station's last_run then
  bool last_read_ = false;
  bool stopped_ = false;
};

}  // namespace fogbench::daemon
