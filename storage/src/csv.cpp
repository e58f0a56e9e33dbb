// Reads and writes the run CSV. One pass over the text: lines are found with memchr and cells
// parsed in place with std::from_chars, so a million-row file costs no allocation per cell.
//
// Why this file is longer than 800 lines: its one job is the run CSV. Most of it is one class,
// Parser, whose steps (header, column mapping, rows split across threads, per-cell errors with
// file, line and column) share the cursor and the error state of one pass; split into files
// they would pass that state around. The writer at the end is short and shares the number
// format with it.
#include "fogbench/storage/csv.hpp"

#include "format_number.hpp"

#include <fcntl.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <thread>
#include <limits>
#include <type_traits>
#include <array>
#include <cassert>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cctype>
#include <cstring>
#include <memory>
#include <system_error>

#include "csv_dialect.hpp"

namespace fogbench::storage {

std::string_view to_string(CsvErrc code) {
  switch (code) {
    case CsvErrc::io: return "io";
    case CsvErrc::bad_option: return "bad_option";
    case CsvErrc::empty: return "empty";
    case CsvErrc::duplicate_column: return "duplicate_column";
    case CsvErrc::missing_column: return "missing_column";
    case CsvErrc::field_count: return "field_count";
    case CsvErrc::bad_quote: return "bad_quote";
    case CsvErrc::not_a_number: return "not_a_number";
    case CsvErrc::not_finite: return "not_finite";
    case CsvErrc::bad_value: return "bad_value";
    case CsvErrc::no_data: return "no_data";
    case CsvErrc::time_not_increasing: return "time_not_increasing";
    case CsvErrc::time_uneven: return "time_uneven";
  }
  return "unknown";
}

namespace {

// The role of a file column; the order is that of csv_columns() (to_csv writes the same
// columns, since_power_on_s and compensated_dph after flags, then a three-axis unit's gyro_y_dph
// and gyro_z_dph with, where its axes have their own thermistors, t1_y_c, t2_y_c, t1_z_c,
// t2_z_c, and a rate table's run's plateau, rate_in_dps and rate_out_dps last).
// The roles up to r_t2_z are numbers (doubles); r_plateau an integer like r_step.
enum Role : int {
  r_time, r_gyro, r_t1, r_t2, r_setpoint, r_chamber, r_power_on, r_compensated, r_rate_in, r_rate_out, r_gyro_y,
  r_gyro_z, r_t1_y, r_t2_y, r_t1_z, r_t2_z, r_phase, r_step, r_flags, r_plateau, r_count,
  r_ignore = -1
};
constexpr int kRequired = 4;
constexpr int kLastDouble = r_t2_z;
constexpr std::array<std::string_view, r_count> kNames = {
    "time_s", "gyro_dph", "t1_c", "t2_c", "setpoint_c", "chamber_c", "since_power_on_s",
    "compensated_dph", "rate_in_dps", "rate_out_dps", "gyro_y_dph", "gyro_z_dph", "t1_y_c", "t2_y_c",
    "t1_z_c", "t2_z_c", "phase", "step", "flags", "plateau"};

// Even spacing tolerance, as a fraction of the median step: loose enough for time written
// with %.3f at 1 Hz, tight enough to catch a skipped or doubled sample.
constexpr double kSpacingTolerance = 0.01;
// A resampling interval between source samples wider than this many median steps is a gap.
constexpr double kGapSteps = 1.5;
// Resampling onto more points than this is surely a unit mistake (ms given as s).
// 10 million rows is 115 days at 1 Hz, and about 600 MB in memory; 1e8 (the old bound) let a
// 101-byte file ask for 6 GB (found by the CSV fuzzer).
constexpr double kMaxResampledRows = 1e7;

// The CPUs this process may run on (its affinity, e.g. under taskset), not those of the machine.
unsigned usable_cpus() {
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) return static_cast<unsigned>(CPU_COUNT(&set));
  return std::max(1u, std::thread::hardware_concurrency());
}

// The lines of a text, counted with memchr (std::count goes a byte at a time).
std::size_t count_lines(std::string_view text) {
  std::size_t n = 1;
  const char* p = text.data();
  const char* const end = p + text.size();
  while (const auto* nl = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)))) {
    ++n;
    p = nl + 1;
  }
  return n;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

using detail::format_number;

// Physical lines of a text, without the '\n' and a trailing '\r'; numbered from 1.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {
    // A UTF-8 byte order mark, as spreadsheet programs write, is not part of the first name.
    if (text_.starts_with("\xEF\xBB\xBF")) pos_ = 3;
  }

  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const char* begin = text_.data() + pos_;
    const std::size_t rest = text_.size() - pos_;
    const auto* nl = static_cast<const char*>(std::memchr(begin, '\n', rest));
    std::size_t len = nl ? static_cast<std::size_t>(nl - begin) : rest;
    pos_ += len + (nl ? 1 : 0);
    ++line_no_;
    if (len > 0 && begin[len - 1] == '\r') --len;
    line = std::string_view(begin, len);
    return true;
  }
  std::size_t line_no() const { return line_no_; }
  std::size_t pos() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_no_ = 0;
};

bool is_blank_or_comment(std::string_view line) {
  for (char c : line) {
    if (c == ' ' || c == '\t') continue;
    return c == '#';
  }
  return true;
}

// The fields of one line. A field may be quoted ("a,b"), as spreadsheets write names with
// commas; the view excludes the outer quotes but keeps doubled quotes doubled (numbers never
// contain them; header names are unescaped by the caller).
class Fields {
 public:
  explicit Fields(std::string_view line) : line_(line) {}

  bool next(std::string_view& field) {
    if (done_) return false;
    const std::size_t n = line_.size();
    std::size_t p = pos_;
    while (p < n && (line_[p] == ' ' || line_[p] == '\t')) ++p;
    if (p < n && line_[p] == '"') return next_quoted(p, field);
    const char* start = line_.data() + pos_;
    const auto* comma = static_cast<const char*>(std::memchr(start, ',', n - pos_));
    if (comma == nullptr) {
      field = trim(line_.substr(pos_));
      done_ = true;
    } else {
      const auto len = static_cast<std::size_t>(comma - start);
      field = trim(line_.substr(pos_, len));
      pos_ += len + 1;
    }
    return true;
  }
  bool bad_quote() const { return bad_quote_; }
  bool quoted() const { return quoted_; }

