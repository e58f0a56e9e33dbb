// fogbenchd's analysis worker (an internal header of daemon/src/, used by server.cpp): the
// Offload that runs fits, verifications, the workbench and large reads on a thread of its own.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <deque>
#include <thread>

#include <spdlog/spdlog.h>

#include "fogbench/daemon/offload.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon::net {

namespace asio = boost::asio;

// The analysis worker (offload.hpp): one thread with its own read-only connection to the store.
// The queue is the loop's (JobQueue: the station's analyses, then the local operator's, then the
// network's): one job at a time goes to the thread, and the next only once the previous one's
// continuation has run on the loop, so every job reads what the jobs before it stored (a run.get
// sent after a run's end sees the models its automatic fit stored), as with InlineOffload. The thread runs niced (+10): on a busy host the loop, which acquires and
// answers, wins the CPU from it.
class AnalysisWorker final : public Offload {
 public:
  AnalysisWorker(asio::io_context& loop, storage::Store reader) : loop_(loop), reader_(std::move(reader)) {
    thread_ = std::thread([this] {
      ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
      jobs_.run();
    });
  }
  ~AnalysisWorker() override { stop(); }

  // On the loop thread.
  void submit(Job job, JobOrigin origin) override {
    queue_.push(std::move(job), std::move(origin));
    if (!busy_) next();
  }
  std::size_t pending_from(std::string_view address) const override { return queue_.pending_from(address); }

  // Jobs not yet started are dropped (the loop is stopping); the one running finishes first.
  void stop() {
    guard_.reset();
    jobs_.stop();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void next() {
    auto job = queue_.pop();
    busy_ = job.has_value();
    if (!busy_) return;
    asio::post(jobs_, [this, job = std::move(job->job), address = std::move(job->address)] {
      Then then;
      try {
        then = job(reader_);
      } catch (const std::exception& e) {  // jobs catch their own; this is a last guard
        spdlog::error("analysis worker: {}", e.what());
      }
      asio::post(loop_, [this, then = std::move(then), address] {
        queue_.done(address);
        if (then) then();
        next();
      });
    });
  }

  asio::io_context& loop_;
  storage::Store reader_;
  JobQueue queue_;  // the loop's
  bool busy_ = false;      // a job is on the thread or its continuation on the loop
  asio::io_context jobs_;
  asio::executor_work_guard<asio::io_context::executor_type> guard_{jobs_.get_executor()};
  std::thread thread_;
};

}  // namespace fogbench::daemon::net
