// fogbenchd's analysis worker (an internal header of daemon/src/, used by server.cpp): the
// Offload that runs fits, verifications, the workbench and large reads on a thread of its own.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio.hpp>
#include <chrono>
#include <deque>
#include <future>
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
    ended_ = ended_promise_.get_future();
    thread_ = std::thread([this] {
      ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
      jobs_.run();
      ended_promise_.set_value();
    });
  }
  ~AnalysisWorker() override {
    // A job that would not end (stop() said so) cannot be joined without hanging: the server
    // ends the process instead of destroying the worker; this is the last guard.
    if (!stop(std::chrono::seconds(2)) && thread_.joinable()) thread_.detach();
  }

  // On the loop thread.
  void submit(Job job, JobOrigin origin) override {
    queue_.push(std::move(job), std::move(origin));
    if (!busy_) next();
  }
  std::size_t pending_from(std::string_view address) const override { return queue_.pending_from(address); }

  // Jobs not yet started are dropped (the loop is stopping); the one running has `timeout` to
  // finish. True when the thread ended and was joined; false (logged, with how long the job had
  // run) leaves the job running, its result never stored, for the process's end to take.
  bool stop(std::chrono::milliseconds timeout) {
    guard_.reset();
    jobs_.stop();
    if (!thread_.joinable()) return true;
    if (ended_.wait_for(timeout) != std::future_status::ready) {
      const auto began = job_began_ns_.load();
      const double ran_s =
          began ? std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch() -
                                                std::chrono::nanoseconds(began))
                      .count()
                : 0.0;
      spdlog::warn("analysis worker: stopping: abandoned the job running for {:.1f} s (not finished within {} ms; "
                   "its result is not stored)",
                   ran_s, timeout.count());
      return false;
    }
    thread_.join();
    return true;
  }

 private:
  void next() {
    auto job = queue_.pop();
    busy_ = job.has_value();
    if (!busy_) return;
    asio::post(jobs_, [this, job = std::move(job->job), address = std::move(job->address)] {
      job_began_ns_ = std::chrono::steady_clock::now().time_since_epoch().count();
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
  std::atomic<std::int64_t> job_began_ns_{0};  // steady clock: the running job's start
  std::promise<void> ended_promise_;            // set when the thread's loop returns
  std::future<void> ended_;
  asio::io_context jobs_;
  asio::executor_work_guard<asio::io_context::executor_type> guard_{jobs_.get_executor()};
  std::thread thread_;
};

}  // namespace fogbench::daemon::net
