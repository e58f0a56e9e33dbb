// Replay of a candump -l log as a frame source, paced by the log's timestamps. The file is read
// line by line, so an hour of 64,000 frames/s needs no more memory than a minute.
#include <sys/timerfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <algorithm>
#include <optional>

#include "fogbench/drivers/can_transport.hpp"
#include "fogbench/drivers/candump.hpp"

namespace fogbench::drivers {
namespace {

class ReplayTransport final : public CanTransport {
 public:
  ReplayTransport(int timer_fd, std::string file, std::ifstream in, double speed, MonotonicClock clock)
      : timer_fd_(timer_fd), file_(std::move(file)), in_(std::move(in)), speed_(speed),
        clock_(std::move(clock)), start_(clock_()) {
    arm();
  }
  ~ReplayTransport() override { ::close(timer_fd_); }

  int fd() const noexcept override { return timer_fd_; }
  std::uint64_t malformed() const noexcept override { return malformed_; }
  std::string describe() const override { return "replay:" + file_; }

  Result<std::size_t> read(std::vector<::can_frame>& out) override {
    std::uint64_t expirations = 0;  // clear the timer's readability; its count is not needed
    while (::read(timer_fd_, &expirations, sizeof expirations) > 0) {
    }
    std::size_t got = 0;
    const auto now = clock_();
    // A bound per call keeps one event-loop turn short even at speed 0.
    while (got < 4096 && fetch()) {
      if (speed_ > 0 && due(*pending_) > now) break;
      out.push_back(pending_->frame);
      pending_.reset();
      ++got;
    }
    if (got == 0 && !fetch()) {
      return fail(ErrorCode::end_of_stream, describe() + ": end of log (" +
                                                std::to_string(delivered_) + " frames)");
    }
    delivered_ += got;
    arm();
    return got;
  }

 private:
  // Makes the next frame pending; false at the end of the file.
  bool fetch() {
    if (pending_) return true;
    std::string line;
    while (std::getline(in_, line)) {
      if (line.empty()) continue;
      if (auto f = parse_candump_line(line)) {
        if (!first_us_) first_us_ = f->time_us;
        pending_ = std::move(*f);
        return true;
      }
      ++malformed_;
    }
    return false;
  }

  std::chrono::nanoseconds due(const LogFrame& f) const {
    const double offset_s = static_cast<double>(f.time_us - *first_us_) * 1e-6 / speed_;
    return start_ + std::chrono::nanoseconds(static_cast<std::int64_t>(offset_s * 1e9));
  }

  // Makes the fd readable when the next frame is due: at once when unpaced, at its time
  // otherwise. At the end of the log it fires once more, so the loop's next read() reports
  // end_of_stream; the timer is one-shot, so after that the fd stays quiet.
  void arm() {
    itimerspec spec{};
    std::chrono::nanoseconds wait{1};
    if (fetch() && speed_ > 0) {
      wait = std::max(due(*pending_) - clock_(), std::chrono::nanoseconds(1));
    }
    spec.it_value.tv_sec = static_cast<time_t>(wait.count() / 1'000'000'000);
    spec.it_value.tv_nsec = static_cast<long>(wait.count() % 1'000'000'000);
    ::timerfd_settime(timer_fd_, 0, &spec, nullptr);
  }

  int timer_fd_;
  std::string file_;
  std::ifstream in_;
  double speed_;
  MonotonicClock clock_;
  std::chrono::nanoseconds start_;
  std::optional<std::int64_t> first_us_;
  std::optional<LogFrame> pending_;
  std::uint64_t malformed_ = 0;
  std::uint64_t delivered_ = 0;
};

}  // namespace

Result<std::unique_ptr<CanTransport>> open_replay(const std::string& file, double speed,
                                                  MonotonicClock clock) {
  if (!(speed >= 0)) return fail(ErrorCode::config, "replay:" + file + ": speed must be >= 0");
  std::ifstream in(file);
  if (!in) return fail(ErrorCode::io, "replay:" + file + ": cannot open: " + std::strerror(errno));
  const int tfd = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (tfd < 0) return fail(ErrorCode::io, "replay:" + file + ": timerfd_create: " + std::strerror(errno));
  if (!clock) {
    clock = [] {
      return std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::steady_clock::now().time_since_epoch());
    };
  }
  return std::make_unique<ReplayTransport>(tfd, file, std::move(in), speed, std::move(clock));
}

}  // namespace fogbench::drivers
