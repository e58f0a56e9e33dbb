// Fuzzes the run CSV import (storage/include/fogbench/storage/csv.hpp, docs/csv.md). The input
// is a CSV text; a first line `#!fuzz item;item;...` (a comment to the CSV parser) sets the
// options as fogctl's flags would: `map canonical=header` (through parse_column_mapping, like
// --map) and `resample <seconds>`. A parsed run must be well formed: equal column lengths,
// increasing finite time, finite readings except NaN (a reading not taken) on rows flagged
// missing; without resampling, to_csv must read back to the very same run (docs/csv.md
// promises the exact round trip); with it, time must be the promised grid.
#include <charconv>
#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "common.hpp"
#include "fogbench/storage/csv.hpp"

using namespace fogbench;
using storage::CsvOptions;

namespace {

CsvOptions options_from(std::string_view text) {
  CsvOptions o;
  o.source_name = "fuzz.csv";
  constexpr std::string_view tag = "#!fuzz ";
  if (!text.starts_with(tag)) return o;
  std::string_view line = text.substr(tag.size());
  line = line.substr(0, line.find('\n'));
  while (!line.empty()) {
    const auto semi = line.find(';');
    const std::string_view item = line.substr(0, semi);
    line = semi == std::string_view::npos ? std::string_view() : line.substr(semi + 1);
    if (item.starts_with("map ")) {
      auto m = storage::parse_column_mapping(item.substr(4));
      if (m) o.column_map.push_back(*m);
      else FUZZ_CHECK(!m.error().message.empty(), "a mapping error without a message");
    } else if (item.starts_with("resample ")) {
      double dt = 0.0;
      const auto v = item.substr(9);
      if (std::from_chars(v.data(), v.data() + v.size(), dt).ec == std::errc()) o.resample_s = dt;
    }
  }
  return o;
}

template <class T>
void check_length(const std::vector<T>& column, std::size_t n, const char* name) {
  FUZZ_CHECK(column.empty() || column.size() == n, "column %s has %zu values for %zu rows", name,
             column.size(), n);
}

// Finite, or NaN on a row whose flags have the missing bit (docs/csv.md).
void check_readings(const model::RunData& run, const std::vector<double>& column, const char* name) {
  for (std::size_t i = 0; i < column.size(); ++i) {
    const double v = column[i];
    const bool missing = run.has_flags() && (run.flags[i] & model::flag::missing);
    FUZZ_CHECK(std::isfinite(v) || (std::isnan(v) && missing), "column %s holds %g on row %zu (flags %d)",
               name, v, i, run.has_flags() ? run.flags[i] : -1);
  }
}

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if constexpr (std::is_floating_point_v<T>) {
      if (std::isnan(a[i]) && std::isnan(b[i])) continue;
    }
    if (!(a[i] == b[i])) return false;
  }
  return true;
}

void check_run(const model::RunData& run) {
  const std::size_t n = run.size();
  FUZZ_CHECK(n >= 1, "a parsed run without rows");
  FUZZ_CHECK(run.gyro_dph.size() == n && run.t1_c.size() == n && run.t2_c.size() == n,
             "required columns of unequal length");
  check_length(run.setpoint_c, n, "setpoint_c");
  check_length(run.chamber_c, n, "chamber_c");
  check_length(run.phase, n, "phase");
  check_length(run.step, n, "step");
  check_length(run.flags, n, "flags");
  for (double t : run.time_s) FUZZ_CHECK(std::isfinite(t), "time_s holds %g", t);
  check_readings(run, run.gyro_dph, "gyro_dph");
  check_readings(run, run.t1_c, "t1_c");
  check_readings(run, run.t2_c, "t2_c");
  check_readings(run, run.setpoint_c, "setpoint_c");
  check_readings(run, run.chamber_c, "chamber_c");
  for (std::size_t i = 1; i < n; ++i)
    FUZZ_CHECK(run.time_s[i] > run.time_s[i - 1], "time %.17g after %.17g at row %zu", run.time_s[i],
               run.time_s[i - 1], i);
  for (auto p : run.phase) FUZZ_CHECK(static_cast<int>(p) <= static_cast<int>(model::Phase::cooling), "phase %d", static_cast<int>(p));
}

void check_round_trip(const model::RunData& run) {
  const std::string text = storage::to_csv(run);
  CsvOptions o;
  o.source_name = run.name;
  auto back = storage::parse_csv(text, o);
  FUZZ_CHECK(back.has_value(), "to_csv does not read back: %s\n%s", back.error().message.c_str(), text.c_str());
  FUZZ_CHECK(same(back->time_s, run.time_s) && same(back->gyro_dph, run.gyro_dph) &&
                 same(back->t1_c, run.t1_c) && same(back->t2_c, run.t2_c) &&
                 same(back->setpoint_c, run.setpoint_c) && same(back->chamber_c, run.chamber_c) &&
                 same(back->phase, run.phase) && same(back->step, run.step) &&
                 same(back->flags, run.flags),
             "to_csv then parse_csv changed the run:\n%s", text.c_str());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto text = fogbench::fuzz::as_text(data, size);
  const CsvOptions options = options_from(text);
  auto run = storage::parse_csv(text, options);
  if (!run) {
    const auto& e = run.error();
    FUZZ_CHECK(e.message.starts_with(options.source_name), "message does not name the source: %s",
               e.message.c_str());
    FUZZ_CHECK(e.line <= size + 1, "error on line %zu of a %zu-byte text", e.line, size);
    return 0;
  }
  FUZZ_CHECK(run->name == options.source_name, "run named '%s'", run->name.c_str());
  check_run(*run);
  if (!options.resample_s) {
    check_round_trip(*run);
    return 0;
  }
  // The promised grid: time_s[0] + k * resample_s.
  const double dt = *options.resample_s;
  for (std::size_t k = 0; k < run->size(); ++k)
    FUZZ_CHECK(run->time_s[k] == run->time_s[0] + static_cast<double>(k) * dt,
               "resampled time %.17g at k=%zu, dt %g", run->time_s[k], k, dt);
  return 0;
}
