// The analysis worker's stop is bounded (daemon/src/analysis_worker.hpp, docs/reliability.md "The
// stop's budget"): a job that does not finish within the stop's share is abandoned (stop says
// false, the thread left running) instead of holding the daemon's exit; a worker whose job has
// ended stops and joins.
#include <catch2/catch.hpp>

#include <future>

#include "../../daemon/src/analysis_worker.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::net;

TEST_CASE("analysis worker: a job still running at the stop's deadline is abandoned, not waited for") {
  auto store = storage::Store::open(":memory:");
  REQUIRE(store);
  asio::io_context loop;
  AnalysisWorker w(loop, std::move(*store));
  std::promise<void> started, release;
  auto released = release.get_future().share();
  w.submit(
      [&started, released](storage::Store&) -> Offload::Then {
        started.set_value();
        released.wait();  // a fit that would run past the stop's share
        return {};
      },
      JobOrigin{});
  started.get_future().wait();
  // The job cannot end before release: stop's answer does not depend on the host's speed.
  CHECK_FALSE(w.stop(std::chrono::milliseconds(50)));
  release.set_value();
  // Once the job has ended the worker stops and joins (the destructor does the same).
  CHECK(w.stop(std::chrono::seconds(30)));
}
