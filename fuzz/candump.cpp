// Fuzzes the candump -l log line parser (drivers/include/fogbench/drivers/candump.hpp), the
// replay transport's input. The input is a log, one line per frame. A line that parses must
// format back (format_candump_line) to a line that parses to the same frame: recording what
// was replayed must not change it. Parsed frames also go through decode and a SampleAccumulator
// checked against AccountingModel, so recorded logs reach the sample accounting too.
#include <cstring>
#include <optional>
#include <string>

#include "can_model.hpp"
#include "fogbench/drivers/candump.hpp"

using namespace fogbench;

namespace {

bool same_frame(const ::can_frame& a, const ::can_frame& b) {
  if (a.can_id != b.can_id || a.can_dlc != b.can_dlc) return false;
  if (a.can_id & CAN_RTR_FLAG) return true;  // a remote request carries no data
  return std::memcmp(a.data, b.data, a.can_dlc > 8 ? 8 : a.can_dlc) == 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view log = fuzz::as_text(data, size);
  std::optional<drivers::SampleAccumulator> acc;
  std::optional<fuzz::AccountingModel> model;
  while (!log.empty()) {
    const auto nl = log.find('\n');
    const std::string_view line = log.substr(0, nl);
    log = nl == std::string_view::npos ? std::string_view() : log.substr(nl + 1);

    const auto parsed = drivers::parse_candump_line(line);
    if (!parsed) continue;
    const ::can_frame& f = parsed->frame;
    FUZZ_CHECK(f.can_dlc <= 8, "dlc %u", f.can_dlc);
    FUZZ_CHECK(!parsed->interface.empty() && parsed->interface.find(' ') == std::string::npos,
               "interface '%s'", parsed->interface.c_str());
    FUZZ_CHECK(parsed->time_us >= 0, "time %lld us", static_cast<long long>(parsed->time_us));

    const std::string again = drivers::format_candump_line(parsed->time_us, parsed->interface, f);
    const auto reparsed = drivers::parse_candump_line(again);
    const int len = static_cast<int>(line.size());
    FUZZ_CHECK(reparsed.has_value(), "'%.*s' formats as '%s', which does not parse", len, line.data(),
               again.c_str());
    FUZZ_CHECK(reparsed->time_us == parsed->time_us && reparsed->interface == parsed->interface,
               "'%.*s' formats as '%s': time or interface changed", len, line.data(), again.c_str());
    FUZZ_CHECK(same_frame(reparsed->frame, f), "'%.*s' formats as '%s': the frame changed", len,
               line.data(), again.c_str());

    // The first standard data frame names the unit of the accumulator.
    if (!acc && !(f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) && (f.can_id & CAN_SFF_MASK) != 0) {
      drivers::GyroChannelConfig config;
      config.node_id = static_cast<std::uint16_t>(f.can_id & CAN_SFF_MASK);
      config.scale_dph_per_count = 1e-4;
      acc.emplace(config);
      model.emplace(config.node_id);
    }
    (void)drivers::can::decode(f);
    if (acc) {
      acc->add(f);
      model->add(f);
    }
  }
  if (acc) model->check_close(acc->close());
  return 0;
}