 private:
  bool next_quoted(std::size_t open, std::string_view& field) {
    const std::size_t n = line_.size();
    std::size_t q = open + 1;
    for (;;) {
      q = line_.find('"', q);
      if (q == std::string_view::npos) return fail_quote();
      if (q + 1 < n && line_[q + 1] == '"') {
        q += 2;
        continue;
      }
      break;
    }
    field = line_.substr(open + 1, q - open - 1);
    quoted_ = true;
    std::size_t r = q + 1;
    while (r < n && (line_[r] == ' ' || line_[r] == '\t')) ++r;
    if (r == n) {
      done_ = true;
    } else if (line_[r] == ',') {
      pos_ = r + 1;
    } else {
      return fail_quote();  // text after the closing quote
    }
    return true;
  }
  bool fail_quote() {
    bad_quote_ = true;
    done_ = true;
    return false;
  }

  std::string_view line_;
  std::size_t pos_ = 0;
  bool done_ = false;
  bool bad_quote_ = false;
  bool quoted_ = false;
};

enum class Num { ok, not_a_number, not_finite, out_of_range };

Num parse_double(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);  // from_chars rejects a plus sign
  if (s.empty()) return Num::not_a_number;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  if (ec == std::errc::result_out_of_range && ptr == end) {
    // from_chars reports underflow (1e-400) like overflow; underflow is just a tiny number,
    // so ask strtod, which rounds it to zero. Rare, so the copy does not matter.
    const std::string copy(s);
    out = std::strtod(copy.c_str(), nullptr);
    return std::isfinite(out) ? Num::ok : Num::out_of_range;
  }
  if (ec != std::errc{} || ptr != end) return Num::not_a_number;
  if (!std::isfinite(out)) return Num::not_finite;
  return Num::ok;
}

template <class Int>
Num parse_int(std::string_view s, Int& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return Num::not_a_number;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  if (ec == std::errc::result_out_of_range) return Num::out_of_range;
  if (ec != std::errc{} || ptr != end) return Num::not_a_number;
  return Num::ok;
}

std::string join_names(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i) out += ',';
    out += names[i].empty() ? "(empty)" : names[i];
    if (out.size() > 400 && i + 1 < names.size()) {
      out += ",... (" + std::to_string(names.size()) + " columns)";
      break;
    }
  }
  return out;
}

bool same_ignoring_case(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto x = static_cast<unsigned char>(a[i]), y = static_cast<unsigned char>(b[i]);
    if (std::tolower(x) != std::tolower(y)) return false;
  }
  return true;
}

class Parser {
 public:
  Parser(std::string_view text, const CsvOptions& options)
      : text_(text),
        options_(options),
        source_(options.source_name.empty() ? "<csv>" : options.source_name) {}

  std::expected<model::RunData, CsvError> run() {
    if (auto ok = check_options(); !ok) return std::unexpected(ok.error());
    Lines lines(text_);
    if (auto ok = read_header(lines); !ok) return std::unexpected(ok.error());
    if (!read_rows_in_two(lines.pos())) {
      if (auto ok = read_rows(lines, text_); !ok) return std::unexpected(ok.error());
    }
    if (data_.size() == 0)
      return fail(CsvErrc::no_data, 0, 0, "no data rows after the header on line " +
                                                  std::to_string(header_line_));
    if (auto ok = check_rate_columns(); !ok) return std::unexpected(ok.error());
    take_axis_thermistors();
    if (options_.time_scale != 1.0)
      for (auto& t : data_.time_s) t *= options_.time_scale;
    if (options_.resample_s) return resample(*options_.resample_s);
    if (auto ok = check_spacing(); !ok) return std::unexpected(ok.error());
    return std::move(data_);
  }

 private:
  std::unexpected<CsvError> fail(CsvErrc code, std::size_t line, std::size_t field,
                                 std::string what) const {
    CsvError e;
    e.code = code;
    e.source = source_;
    e.line = line;
    e.column = field;
    e.message = source_;
    if (line) e.message += ":" + std::to_string(line);
    e.message += ": ";
    if (field) {
      e.column_name = field <= names_.size() ? names_[field - 1] : std::string();
      e.message += "column " + std::to_string(field) + " '" + e.column_name + "'";
      const int role = field <= role_of_.size() ? role_of_[field - 1] : r_ignore;
      if (role != r_ignore && kNames[role] != e.column_name)
        e.message += " (" + std::string(kNames[role]) + ")";
      e.message += ": ";
    }
    e.message += what;
    return std::unexpected(std::move(e));
  }

  std::expected<void, CsvError> check_options() {
    if (!(std::isfinite(options_.time_scale) && options_.time_scale > 0))
      return fail(CsvErrc::bad_option, 0, 0,
                  "the time scale must be a positive number, got " + format_number(options_.time_scale));
    if (const auto& dt = options_.resample_s; dt && !(std::isfinite(*dt) && *dt > 0))
      return fail(CsvErrc::bad_option, 0, 0,
                  "--resample: the interval must be a positive number of seconds, got " +
                      format_number(*dt));
    for (std::size_t i = 0; i < options_.column_map.size(); ++i) {
      const ColumnMapping& m = options_.column_map[i];
      const std::string spec = m.canonical + "=" + m.header;
      const auto* it = std::find(kNames.begin(), kNames.end(), m.canonical);
      if (it == kNames.end())
        return fail(CsvErrc::bad_option, 0, 0,
                    "--map " + spec + ": '" + m.canonical +
                        "' is not a fogbench column (time_s,gyro_dph,t1_c,t2_c,setpoint_c,"
                        "chamber_c,since_power_on_s,compensated_dph,rate_in_dps,rate_out_dps,gyro_y_dph,"
                        "gyro_z_dph,t1_y_c,t2_y_c,t1_z_c,t2_z_c,phase,step,flags,plateau)");
      if (m.header.empty())
        return fail(CsvErrc::bad_option, 0, 0, "--map " + spec + ": empty header name");
      for (std::size_t j = 0; j < i; ++j) {
        const ColumnMapping& o = options_.column_map[j];
        if (o.canonical == m.canonical)
          return fail(CsvErrc::bad_option, 0, 0,
                      "--map names " + m.canonical + " twice (=" + o.header + " and =" +
                          m.header + ")");
        if (o.header == m.header)
          return fail(CsvErrc::bad_option, 0, 0,
                      "--map gives column '" + m.header + "' to both " + o.canonical + " and " +
                          m.canonical);
      }
    }
    return {};
  }

