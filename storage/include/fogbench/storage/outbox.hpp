// The plant outbox as stored (store_outbox.cpp, docs/plant.md): runs waiting to be
// replicated to the plant store, and the outbox's status.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace fogbench::storage {

// One run waiting in the plant outbox.
struct OutboxEntry {
  std::int64_t id = 0;
  std::int64_t run_id = 0;
  std::string queued_at;    // ISO 8601 UTC
  int attempts = 0;         // failed attempts so far
  std::string last_error;   // the last attempt's error, "" when none failed
};

struct OutboxStatus {
  std::int64_t depth = 0;                     // entries waiting
  std::optional<std::string> oldest_queued_at;
  int attempts = 0;                           // failed attempts of the oldest entry
  std::string last_error;                     // and its last error
  std::optional<std::string> last_sent_at;    // the last entry the plant committed
  std::int64_t sent = 0;                      // entries sent, ever
};

}  // namespace fogbench::storage
