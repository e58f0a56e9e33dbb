// The candump -l log line format, `(1700000000.123456) can0 123#0102030405060708`: parsed for
// replay, formatted for recording. Pure, shared with the mock bench.
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace fogbench::drivers {

struct LogFrame {
  std::int64_t time_us = 0;  // the log's wall-clock timestamp in microseconds since the epoch
  std::string interface;
  ::can_frame frame{};
};

// Classic CAN lines only: 3 hex digits for a standard id, 8 for an extended one (flagged with
// CAN_EFF_FLAG unless the error flag is set, as candump writes them), `R` for a remote request,
// up to 8 data bytes. CAN FD lines (`##`) and anything malformed give nullopt.
std::optional<LogFrame> parse_candump_line(std::string_view line);

// The line candump -l would write for a frame (no newline).
std::string format_candump_line(std::int64_t time_us, std::string_view interface,
                                const ::can_frame& frame);

}  // namespace fogbench::drivers