  std::expected<void, CsvError> read_header(Lines& lines) {
    std::string_view line;
    bool found = false;
    while (lines.next(line)) {
      if (is_blank_or_comment(line)) continue;
      found = true;
      break;
    }
    if (!found)
      return fail(CsvErrc::empty, 0, 0,
                  "empty file: no header row (expected at least time_s,gyro_dph,t1_c,t2_c)");
    header_line_ = lines.line_no();

    Fields fields(line);
    std::string_view f;
    while (fields.next(f)) {
      std::string name(f);
      if (fields.quoted()) {  // undo the doubling of quotes inside a quoted name
        std::size_t p = 0;
        while ((p = name.find("\"\"", p)) != std::string::npos) name.erase(p++, 1);
      }
      names_.push_back(std::move(name));
    }
    role_of_.assign(names_.size(), r_ignore);
    if (fields.bad_quote())
      return fail(CsvErrc::bad_quote, header_line_, names_.size() + 1,
                  "unterminated quoted name in the header");

    for (std::size_t i = 0; i < names_.size(); ++i) {
      if (names_[i].empty()) continue;  // a trailing comma's empty column is just ignored
      for (std::size_t j = 0; j < i; ++j)
        if (names_[j] == names_[i])
          return fail(CsvErrc::duplicate_column, header_line_, i + 1,
                      "duplicate column name, also column " + std::to_string(j + 1));
    }

    field_of_.fill(-1);
    // A header name matches exactly, else in any case (Time_s, GYRO_DPH): spreadsheets and
    // loggers capitalise. An exact match wins over a case-insensitive one.
    auto find = [&](std::string_view name) -> int {
      for (std::size_t i = 0; i < names_.size(); ++i)
        if (names_[i] == name) return static_cast<int>(i);
      for (std::size_t i = 0; i < names_.size(); ++i)
        if (same_ignoring_case(names_[i], name) && role_of_[i] == r_ignore) return static_cast<int>(i);
      return -1;
    };
    // Every column not found is named in one message, the mapped ones and the required ones.
    std::vector<std::string> missing;
    std::string map_hint;
    // Mapped columns first: an explicit --map wins over a column that happens to carry the
    // canonical name.
    for (const ColumnMapping& m : options_.column_map) {
      const auto role = static_cast<int>(
          std::find(kNames.begin(), kNames.end(), m.canonical) - kNames.begin());
      const int i = find(m.header);
      if (i < 0) {
        missing.push_back("'" + m.header + "' (named by --map " + m.canonical + "=" + m.header + ")");
        field_of_[role] = -2;  // not looked for again under its canonical name
        continue;
      }
      field_of_[role] = i;
      role_of_[i] = role;
    }
    std::size_t required_missing = 0;
    for (int role = 0; role < r_count; ++role) {
      if (field_of_[role] != -1) continue;
      if (role >= kRequired && std::find(options_.skip.begin(), options_.skip.end(), kNames[role]) != options_.skip.end())
        continue;
      const int i = find(kNames[role]);
      if (i >= 0 && role_of_[i] == r_ignore) {
        field_of_[role] = i;
        role_of_[i] = role;
      } else if (role < kRequired) {
        missing.push_back("'" + std::string(kNames[role]) + "'");
        map_hint += (map_hint.empty() ? "" : " ") + std::string("--map ") + std::string(kNames[role]) + "=<name in the file>";
        ++required_missing;
      }
    }
    for (auto& slot : field_of_)
      if (slot == -2) slot = -1;
    if (!missing.empty()) {
      std::string what;
      for (std::size_t k = 0; k < missing.size(); ++k) what += (k ? ", " : "") + missing[k];
      std::string msg = std::string(missing.size() == 1 ? "column " : "columns ") + what +
                        (missing.size() == 1 ? " not found" : " not found") + "; the header has: " + join_names(names_);
      if (names_.size() == 1 && names_[0].find_first_of(";\t|") != std::string::npos)
        msg += "; the header is one column: give its separator with --delimiter";
      if (required_missing)
        msg += "; if the file names " + std::string(required_missing == 1 ? "it" : "them") + " differently, use " + map_hint;
      // "required column 'gyro_dph'": the wording of one missing required column, kept.
      if (missing.size() == 1 && required_missing == 1) msg = "required " + msg;
      return fail(CsvErrc::missing_column, header_line_, 0, msg);
    }
    // A three-axis unit's y and z come together (model::RunData::has_axes).
    if ((field_of_[r_gyro_y] >= 0) != (field_of_[r_gyro_z] >= 0))
      return fail(CsvErrc::missing_column, header_line_, 0,
                  "column '" + std::string(kNames[field_of_[r_gyro_y] >= 0 ? r_gyro_z : r_gyro_y]) +
                      "' not found: a three-axis unit's columns gyro_y_dph and gyro_z_dph go together; the header has: " +
                      join_names(names_));
    // Per-axis thermistors: all four together, and only beside y and z.
    int axis_temps = 0;
    for (int role = r_t1_y; role <= r_t2_z; ++role) axis_temps += field_of_[role] >= 0 ? 1 : 0;
    if (axis_temps != 0 && (axis_temps != 4 || field_of_[r_gyro_y] < 0)) {
      std::string absent;
      for (int role = r_gyro_y; role <= r_t2_z; ++role)
        if (field_of_[role] < 0) absent += (absent.empty() ? "'" : ", '") + std::string(kNames[role]) + "'";
      return fail(CsvErrc::missing_column, header_line_, 0,
                  "column " + absent + " not found: a three-axis unit's per-axis thermistors t1_y_c, t2_y_c, t1_z_c, t2_z_c go "
                  "together, beside gyro_y_dph and gyro_z_dph; the header has: " + join_names(names_));
    }
    return {};
  }

