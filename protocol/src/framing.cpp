// The line splitter of the command protocol.
#include "fogbench/protocol/framing.hpp"

#include <algorithm>
#include <set>
#include <vector>

namespace fogbench::protocol {

namespace {

using nlohmann::json;

// The 1-based column of the bracket that opens level max_depth + 1, counting '[' and '{'
// outside strings. Called only once the parser has met that level, so the line's prefix up to
// it is valid JSON and the count is exact.
std::size_t column_past_depth(std::string_view line, std::size_t max_depth) {
  std::size_t depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (in_string) {
      if (c == '\\') ++i;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i + 1;
    } else if (c == ']' || c == '}') {
      if (depth > 0) --depth;
    }
  }
  return line.size();
}

// nlohmann's DOM builder behind a gate: each event is checked first and the parse stops (false)
// at a level past the limit or a key seen twice in the same object.
class CheckedSax {
 public:
  CheckedSax(json& out, std::size_t max_depth) : dom_(out, false), max_depth_(max_depth) {}

  bool null() { return dom_.null(); }
  bool boolean(bool v) { return dom_.boolean(v); }
  bool number_integer(json::number_integer_t v) { return dom_.number_integer(v); }
  bool number_unsigned(json::number_unsigned_t v) { return dom_.number_unsigned(v); }
  bool number_float(json::number_float_t v, const json::string_t& s) { return dom_.number_float(v, s); }
  bool string(json::string_t& v) { return dom_.string(v); }
  bool binary(json::binary_t& v) { return dom_.binary(v); }

  bool start_object(std::size_t n) {
    if (!enter()) return false;
    levels_.push_back(Level{true, {}, {}});
    return dom_.start_object(n);
  }
  bool key(json::string_t& k) {
    Level& l = levels_.back();
    if (!l.keys.insert(k).second) {
      l.key = k;
      problem_ = "duplicate key \"" + k + "\"" + where();
      return false;
    }
    l.key = k;
    return dom_.key(k);
  }
  bool end_object() {
    levels_.pop_back();
    return dom_.end_object();
  }
  bool start_array(std::size_t n) {
    if (!enter()) return false;
    levels_.push_back(Level{false, {}, {}});
    return dom_.start_array(n);
  }
  bool end_array() {
    levels_.pop_back();
    return dom_.end_array();
  }
  bool parse_error(std::size_t pos, const std::string& token, const nlohmann::detail::exception& e) {
    return dom_.parse_error(pos, token, e);
  }

  const std::string& problem() const { return problem_; }
  bool too_deep() const { return too_deep_; }

 private:
  struct Level {
    bool object;
    std::set<std::string> keys;  // an object's keys so far
    std::string key;             // the key whose value is being read
  };

  bool enter() {
    if (levels_.size() >= max_depth_) {
      too_deep_ = true;
      return false;
    }
    return true;
  }
  // Where a duplicate is, as the path of keys from the request object: "" for the request
  // object itself, else ` in "x"."y"` (array levels add nothing: their index is not tracked).
  std::string where() const {
    std::string path;
    for (std::size_t i = 0; i + 1 < levels_.size(); ++i)
      if (levels_[i].object) path += (path.empty() ? "\"" : ".\"") + levels_[i].key + "\"";
    return path.empty() ? std::string() : " in " + path;
  }

  nlohmann::detail::json_sax_dom_parser<json> dom_;
  std::size_t max_depth_;
  std::vector<Level> levels_;
  std::string problem_;
  bool too_deep_ = false;
};

}  // namespace

std::expected<json, std::string> parse_line(std::string_view line, std::size_t max_depth) {
  json out;
  CheckedSax sax(out, max_depth);
  bool ok = false;
  try {
    ok = json::sax_parse(line, &sax, json::input_format_t::json, true, false);
  } catch (const json::exception&) {
    ok = false;
  }
  if (ok && !out.is_discarded()) return out;
  // `out` holds what was built before the stop: at most max_depth levels, safe to destroy.
  if (sax.too_deep())
    return std::unexpected("nesting deeper than " + std::to_string(max_depth) + " levels at column " +
                           std::to_string(column_past_depth(line, max_depth)));
  if (!sax.problem().empty()) return std::unexpected(sax.problem());
  return std::unexpected(std::string("not a JSON value"));
}

LineSplitter::Status LineSplitter::next(std::string& out) {
  if (spent_) return Status::too_long;
  // The search resumes where the last one stopped: a long line arriving in many reads is
  // scanned once, not once per read (O(n), not O(n^2) for a 64 MiB message).
  const auto nl = buffer_.find('\n', std::max(start_, scanned_));
  if (nl == std::string::npos) {
    if (buffer_.size() - start_ > max_) {
      spent_ = true;
      buffer_.clear();
      start_ = scanned_ = 0;
      return Status::too_long;
    }
    // Compact only when nothing is pending from the front, so a burst of lines is O(n).
    if (start_ > 0) {
      buffer_.erase(0, start_);
      start_ = 0;
    }
    scanned_ = buffer_.size();
    return Status::incomplete;
  }
  std::size_t len = nl - start_;
  if (len > max_) {
    spent_ = true;
    buffer_.clear();
    start_ = scanned_ = 0;
    return Status::too_long;
  }
  if (len > 0 && buffer_[nl - 1] == '\r') --len;
  out.assign(buffer_, start_, len);
  start_ = nl + 1;
  scanned_ = start_;
  return Status::line;
}

}  // namespace fogbench::protocol
