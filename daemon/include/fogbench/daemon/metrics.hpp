// fogbenchd's Prometheus metrics (GET /metrics on the web server, docs/web.md): the text
// exposition format 0.0.4 rendered from the station's status and the server's counters. Pure: no
// I/O, so the unit tests render it from a status they make.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace fogbench::daemon {

struct MetricsInput {
  nlohmann::json status;                    // Station::status() (docs/protocol.md, `status`)
  std::optional<std::int64_t> store_bytes;  // the store's files on disk (database, -wal, -shm)
  std::size_t socket_clients = 0;           // command socket connections (unix and TCP)
  std::size_t web_clients = 0;              // WebSocket connections of the panel
  std::uint64_t http_requests = 0;          // HTTP requests answered since start
  std::int64_t ticks = 0;                   // seconds acquired since start
  std::int64_t ticks_skipped = 0;           // seconds the loop was too late for (stored as not read)
  std::int64_t polls_late = 0;              // ticks that used the previous period's device reading
  std::int64_t paced_slowed = 0;            // simulated clock: ticks the schedule was moved back for
  double tick_lateness_s = 0.0;             // how late the last tick ran, wall s
  double tick_lateness_max_s = 0.0;         // the largest since start, wall s
};

std::string render_metrics(const MetricsInput& in);

// A label value as the exposition format writes it: \ " and newline escaped.
std::string escape_label_value(std::string_view v);

}  // namespace fogbench::daemon