  // A large file is parsed in two halves on two threads, split at a line break. Only the
  // happy path is parallel: if either half has any error, or time does not increase across
  // the split, the caller parses the whole file again in one pass, which finds the first
  // error with its exact line number. Returns whether the rows were read.
  bool read_rows_in_two(std::size_t body_pos) {
    constexpr std::size_t kMinParallelBytes = 4u << 20;
    const std::string_view body = text_.substr(body_pos);
    if (body.size() < kMinParallelBytes || usable_cpus() < 2) return false;
    const std::size_t nl = body.find('\n', body.size() / 2);
    if (nl == std::string_view::npos || nl + 1 >= body.size()) return false;
    const std::string_view first = body.substr(0, nl + 1), second = body.substr(nl + 1);
    Parser other(*this);
    other.data_ = model::RunData{};
    std::expected<void, CsvError> second_ok;
    std::thread worker([&] {
      Lines l(second);
      second_ok = other.read_rows(l, second);
    });
    Lines l(first);
    const auto first_ok = read_rows(l, body);  // reserves room for both halves: no regrowth below
    worker.join();
    auto& a = data_;
    auto& b = other.data_;
    if (!first_ok || !second_ok || b.size() == 0 || (a.size() > 0 && !(b.time_s.front() > a.time_s.back()))) {
      data_ = model::RunData{};
      rate_out_dps_.clear();
      plateau_.clear();
      return false;
    }
    auto append = [](auto& x, auto& y) { x.insert(x.end(), y.begin(), y.end()); };
    append(a.time_s, b.time_s);
    append(a.gyro_dph, b.gyro_dph);
    append(a.t1_c, b.t1_c);
    append(a.t2_c, b.t2_c);
    append(a.setpoint_c, b.setpoint_c);
    append(a.chamber_c, b.chamber_c);
    append(a.since_power_on_s, b.since_power_on_s);
    append(a.compensated_dph, b.compensated_dph);
    append(a.rate_in_dps, b.rate_in_dps);
    append(rate_out_dps_, other.rate_out_dps_);
    append(plateau_, other.plateau_);
    append(a.gyro_y_dph, b.gyro_y_dph);
    append(a.gyro_z_dph, b.gyro_z_dph);
    for (std::size_t k = 0; k < axis_temps_.size(); ++k) append(axis_temps_[k], other.axis_temps_[k]);
    append(a.phase, b.phase);
    append(a.step, b.step);
    append(a.flags, b.flags);
    return true;
  }

  // Reads the data rows of `lines`; `region` is the text whose rows to reserve room for.
  std::expected<void, CsvError> read_rows(Lines& lines, std::string_view region) {
    // One row per remaining line at most: reserving that bound avoids regrowth, and the excess
    // is small next to the data.
    const std::size_t rows = count_lines(region);
    data_.name = source_;
    std::vector<double>* doubles[r_count] = {&data_.time_s,     &data_.gyro_dph,  &data_.t1_c,
                                             &data_.t2_c,       &data_.setpoint_c, &data_.chamber_c,
                                             &data_.since_power_on_s, &data_.compensated_dph,
                                             &data_.rate_in_dps, &rate_out_dps_, &data_.gyro_y_dph,
                                             &data_.gyro_z_dph, &axis_temps_[0], &axis_temps_[1],
                                             &axis_temps_[2], &axis_temps_[3]};
    for (int role = 0; role <= kLastDouble; ++role)
      if (field_of_[role] >= 0) doubles[role]->reserve(rows);
    if (field_of_[r_plateau] >= 0) plateau_.reserve(rows);
    if (field_of_[r_phase] >= 0) data_.phase.reserve(rows);
    if (field_of_[r_step] >= 0) data_.step.reserve(rows);
    if (field_of_[r_flags] >= 0) data_.flags.reserve(rows);

    const std::size_t time_field = static_cast<std::size_t>(field_of_[r_time]) + 1;
    double prev_time = 0;
    std::size_t prev_line = 0;
    std::string_view line;
    while (lines.next(line)) {
      if (is_blank_or_comment(line)) continue;
      const std::size_t ln = lines.line_no();
      if (!fast_row(line, doubles))
        if (auto ok = general_row(line, ln, doubles); !ok) return ok;
      const double t = data_.time_s.back();
      if (data_.time_s.size() > 1 && !(t > prev_time))
        return fail(CsvErrc::time_not_increasing, ln, time_field,
                    format_number(t) + " is not after " + format_number(prev_time) +
                        " on line " + std::to_string(prev_line) +
                        "; time must be strictly increasing");
      prev_time = t;
      prev_line = ln;
    }
    return {};
  }

  // The common row, parsed in one pass: every cell a plain number (or phase name), no spaces,
  // quotes or empty cells. Any row it does not take is left untouched for general_row, which
  // accepts the same values and more, and names what is wrong; so the fast path only decides
  // how fast a row is read, never what it reads.
  bool fast_row(std::string_view line, std::vector<double>* doubles[]) {
    const char* p = line.data();
    const char* const end = p + line.size();
    double values[kLastDouble + 1];
    model::Phase phase{};
    int step = 0, plateau = 0;
    unsigned flags = 0;
    const std::size_t n = names_.size();
    for (std::size_t i = 0; i < n; ++i) {
      const int role = role_of_[i];
      if (role == r_ignore) {
        for (; p != end && *p != ','; ++p)
          if (*p == '"') return false;  // a quoted cell may hold commas
      } else if (role <= kLastDouble) {
        double v;
        const auto [q, ec] = std::from_chars(p, end, v);
        if (ec != std::errc{} || q == p || !std::isfinite(v)) return false;
        values[role] = v;
        p = q;
      } else if (role == r_phase) {
        const char* q = p;
        while (q != end && *q != ',') ++q;
        const auto ph = model::phase_from_string(std::string_view(p, static_cast<std::size_t>(q - p)));
        if (!ph) return false;
        phase = *ph;
        p = q;
      } else {
        const auto [q, ec] = role == r_step      ? std::from_chars(p, end, step)
                             : role == r_plateau ? std::from_chars(p, end, plateau)
                                                 : std::from_chars(p, end, flags);
        if (ec != std::errc{} || q == p || (role == r_flags && flags > 0xFFu)) return false;
        p = q;
      }
      if (i + 1 < n) {
        if (p == end || *p != ',') return false;
        ++p;
      } else if (p != end) {
        return false;
      }
    }
    for (int role = 0; role <= kLastDouble; ++role)
      if (field_of_[role] >= 0) doubles[role]->push_back(values[role]);
    if (field_of_[r_plateau] >= 0) plateau_.push_back(plateau);
    if (field_of_[r_phase] >= 0) data_.phase.push_back(phase);
    if (field_of_[r_step] >= 0) data_.step.push_back(step);
    if (field_of_[r_flags] >= 0) data_.flags.push_back(static_cast<std::uint8_t>(flags));
    return true;
  }

