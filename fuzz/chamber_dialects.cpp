// Fuzzes the ASCII chamber controllers' reply and command parsers
// (drivers/include/fogbench/drivers/chamber_dialects.hpp): what an Espec or SIMSERV controller,
// or anything else on its port, sends back. Every parser must return a value or nothing, never
// crash; a TEMP? reply that parses has finite numbers; an ALARM? reply's code count is its
// first field; a SIMSERV reply that parses formats back (format_reply) to a line that parses to
// the same code and values; printable() shows only printable ASCII.
#include <cmath>
#include <string>

#include "common.hpp"
#include "fogbench/drivers/chamber_dialects.hpp"

using namespace fogbench;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view line = fuzz::as_text(data, size);
  namespace espec = drivers::espec;
  namespace simserv = drivers::simserv;

  if (auto t = espec::parse_temp(line)) {
    FUZZ_CHECK(std::isfinite(t->process_value_c) && std::isfinite(t->setpoint_c), "TEMP? parsed a non-finite number");
  }
  if (auto m = espec::parse_mon(line)) {
    FUZZ_CHECK(m->alarms >= 0, "MON? parsed a negative alarm count");
    FUZZ_CHECK(espec::parse_mode(m->mode).has_value(), "MON? parsed an unknown mode");
  }
  (void)espec::parse_alarm(line);
  (void)espec::parse_mode(line);
  (void)espec::describe_error(line);

  if (auto r = simserv::parse_reply(line)) {
    std::string again = simserv::format_reply(r->code, r->values);
    again.resize(again.size() - 2);  // the CR LF
    auto back = simserv::parse_reply(again);
    FUZZ_CHECK(back.has_value(), "a formatted reply does not parse");
    FUZZ_CHECK(back->code == r->code && back->values == r->values, "a reply changed through format_reply");
  }
  if (auto c = simserv::parse_command(line)) {
    std::string again = simserv::format_command(c->number, c->chamber_index, c->args);
    again.pop_back();  // the CR
    auto back = simserv::parse_command(again);
    FUZZ_CHECK(back.has_value(), "a formatted command does not parse");
    FUZZ_CHECK(back->number == c->number && back->chamber_index == c->chamber_index && back->args == c->args,
               "a command changed through format_command");
  }
  for (char ch : drivers::printable(line)) FUZZ_CHECK(ch >= 0x20 && ch < 0x7f, "printable() let a byte through");
  return 0;
}
