// The CSV form of a recorded run (fogctl's import and export format), read into and written
// from model::RunData. The format and every error are described in docs/csv.md.
#pragma once

#include <cstddef>
#include <expected>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/model/run.hpp"

namespace fogbench::storage {

// What went wrong, for callers that react to the kind of failure (the message is for people).
enum class CsvErrc {
  io,                   // the file cannot be read or written
  bad_option,           // a CsvOptions value is invalid: a column map entry, resample_s, delimiter
  empty,                // no header row: the file is empty or holds only comments
  duplicate_column,     // two header fields with the same name
  missing_column,       // required (or explicitly mapped) columns not in the header: all named
  field_count,          // a data row with fewer or more fields than the header
  bad_quote,            // a quoted field that is not closed on its line
  not_a_number,         // a cell that is not a number (or not an integer for step and flags)
  not_finite,           // a cell that is nan or inf, or overflows a double
  bad_value,            // a value outside its domain: unknown phase, flags > 255, huge step
  no_data,              // a header but no data rows
  time_not_increasing,  // a time_s not greater than the previous row's
  time_uneven,          // a time step off the median step by more than 1% (and no resampling)
};
std::string_view to_string(CsvErrc code);

// A failure with its place. `message` is complete and self-contained, e.g.
//   run.csv:12: column 2 'gyro_dph': not a number: '1.2.3'
struct CsvError {
  CsvErrc code = CsvErrc::io;
  std::string source;       // the file name (or CsvOptions::source_name)
  std::size_t line = 0;     // 1-based physical line in the file; 0 when not about one line
  std::size_t column = 0;   // 1-based field index in the row; 0 when not about one field
  std::string column_name;  // the file's header name of that field; empty when none
  std::string message;
};

// One `--map canonical=header` entry: the file calls the column `canonical` by `header`.
struct ColumnMapping {
  std::string canonical;  // time_s, gyro_dph, t1_c, t2_c, setpoint_c, chamber_c, phase, step, flags
  std::string header;     // the name in the file's header row
};

// Parses "gyro_dph=Rate" (the argument of fogctl's --map). Errors are CsvErrc::bad_option.
std::expected<ColumnMapping, CsvError> parse_column_mapping(std::string_view spec);

struct CsvOptions {
  // Names the input in messages and becomes RunData::name; read_csv_file uses the path when
  // this is empty, parse_csv uses "<csv>".
  std::string source_name;
  // Columns the file names differently; each canonical name at most once.
  std::vector<ColumnMapping> column_map;
  // When set (> 0, s), unevenly spaced time is accepted and every column is resampled onto
  // time_s[0] + k * resample_s: numbers linearly, phase/step/flags from the nearest previous
  // sample. Grid points inside a gap wider than 1.5 median steps get flag::missing, because
  // interpolating across a gap invents data. When unset, uneven time is an error.
  std::optional<double> resample_s;
  // Optional columns (setpoint_c, chamber_c, phase, step, flags) not to read even when the file
  // has them: a caller that does not use them saves their parsing (and their checks).
  std::vector<std::string> skip;
  // The field separator: ',', ';' or '\t'. Unset: detected from the header row where that is
  // unambiguous (';' when it has no ',', tab when it has neither), else ','.
  std::optional<char> delimiter;
  // Numbers written with a decimal comma (1,5): only with a ';' or tab separator.
  bool decimal_comma = false;
  // time_s is multiplied by this as it is read, before the spacing check and resampling:
  // 1e-3 reads a time column written in milliseconds (fogctl --time-unit ms).
  double time_scale = 1.0;
};

// The canonical column names, required first: time_s, gyro_dph, t1_c, t2_c, then the optional
// setpoint_c, chamber_c, since_power_on_s, compensated_dph, phase, step, flags.
const std::vector<std::string_view>& csv_columns();

// Parses a whole CSV text. Never throws; every problem in the text is a CsvError.
std::expected<model::RunData, CsvError> parse_csv(std::string_view text, const CsvOptions& options);

// Reads the whole file and parses it; a missing or unreadable file is a CsvErrc::io error
// naming the path.
std::expected<model::RunData, CsvError> read_csv_file(const std::filesystem::path& path,
                                                      const CsvOptions& options = {});

// Writes the header and one row per sample: the four required columns, then each optional
// column the run has. Numbers are written in the shortest form that reads back to the same
// double, so parse_csv(to_csv(run)) reproduces run exactly (apart from RunData::name).
// A non-finite value is written as nan/inf, which parse_csv rejects: such a run is not valid
// input. Precondition (asserted): every non-empty column has run.size() elements.
std::string to_csv(const model::RunData& run);

// Writes to_csv(run) to `path` (replacing it). Errors are CsvErrc::io naming the path.
std::expected<void, CsvError> write_csv_file(const std::filesystem::path& path,
                                             const model::RunData& run);

}  // namespace fogbench::storage