  // Any row, cell by cell, with the exact error of the first bad cell.
  std::expected<void, CsvError> general_row(std::string_view line, std::size_t ln,
                                            std::vector<double>* doubles[]) {
    const std::size_t expected_fields = names_.size();
    Fields fields(line);
    std::string_view cell;
    std::size_t i = 0;
    while (fields.next(cell)) {
      if (i >= expected_fields) {
        std::size_t n = i + 1;
        while (fields.next(cell)) ++n;
        return fail(CsvErrc::field_count, ln, 0,
                    std::to_string(n) + " fields but the header (line " +
                        std::to_string(header_line_) + ") has " +
                        std::to_string(expected_fields));
      }
      const int role = role_of_[i];
      ++i;
      if (role == r_ignore) continue;
      if (auto ok = parse_cell(role, cell, ln, i, doubles); !ok) return ok;
    }
    if (fields.bad_quote())
      return fail(CsvErrc::bad_quote, ln, i + 1, "unterminated quoted field");
    if (empty_field_) {
      const std::size_t f = empty_field_;
      empty_field_ = 0;
      if (data_.flags.empty() || !(data_.flags.back() & model::flag::missing))
        return fail(CsvErrc::not_a_number, ln, f,
                    "empty cell, expected a number (an empty cell is allowed only on a row "
                    "whose flags column has the missing bit, 1, set)");
    }
    if (i < expected_fields)
      return fail(CsvErrc::field_count, ln, 0,
                  "too few fields: " + std::to_string(i) + " but the header (line " +
                      std::to_string(header_line_) + ") has " +
                      std::to_string(expected_fields) + "; first missing: column " +
                      std::to_string(i + 1) + " '" + names_[i] + "'");
    return {};
  }

  std::size_t empty_field_ = 0;  // 1-based field of the row's first empty cell, 0 if none

  // A rate table's columns as to_csv writes them: rate_out_dps is gyro_dph / 3600 (both empty
  // together), and plateau the profile step (the step column when the file has none, else the
  // same number). rate_in_dps is read as RunData::rate_in_dps.
  std::expected<void, CsvError> check_rate_columns() {
    const std::size_t n = data_.size();
    if (field_of_[r_rate_out] >= 0) {
      const std::size_t field = static_cast<std::size_t>(field_of_[r_rate_out]) + 1;
      for (std::size_t i = 0; i < n; ++i) {
        const double g = data_.gyro_dph[i], r = rate_out_dps_[i];
        const bool same = std::isfinite(g) ? std::isfinite(r) && std::fabs(r * 3600.0 - g) <= 1e-9 * std::max(1.0, std::fabs(g))
                                           : !std::isfinite(r);
        if (!same)
          return fail(CsvErrc::bad_value, line_of_row(i), field,
                      (std::isfinite(r) ? format_number(r) + " deg/s" : std::string("empty")) +
                          " is not gyro_dph / 3600 (" +
                          (std::isfinite(g) ? format_number(g / 3600.0) + " deg/s" : std::string("gyro_dph empty")) +
                          "): rate_out_dps is the gyro's output in deg/s");
      }
    }
    rate_out_dps_.clear();
    if (field_of_[r_plateau] >= 0) {
      const std::size_t field = static_cast<std::size_t>(field_of_[r_plateau]) + 1;
      const bool has_step = field_of_[r_step] >= 0;
      bool complete = true;
      for (std::size_t i = 0; i < n; ++i) {
        if (plateau_[i] == kNoPlateau) {
          complete = false;
          continue;
        }
        if (has_step && plateau_[i] != data_.step[i])
          return fail(CsvErrc::bad_value, line_of_row(i), field,
                      "plateau " + std::to_string(plateau_[i]) + " but step " + std::to_string(data_.step[i]) +
                          ": the plateau is the profile step");
      }
      if (!has_step && complete) data_.step = std::move(plateau_);
    }
    plateau_.clear();
    return {};
  }
  // The per-axis thermistors read (t1_y_c, t2_y_c, t1_z_c, t2_z_c) into the run's axis_t1_c,
  // axis_t2_c, whose x is the recording's t1_c, t2_c.
  void take_axis_thermistors() {
    if (field_of_[r_t1_y] < 0) return;
    data_.axis_t1_c = {data_.t1_c, std::move(axis_temps_[0]), std::move(axis_temps_[2])};
    data_.axis_t2_c = {data_.t2_c, std::move(axis_temps_[1]), std::move(axis_temps_[3])};
  }
  std::array<std::vector<double>, 4> axis_temps_;  // rows' t1_y_c, t2_y_c, t1_z_c, t2_z_c, degC

  static constexpr int kNoPlateau = std::numeric_limits<int>::min();
  std::vector<double> rate_out_dps_;  // rows' rate_out_dps, deg/s, checked and dropped
  std::vector<int> plateau_;          // rows' plateau, kNoPlateau where empty

