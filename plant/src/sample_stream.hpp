// The samples of a run read from the bench's SQLite store and encoded as binary COPY data on a
// thread of their own (internal to plant/src), so that reading the bench and the plant's
// ingestion overlap: while the plant's server takes one page, the next is read and encoded.
// Without it the two alternated (the server idled while a page was read; the run's time was
// the sum of both, docs/performance.md).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "fogbench/storage/store.hpp"

namespace fogbench::plant::detail {

class SampleStream {
 public:
  // Starts reading `units` of `run_id` in order, `page` rows at a time; the first chunk begins
  // with the binary COPY header, the last ends with its trailer. At most `depth` chunks wait.
  SampleStream(storage::Store& bench, std::string bench_id, std::int64_t run_id, std::vector<int> units,
               std::int64_t page = 50000, std::size_t depth = 2);
  // Stops the reader (when the consumer gave up early) and joins it.
  ~SampleStream();
  SampleStream(const SampleStream&) = delete;
  SampleStream& operator=(const SampleStream&) = delete;

  // The next chunk; nullopt at the end. A store failure is returned as an error string.
  struct Chunk {
    std::string data;
    std::string error;  // non-empty: the bench's store failed (data empty)
    std::int64_t rows = 0;
  };
  std::optional<Chunk> next();

 private:
  void run();
  bool push(Chunk c);  // false when stopping

  storage::Store& bench_;
  std::string bench_id_;
  std::int64_t run_id_;
  std::vector<int> units_;
  std::int64_t page_;
  std::size_t depth_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Chunk> ready_;
  bool done_ = false, stopping_ = false;
  std::thread thread_;
};

}  // namespace fogbench::plant::detail
