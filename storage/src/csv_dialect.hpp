// CSV dialects other than fogbench's own (',' between fields, '.' in numbers): ';' or tab
// between fields, as spreadsheets in many locales write, with or without a decimal comma. Such
// a text is rewritten into the plain dialect, line for line (line numbers and field numbers
// stay those of the file), and parsed as usual.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace fogbench::storage::detail {

// The field separator of a text, from its header row (its first line that is neither blank nor
// a comment): ';' when it has ';' and no ',' outside quotes, tab when it has tabs and neither
// ',' nor ';'; else ','. Unambiguous cases only: a header with both ',' and ';' is ','.
char detect_delimiter(std::string_view text);

// The text in the plain dialect: `delimiter` becomes ','; with decimal_comma a ',' in a data
// cell becomes '.'; a cell that still holds a ',' (a header name, a number with a comma when
// decimal_comma is off) is quoted so that it stays one field. Comments and blank lines are kept.
std::string to_plain_csv(std::string_view text, char delimiter, bool decimal_comma);

}  // namespace fogbench::storage::detail