  std::expected<void, CsvError> parse_cell(int role, std::string_view cell, std::size_t ln,
                                           std::size_t field, std::vector<double>* doubles[]) {
    if (role <= kLastDouble) {
      if (cell.empty() && (role == r_power_on || role == r_compensated || role == r_rate_out)) {
        // The gyro's power-on was not known at this sample (the daemon saw none), or the daemon
        // computed no live compensation: nothing was missed, nothing is guessed. An empty
        // rate_out_dps is an empty gyro_dph (check_rate_columns), which the flags answer for.
        doubles[role]->push_back(std::numeric_limits<double>::quiet_NaN());
        return {};
      }
      if (cell.empty() && role != r_time) {
        // A reading that was not taken: kept as NaN, valid only if the row says so (checked
        // once the row's flags are read).
        doubles[role]->push_back(std::numeric_limits<double>::quiet_NaN());
        if (!empty_field_) empty_field_ = field;
        return {};
      }
      double v;
      switch (parse_double(cell, v)) {
        case Num::ok: doubles[role]->push_back(v); return {};
        case Num::not_a_number: return fail(CsvErrc::not_a_number, ln, field, not_a_number(cell));
        case Num::not_finite:
          return fail(CsvErrc::not_finite, ln, field,
                      "'" + std::string(cell) + "' is not a finite number");
        case Num::out_of_range:
          return fail(CsvErrc::not_finite, ln, field,
                      "'" + std::string(cell) + "' is out of the range of a double");
      }
    }
    if (role == r_phase) {
      auto p = model::phase_from_string(cell);
      if (!p)
        return fail(CsvErrc::bad_value, ln, field,
                    "unknown phase '" + std::string(cell) +
                        "' (expected settle, hold, heating, cooling or unknown)");
      data_.phase.push_back(*p);
      return {};
    }
    if (role == r_plateau && cell.empty()) {
      // to_csv writes no plateau for a run without its step column.
      plateau_.push_back(kNoPlateau);
      return {};
    }
    if (role == r_step || role == r_plateau) {
      int v;
      switch (parse_int(cell, v)) {
        case Num::ok: (role == r_step ? data_.step : plateau_).push_back(v); return {};
        case Num::out_of_range:
          return fail(CsvErrc::bad_value, ln, field,
                      std::string(role == r_step ? "step " : "plateau ") + std::string(cell) +
                          " is out of the range of an int");
        default:
          return fail(CsvErrc::not_a_number, ln, field,
                      "not an integer: '" + std::string(cell) + "'");
      }
    }
    // flags
    unsigned v;
    const Num r = parse_int(cell, v);
    if (r == Num::ok && v <= 0xFFu) {
      data_.flags.push_back(static_cast<std::uint8_t>(v));
      return {};
    }
    if (r == Num::ok || r == Num::out_of_range)
      return fail(CsvErrc::bad_value, ln, field,
                  "flags " + std::string(cell) + " is not a bit set of 0..255");
    return fail(CsvErrc::not_a_number, ln, field, "not an integer: '" + std::string(cell) + "'");
  }

  static std::string not_a_number(std::string_view cell) {
    if (cell.empty()) return "empty cell, expected a number";
    std::string m = "not a number: '" + std::string(cell) + "'";
    if (cell.find(',') != std::string_view::npos)
      m += "; a decimal comma? give --decimal-comma (with ';' or tab between the fields)";
    return m;
  }

  // The physical line of data row `row` (0-based), found again only on the error path so the
  // fast path keeps no per-row bookkeeping.
  std::size_t line_of_row(std::size_t row) const {
    Lines lines(text_);
    std::string_view line;
    while (lines.line_no() < header_line_ && lines.next(line)) {
    }
    std::size_t k = 0;
    while (lines.next(line)) {
      if (is_blank_or_comment(line)) continue;
      if (k++ == row) return lines.line_no();
    }
    return 0;
  }

  double median_step() const {
    const auto& t = data_.time_s;
    std::vector<double> d(t.size() - 1);
    for (std::size_t i = 1; i < t.size(); ++i) d[i - 1] = t[i] - t[i - 1];
    auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
    std::nth_element(d.begin(), mid, d.end());
    return *mid;
  }

  std::expected<void, CsvError> check_spacing() {
    const auto& t = data_.time_s;
    if (t.size() < 3) return {};  // one step is its own median
    const double median = median_step();
    const double tolerance = kSpacingTolerance * median;
    for (std::size_t i = 1; i < t.size(); ++i) {
      const double step = t[i] - t[i - 1];
      if (std::fabs(step - median) <= tolerance) continue;
      return fail(CsvErrc::time_uneven, line_of_row(i),
                  static_cast<std::size_t>(field_of_[r_time]) + 1,
                  "time step " + format_number(step) + " s (" + format_number(t[i - 1]) +
                      " on line " + std::to_string(line_of_row(i - 1)) + " -> " +
                      format_number(t[i]) + ") but the median step is " +
                      format_number(median) +
                      " s (tolerance 1%); time must be evenly spaced, or import with "
                      "resampling: --resample S");
    }
    return {};
  }

