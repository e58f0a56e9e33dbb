#include "rate_table_link.hpp"

#include <algorithm>
#include <boost/asio.hpp>
#include <optional>
#include <thread>

#include <spdlog/spdlog.h>

namespace fogbench::daemon {

namespace asio = boost::asio;

struct RateTableLink::Impl {
  asio::io_context& loop;
  std::unique_ptr<drivers::RateTable> table;  // used on the worker only
  asio::io_context worker;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> guard;
  std::thread thread;
  // On the loop.
  bool in_flight = false;
  std::optional<double> written_dps;  // the rate the table last accepted, deg/s
  std::string last_error;             // logged once per change, not every second
  int status_tolerance = 5;           // failed status reads in a row before `unreadable`
  int failed_reads = 0;               // status reads in a row that failed, not for the link
  std::string last_status_error;      // the last of them, logged once per change

  Impl(asio::io_context& l, std::unique_ptr<drivers::RateTable> t, int tolerance)
      : loop(l), table(std::move(t)), status_tolerance(std::max(1, tolerance)) {
    guard.emplace(worker.get_executor());
    thread = std::thread([this] { worker.run(); });
  }
};

namespace {

// What one job saw: the command's outcome (when one was sent) and the status.
struct JobResult {
  std::optional<double> sent_dps;
  std::string command_error;  // empty: accepted
  RateTableReading reading;
  std::vector<drivers::RateTableEvent> events;
};

}  // namespace

RateTableLink::RateTableLink(asio::io_context& loop, std::unique_ptr<drivers::RateTable> table, int status_tolerance)
    : impl_(std::make_unique<Impl>(loop, std::move(table), status_tolerance)) {}

RateTableLink::~RateTableLink() {
  impl_->guard.reset();
  if (impl_->thread.joinable()) impl_->thread.join();
}

void RateTableLink::command(double rate_dps) {
  Impl& m = *impl_;
  if (m.in_flight) return;  // the next second sends the then-current rate
  m.in_flight = true;
  std::optional<double> send;
  if (!m.written_dps || *m.written_dps != rate_dps) send = rate_dps;
  asio::post(m.worker, [this, send] {
    Impl& w = *impl_;
    JobResult r;
    if (send) {
      r.sent_dps = send;
      auto ok = *send == 0.0 ? w.table->stop() : w.table->set_rate_dps(*send);
      if (!ok) r.command_error = ok.error().to_string();
    }
    if (auto s = w.table->read_status()) {
      r.reading.fault = s->fault;
      if (s->fault) r.reading.reason = s->fault_text.empty() ? "fault (no text)" : s->fault_text;
    } else {
      r.reading.link_down = drivers::is_link_failure(s.error());
      r.reading.reason = s.error().to_string();
      if (!r.reading.link_down) r.reading.reason = "status not read: " + r.reading.reason;
    }
    // A link lost during the command (its status read may have reconnected since): the loss
    // is what the run is told.
    if (!r.command_error.empty() && !r.reading.fault && !r.reading.link_down) {
      r.reading.link_down = true;
      r.reading.reason = r.command_error;
    }
    r.events = w.table->take_events();
    asio::post(w.loop, [this, r = std::move(r)] {
      Impl& m2 = *impl_;
      m2.in_flight = false;
      for (const auto& e : r.events) spdlog::warn("rate table: {}", e.to_string());
      if (r.sent_dps) {
        if (r.command_error.empty()) {
          m2.written_dps = r.sent_dps;
          if (*r.sent_dps == 0.0) spdlog::info("rate table stopped (0 deg/s)");
          else spdlog::info("rate table at {} deg/s", *r.sent_dps);
          m2.last_error.clear();
        } else {
          m2.written_dps.reset();  // sent again next second
          if (r.command_error != m2.last_error)
            spdlog::warn("rate table: {} deg/s not commanded: {}", *r.sent_dps, r.command_error);
          m2.last_error = r.command_error;
        }
      }
      RateTableReading reading = r.reading;
      // A status not read, for a reason other than the link: tolerated up to the configured
      // count in a row (logged at the first and at each new reason), then `unreadable`.
      if (!reading.fault && !reading.link_down && !reading.reason.empty()) {
        ++m2.failed_reads;
        if (m2.failed_reads == 1 || reading.reason != m2.last_status_error)
          spdlog::warn("rate table: {} ({} of {} tolerated in a row)", reading.reason, m2.failed_reads,
                       m2.status_tolerance);
        m2.last_status_error = reading.reason;
        if (m2.failed_reads >= m2.status_tolerance) {
          reading.unreadable = true;
          reading.reason = std::to_string(m2.failed_reads) + " status reads in a row failed (rate_table.status_tolerance " +
                           std::to_string(m2.status_tolerance) + "); the last: " + reading.reason;
        }
      } else {
        if (m2.failed_reads > 0 && reading.reason.empty())
          spdlog::info("rate table: status read again after {} failed", m2.failed_reads);
        m2.failed_reads = 0;
      }
      reading_ = reading;
    });
  });
}

void RateTableLink::stop_table(std::function<void(const std::string&)> done) {
  asio::post(impl_->worker, [this, done = std::move(done)] {
    auto ok = impl_->table->stop();
    std::string err = ok ? "" : ok.error().to_string();
    asio::post(impl_->loop, [done, err] { done(err); });
  });
}

}  // namespace fogbench::daemon