  std::expected<model::RunData, CsvError> resample(double dt) {
    const model::RunData& in = data_;
    const std::size_t n = in.size();
    if (n < 2) return std::move(data_);
    const double t0 = in.time_s.front();
    const double span = in.time_s.back() - t0;
    const double points = std::floor(span / dt + 1e-9) + 1;
    if (points > kMaxResampledRows)
      return fail(CsvErrc::bad_option, 0, 0,
                  "resampling " + format_number(span) + " s every " + format_number(dt) +
                      " s would make " + format_number(points) + " rows; is the interval in s?");
    const auto m = static_cast<std::size_t>(points);
    const double gap = kGapSteps * median_step();
    // Resampling far finer than the recording invents nearly every row: a time column in
    // milliseconds read as seconds (1000 per sample, resampled every 1 s) is the usual cause.
    if (n >= 3 && median_step() >= 100.0 * dt)
      return fail(CsvErrc::bad_option, 0, 0,
                  "resampling every " + format_number(dt) + " s a run whose time_s advances by " +
                      format_number(median_step()) + " per sample would invent " +
                      format_number(std::round(median_step() / dt) - 1) +
                      " of every " + format_number(std::round(median_step() / dt)) + " rows" +
                      (std::abs(median_step() - 1000.0) <= 10.0
                           ? "; time_s looks like milliseconds: read it with --time-unit ms (and no --resample)"
                           : "; is time_s in s?"));

    model::RunData out;
    out.name = in.name;
    out.time_s.resize(m);
    std::vector<double> model::RunData::*const numeric[] = {
        &model::RunData::gyro_dph, &model::RunData::t1_c, &model::RunData::t2_c,
        &model::RunData::setpoint_c, &model::RunData::chamber_c, &model::RunData::gyro_y_dph,
        &model::RunData::gyro_z_dph};
    for (std::size_t c = 0; c < std::size(numeric); ++c)
      if (!(in.*numeric[c]).empty()) (out.*numeric[c]).resize(m);
    if (in.has_phase()) out.phase.resize(m);
    if (in.has_step()) out.step.resize(m);
    if (in.has_power_on()) out.since_power_on_s.resize(m);
    if (in.has_compensated()) out.compensated_dph.resize(m);
    if (in.has_rate_in()) out.rate_in_dps.resize(m);
    if (in.has_axis_thermistors())
      for (std::size_t a = 0; a < 3; ++a) {
        out.axis_t1_c[a].resize(m);
        out.axis_t2_c[a].resize(m);
      }
    out.flags.assign(m, 0);
    bool any_gap = false;

    std::size_t j = 0;  // the last source sample at or before the grid time
    for (std::size_t k = 0; k < m; ++k) {
      const double t = t0 + static_cast<double>(k) * dt;
      out.time_s[k] = t;
      while (j + 1 < n && in.time_s[j + 1] <= t) ++j;
      double w = 0;
      bool in_gap = false;
      if (j + 1 < n) {
        const double width = in.time_s[j + 1] - in.time_s[j];
        w = std::clamp((t - in.time_s[j]) / width, 0.0, 1.0);
        in_gap = width > gap && w > 0;
      }
      bool touches_missing = false;
      for (std::size_t c = 0; c < std::size(numeric); ++c) {
        const auto& src = in.*numeric[c];
        if (src.empty()) continue;
        const double a = src[j];
        const double v = w == 0 ? a : a + w * (src[j + 1] - a);
        (out.*numeric[c])[k] = v;
        touches_missing = touches_missing || !std::isfinite(v);
      }
      if (in.has_axis_thermistors())
        for (std::size_t a = 0; a < 3; ++a)
          for (auto [src, dst] : {std::pair{&in.axis_t1_c[a], &out.axis_t1_c[a]}, std::pair{&in.axis_t2_c[a], &out.axis_t2_c[a]}}) {
            const double x = (*src)[j];
            const double v = w == 0 ? x : x + w * ((*src)[j + 1] - x);
            (*dst)[k] = v;
            touches_missing = touches_missing || !std::isfinite(v);
          }
      if (in.has_power_on()) {
        // Time since power-on runs at 1 s per s from the sample before, unless the gyro powered
        // on (again) before the next one: then back from the next. Unknown stays unknown and
        // is no missing reading.
        const double a = in.since_power_on_s[j];
        double v = a;
        if (w > 0) {
          const double b = in.since_power_on_s[j + 1];
          v = a + (t - in.time_s[j]);
          if (std::isfinite(b) && !(b > a)) {
            const double back = b - (in.time_s[j + 1] - t);
            if (back >= 0) v = back;
          }
        }
        out.since_power_on_s[k] = v;
      }
      if (in.has_compensated()) {
        // Interpolated like a reading, but none where either side has none (never a missing
        // reading: the daemon's own record, not a measurement).
        const double a = in.compensated_dph[j];
        out.compensated_dph[k] = w == 0 ? a : a + w * (in.compensated_dph[j + 1] - a);
      }
      if (in.has_phase()) out.phase[k] = in.phase[j];
      if (in.has_step()) out.step[k] = in.step[j];
      // The table's commanded rate holds until the next command: never interpolated.
      if (in.has_rate_in()) out.rate_in_dps[k] = in.rate_in_dps[j];
      std::uint8_t f = in.has_flags() ? in.flags[j] : 0;
      // A grid point interpolated towards a reading not taken is itself not taken, whatever
      // the flags of the sample before it say (found by the CSV fuzzer).
      if (touches_missing) {
        f |= model::flag::missing;
        any_gap = true;
      }
      if (in_gap) {
        f |= model::flag::missing;
        any_gap = true;
      }
      out.flags[k] = f;
    }
    if (!in.has_flags() && !any_gap) out.flags.clear();
    return out;
  }

  std::string_view text_;
  const CsvOptions& options_;
  std::string source_;
  std::size_t header_line_ = 0;
  std::vector<std::string> names_;  // the header's names, by field
  std::vector<int> role_of_;        // the Role of each field
  std::array<int, r_count> field_of_{};  // the 0-based field of each Role, -1 when absent
  model::RunData data_;
};

CsvError io_error(const std::filesystem::path& path, std::string what) {
  CsvError e;
  e.code = CsvErrc::io;
  e.source = path.string();
  e.message = "cannot " + what + " '" + path.string() + "': " + std::strerror(errno);
  return e;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

}  // namespace

const std::vector<std::string_view>& csv_columns() {
  static const std::vector<std::string_view> names(kNames.begin(), kNames.end());
  return names;
}

std::expected<ColumnMapping, CsvError> parse_column_mapping(std::string_view spec) {
  const std::size_t eq = spec.find('=');
  if (eq == std::string_view::npos || eq == 0 || eq + 1 == spec.size()) {
    CsvError e;
    e.code = CsvErrc::bad_option;
    e.message = "--map " + std::string(spec) +
                ": expected canonical=header, e.g. --map gyro_dph=Rate";
    return std::unexpected(std::move(e));
  }
  return ColumnMapping{std::string(trim(spec.substr(0, eq))),
                       std::string(trim(spec.substr(eq + 1)))};
}

std::expected<model::RunData, CsvError> parse_csv(std::string_view text,
                                                  const CsvOptions& options) {
  const char delimiter = options.delimiter.value_or(detail::detect_delimiter(text));
  if (delimiter != ',' && delimiter != ';' && delimiter != '\t') {
    CsvError e;
    e.code = CsvErrc::bad_option;
    e.source = options.source_name.empty() ? "<csv>" : options.source_name;
    e.message = e.source + ": --delimiter must be ',', ';' or tab ('\\t'), got '" + std::string(1, delimiter) + "'";
    return std::unexpected(std::move(e));
  }
  if (delimiter == ',' && options.decimal_comma) {
    CsvError e;
    e.code = CsvErrc::bad_option;
    e.source = options.source_name.empty() ? "<csv>" : options.source_name;
    e.message = e.source +
                ": --decimal-comma needs ';' or tab between the fields (--delimiter): with ',' a decimal comma cannot be "
                "told from the next field";
    return std::unexpected(std::move(e));
  }
  if (delimiter == ',') return Parser(text, options).run();
  // Another dialect: rewritten line for line into the plain one (csv_dialect.hpp).
  const std::string plain = detail::to_plain_csv(text, delimiter, options.decimal_comma);
  CsvOptions o = options;
  o.delimiter = delimiter;
  return Parser(plain, o).run();
}

std::expected<model::RunData, CsvError> read_csv_file(const std::filesystem::path& path,
                                                      const CsvOptions& options) {
  CsvOptions named = options;
  if (named.source_name.empty()) named.source_name = path.string();
  // A regular file is mapped rather than copied: a day's run is ~9 MB, and copying it costs
  // as much as parsing it. Anything else (a pipe, /dev/stdin) is read.
  {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return std::unexpected(io_error(path, "open"));
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      const auto size = static_cast<std::size_t>(st.st_size);
      void* p = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
      ::close(fd);
      if (p != MAP_FAILED) {
        auto r = parse_csv(std::string_view(static_cast<const char*>(p), size), named);
        ::munmap(p, size);
        return r;
      }
    } else {
      ::close(fd);
    }
  }
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) return std::unexpected(io_error(path, "open"));
  std::string text;
  std::error_code ec;
  if (const auto size = std::filesystem::file_size(path, ec); !ec)
    text.reserve(static_cast<std::size_t>(size));
  char buf[1 << 16];
  std::size_t got;
  while ((got = std::fread(buf, 1, sizeof buf, f.get())) > 0) text.append(buf, got);
  if (std::ferror(f.get())) return std::unexpected(io_error(path, "read"));
  return parse_csv(text, named);
}

std::string to_csv(const model::RunData& run) {
  const std::size_t n = run.size();
  auto fits = [n](const auto& column) { return column.empty() || column.size() == n; };
  assert(run.gyro_dph.size() == n && run.t1_c.size() == n && run.t2_c.size() == n);
  assert(fits(run.setpoint_c) && fits(run.chamber_c) && fits(run.phase) && fits(run.step) &&
         fits(run.flags) && fits(run.since_power_on_s) && fits(run.compensated_dph) &&
         fits(run.rate_in_dps) && fits(run.gyro_y_dph) && run.gyro_z_dph.size() == run.gyro_y_dph.size());
  (void)fits;

  std::string out = "time_s,gyro_dph,t1_c,t2_c";
  if (run.has_setpoint()) out += ",setpoint_c";
  if (run.has_chamber()) out += ",chamber_c";
  if (run.has_phase()) out += ",phase";
  if (run.has_step()) out += ",step";
  if (run.has_flags()) out += ",flags";
  if (run.has_power_on()) out += ",since_power_on_s";
  if (run.has_compensated()) out += ",compensated_dph";
  if (run.has_axes()) out += ",gyro_y_dph,gyro_z_dph";  // a three-axis unit's y and z only
  // Its axes' own thermistors, where they have them (x's are t1_c, t2_c).
  const bool axis_temps = run.has_axes() && run.has_axis_thermistors();
  if (axis_temps) out += ",t1_y_c,t2_y_c,t1_z_c,t2_z_c";
  // A run that drove the rate table: the rate-sequence columns of `fogctl scale-factor`
  // (cli/scale_factor.hpp), the plateau being the profile step. parse_csv reads them back.
  if (run.has_rate_in()) out += ",plateau,rate_in_dps,rate_out_dps";
  out += '\n';
  out.reserve(out.size() + n * 96);

  char buf[64];
  // A measurement the daemon could not take is NaN in memory and an empty cell in the file;
  // parse_csv accepts the empty cell only on a row flagged missing.
  auto put = [&](auto v) {
    if constexpr (std::is_floating_point_v<decltype(v)>) {
      if (!std::isfinite(v)) return;
    }
    auto res = std::to_chars(buf, buf + sizeof buf, v);
    out.append(buf, res.ptr);
  };
  for (std::size_t i = 0; i < n; ++i) {
    put(run.time_s[i]);
    out += ',';
    put(run.gyro_dph[i]);
    out += ',';
    put(run.t1_c[i]);
    out += ',';
    put(run.t2_c[i]);
    if (run.has_setpoint()) {
      out += ',';
      put(run.setpoint_c[i]);
    }
    if (run.has_chamber()) {
      out += ',';
      put(run.chamber_c[i]);
    }
    if (run.has_phase()) {
      out += ',';
      out += model::to_string(run.phase[i]);
    }
    if (run.has_step()) {
      out += ',';
      put(run.step[i]);
    }
    if (run.has_flags()) {
      out += ',';
      put(static_cast<unsigned>(run.flags[i]));
    }
    if (run.has_power_on()) {
      out += ',';
      put(run.since_power_on_s[i]);  // empty where the power-on was not known
    }
    if (run.has_compensated()) {
      out += ',';
      put(run.compensated_dph[i]);  // empty where the daemon computed none
    }
    if (run.has_axes()) {
      out += ',';
      put(run.gyro_y_dph[i]);  // empty where the axis sent nothing usable (flag missing)
      out += ',';
      put(run.gyro_z_dph[i]);
    }
    if (axis_temps)
      for (const auto* col : {&run.axis_t1_c[1], &run.axis_t2_c[1], &run.axis_t1_c[2], &run.axis_t2_c[2]}) {
        out += ',';
        put((*col)[i]);  // empty where the thermistor was not read (flag missing)
      }
    if (run.has_rate_in()) {
      out += ',';
      if (run.has_step()) put(run.step[i]);
      out += ',';
      put(run.rate_in_dps[i]);
      out += ',';
      put(run.gyro_dph[i] / 3600.0);  // deg/h -> deg/s; empty where the gyro was not read
    }
    out += '\n';
  }
  return out;
}

std::expected<void, CsvError> write_csv_file(const std::filesystem::path& path,
                                             const model::RunData& run) {
  const std::string text = to_csv(run);
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "wb"));
  if (!f) return std::unexpected(io_error(path, "create"));
  if (std::fwrite(text.data(), 1, text.size(), f.get()) != text.size())
    return std::unexpected(io_error(path, "write"));
  // fclose flushes the last buffer; its failure (a full disk) is a failed write too.
  if (std::fclose(f.release()) != 0) return std::unexpected(io_error(path, "write"));
  return {};
}

}  // namespace fogbench::storage
