// The profile text parser: one statement per line, `#` comments, checked units, and errors
// that point at the line and column of the offending word.
#include <charconv>
#include <cmath>
#include <optional>
#include <system_error>

#include "detail.hpp"
#include "fogbench/profiles/profile.hpp"

namespace fogbench::profiles {
namespace {

struct Token {
  std::string_view text;
  int column;  // 1-based byte column
};

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Length of the number at the start of s (-?digits(.digits)?), 0 if there is none.
std::size_t number_prefix(std::string_view s) {
  std::size_t i = 0;
  if (i < s.size() && s[i] == '-') ++i;
  const std::size_t digits_from = i;
  while (i < s.size() && is_digit(s[i])) ++i;
  if (i == digits_from) return 0;
  if (i + 1 < s.size() && s[i] == '.' && is_digit(s[i + 1])) {
    ++i;
    while (i < s.size() && is_digit(s[i])) ++i;
  }
  return i;
}

// Splits the code part of a line into words. A word that starts with a number is split
// after it, so that "20C" and "1C/min", natural to type by hand, read as "20 C", "1 C/min".
std::vector<Token> tokenize(std::string_view code) {
  std::vector<Token> out;
  std::size_t i = 0;
  while (i < code.size()) {
    if (is_space(code[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < code.size() && !is_space(code[j])) ++j;
    const std::string_view word = code.substr(i, j - i);
    const std::size_t n = number_prefix(word);
    if (n > 0 && n < word.size()) {
      out.push_back({word.substr(0, n), static_cast<int>(i) + 1});
      out.push_back({word.substr(n), static_cast<int>(i + n) + 1});
    } else {
      out.push_back({word, static_cast<int>(i) + 1});
    }
    i = j;
  }
  return out;
}

std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

// A number with the token it came from, so later messages can quote it as written.
struct Value {
  double v;
  Token tok;
};

using Unexpected = std::unexpected<ProfileError>;

// Parses the statement on one line. Holds the tokens and a cursor; every method that can
// fail returns the error ready to hand back.
class LineParser {
 public:
  LineParser(std::string_view source, int line_no, std::string_view line)
      : source_(source), line_no_(line_no), line_(line) {
    const auto hash = line.find('#');
    tokens_ = tokenize(line.substr(0, hash));
  }

  bool empty() const { return tokens_.empty(); }
  const Token& first() const { return tokens_.front(); }

  ProfileError error(int column, std::string message) const {
    return ProfileError{std::string(source_), line_no_, column, std::move(message),
                        std::string(line_)};
  }

  std::expected<Step, ProfileError> statement(double setpoint_c, bool have_setpoint) {
    Step step;
    step.line = line_no_;
    step.text = std::string(line_);
    const Token kw = next();
    if (kw.text == "setpoint") {
      auto t = temperature(kw);
      if (!t) return Unexpected(t.error());
      step.action = SetpointStep{t->v, t->tok.column};
    } else if (kw.text == "hold") {
      auto d = duration(kw);
      if (!d) return Unexpected(d.error());
      step.action = HoldStep{d->v};
    } else if (kw.text == "ramp") {
      auto r = ramp(kw, setpoint_c, have_setpoint);
      if (!r) return Unexpected(r.error());
      step.action = *r;
    } else if (kw.text == "settle") {
      auto s = settle(kw);
      if (!s) return Unexpected(s.error());
      step.action = *s;
    } else {
      return Unexpected(error(kw.column, "unknown statement " + quoted(kw.text) +
                                             "; expected 'setpoint', 'hold', 'ramp', 'settle' or 'rate'"));
    }
    if (pos_ < tokens_.size()) {
      return Unexpected(error(tokens_[pos_].column,
                              "unexpected " + quoted(tokens_[pos_].text) +
                                  " after the end of the '" + std::string(kw.text) +
                                  "' statement"));
    }
    return step;
  }

  // A `rate` line (its first word is "rate").
  std::expected<RateStep, ProfileError> rate() {
    const Token kw = next();
    return rate_step(kw);
  }

 private:
  Token next() { return tokens_[pos_++]; }
  bool at_end() const { return pos_ >= tokens_.size(); }

  // Where a missing word would go: just past the last one.
  int end_column() const {
    const Token& last = tokens_.back();
    return last.column + static_cast<int>(last.text.size());
  }
  std::string found() const { return at_end() ? "end of line" : quoted(tokens_[pos_].text); }
  int found_column() const { return at_end() ? end_column() : tokens_[pos_].column; }

  ProfileError expected_after(std::string_view what, const Token& after) const {
    return error(found_column(), "expected " + std::string(what) + " after " +
                                     quoted(after.text) + ", found " + found());
  }

  std::expected<Token, ProfileError> keyword(std::string_view kw, const Token& after) {
    if (at_end() || tokens_[pos_].text != kw) return Unexpected(expected_after(quoted(kw), after));
    return next();
  }

  std::expected<Value, ProfileError> number(std::string_view what, const Token& after) {
    if (at_end()) return Unexpected(expected_after(what, after));
    const Token t = tokens_[pos_];
    double v = 0.0;
    const char* first = t.text.data();
    const char* last = first + t.text.size();
    // number_prefix decides what a number is (no exponents, no leading '+' or '.'), so that
    // from_chars' wider grammar does not leak into the format.
    if (number_prefix(t.text) != t.text.size()) return Unexpected(expected_after(what, after));
    const auto r = std::from_chars(first, last, v);
    if (r.ec != std::errc{} || r.ptr != last || !std::isfinite(v)) {
      return Unexpected(expected_after(what, after));
    }
    ++pos_;
    return Value{v, t};
  }

  std::expected<Value, ProfileError> positive(std::string_view what, std::string_view rule,
                                              const Token& after) {
    auto n = number(what, after);
    if (!n) return n;
    if (!(n->v > 0.0)) {
      return Unexpected(error(n->tok.column, std::string(rule) + ", found " + quoted(n->tok.text)));
    }
    return n;
  }

  // "C" or "degC" after a number. Temperature differences (a band) use the same unit.
  std::expected<void, ProfileError> temp_unit(const Token& number_tok) {
    if (!at_end() && (tokens_[pos_].text == "C" || tokens_[pos_].text == "degC")) {
      ++pos_;
      return {};
    }
    return Unexpected(expected_after("a temperature unit 'C'", number_tok));
  }

  std::expected<Value, ProfileError> temperature(const Token& after) {
    auto t = number("a temperature", after);
    if (!t) return t;
    if (auto u = temp_unit(t->tok); !u) return Unexpected(u.error());
    return t;
  }

  // A positive duration in s, min or h; the value returned is in s.
  std::expected<Value, ProfileError> duration(const Token& after) {
    auto d = positive("a duration", "a duration must be positive", after);
    if (!d) return d;
    double scale_s = 0.0;
    if (!at_end()) {
      const auto u = tokens_[pos_].text;
      scale_s = u == "s" ? 1.0 : u == "min" ? 60.0 : u == "h" ? 3600.0 : 0.0;
    }
    if (scale_s == 0.0) {
      return Unexpected(expected_after("a duration unit 's', 'min' or 'h'", d->tok));
    }
    ++pos_;
    d->v *= scale_s;
    return d;
  }

  // A positive rate in C/min or C/h; the value returned is in degC/min.
  std::expected<Value, ProfileError> rate(std::string_view rule, const Token& after) {
    auto r = positive("a rate", rule, after);
    if (!r) return r;
    double min_per_unit = 0.0;  // divide, so that 180 C/h is exactly 3 degC/min
    if (!at_end()) {
      const auto u = tokens_[pos_].text;
      if (u == "C/min" || u == "degC/min") min_per_unit = 1.0;
      if (u == "C/h" || u == "degC/h") min_per_unit = 60.0;
    }
    if (min_per_unit == 0.0) {
      return Unexpected(expected_after("a rate unit 'C/min' or 'C/h'", r->tok));
    }
    ++pos_;
    r->v /= min_per_unit;
    return r;
  }

  // `rate <r> dps|deg/s for <d>`: the keyword already read. The rate may be negative (the
  // other direction) or 0 (at rest); a leading '+' is taken.
  std::expected<RateStep, ProfileError> rate_step(const Token& kw) {
    RateStep r;
    r.line = line_no_;
    r.text = std::string(line_);
    if (!at_end() && tokens_[pos_].text.size() > 1 && tokens_[pos_].text.front() == '+') {
      Token& t = tokens_[pos_];
      t.text.remove_prefix(1);
      ++t.column;
      if (t.text.front() == '-') return Unexpected(expected_after("a rate in deg/s", kw));
      // "+100dps" as typed: split the unit off as the tokenizer does for an unsigned number.
      // The insert may move the tokens: `t` is not used after it.
      const std::size_t n = number_prefix(t.text);
      if (n > 0 && n < t.text.size()) {
        const Token unit{t.text.substr(n), t.column + static_cast<int>(n)};
        t.text = t.text.substr(0, n);
        tokens_.insert(tokens_.begin() + static_cast<std::ptrdiff_t>(pos_) + 1, unit);
      }
    }
    auto v = number("a table rate in deg/s", kw);
    if (!v) return Unexpected(v.error());
    r.rate_dps = v->v;
    r.rate_column = v->tok.column;
    if (at_end() || (tokens_[pos_].text != "dps" && tokens_[pos_].text != "deg/s")) {
      return Unexpected(expected_after("a table rate unit 'dps' or 'deg/s'", v->tok));
    }
    const Token unit = next();
    auto f = keyword("for", unit);
    if (!f) return Unexpected(f.error());
    auto d = duration(*f);
    if (!d) return Unexpected(d.error());
    r.duration_s = d->v;
    if (pos_ < tokens_.size()) {
      return Unexpected(error(tokens_[pos_].column, "unexpected " + quoted(tokens_[pos_].text) +
                                                        " after the end of the 'rate' statement"));
    }
    return r;
  }

  std::expected<RampStep, ProfileError> ramp(const Token& kw, double setpoint_c,
                                             bool have_setpoint) {
    auto to = keyword("to", kw);
    if (!to) return Unexpected(to.error());
    auto target = temperature(*to);
    if (!target) return Unexpected(target.error());
    const Token unit = tokens_[pos_ - 1];
    auto at = keyword("at", unit);
    if (!at) return Unexpected(at.error());
    auto r = rate("a ramp rate must be positive (the direction comes from the target)", *at);
    if (!r) return Unexpected(r.error());
    // A ramp that goes nowhere is almost surely a typo for another target.
    if (have_setpoint && target->v == setpoint_c) {
      return Unexpected(error(target->tok.column,
                              "this ramp does not move the setpoint: it is already " +
                                  detail::format_number(setpoint_c) + " degC here"));
    }
    return RampStep{target->v, r->v, target->tok.column, r->tok.column};
  }

  std::expected<SettleStep, ProfileError> settle(const Token& kw) {
    SettleStep s;
    auto within = keyword("within", kw);
    if (!within) return Unexpected(within.error());
    auto band = positive("a temperature band", "a settle band must be positive", *within);
    if (!band) return Unexpected(band.error());
    if (auto u = temp_unit(band->tok); !u) return Unexpected(u.error());
    s.band_c = band->v;

    // The optional clauses may come in any order, each at most once: a hand-written line
    // reads naturally either way.
    std::optional<Token> on_kw, slope_kw, for_kw, timeout_kw;
    std::optional<Value> for_value, timeout_value;
    while (!at_end()) {
      const Token c = next();
      std::optional<Token>* seen = c.text == "on"        ? &on_kw
                                   : c.text == "slope"   ? &slope_kw
                                   : c.text == "for"     ? &for_kw
                                   : c.text == "timeout" ? &timeout_kw
                                                         : nullptr;
      if (seen == nullptr) {
        return Unexpected(error(c.column, "unexpected " + quoted(c.text) +
                                              " in 'settle'; expected 'on', 'slope', 'for' "
                                              "or 'timeout'"));
      }
      if (seen->has_value()) {
        return Unexpected(error(c.column, quoted(c.text) + " given twice in one 'settle' (first at column " +
                                              std::to_string((*seen)->column) + ")"));
      }
      *seen = c;
      if (c.text == "on") {
        const auto what = at_end() ? std::string_view{} : tokens_[pos_].text;
        if (what == "chamber" || what == "coil") {
          s.on = what == "coil" ? SettleOn::coil : SettleOn::chamber;
          ++pos_;
        } else {
          return Unexpected(expected_after("'chamber' or 'coil'", c));
        }
      } else if (c.text == "slope") {
        auto r = rate("a slope limit must be positive", c);
        if (!r) return Unexpected(r.error());
        s.max_slope_c_per_min = r->v;
      } else if (c.text == "for") {
        auto d = duration(c);
        if (!d) return Unexpected(d.error());
        s.stable_s = d->v;
        for_value = *d;
      } else {
        auto d = duration(c);
        if (!d) return Unexpected(d.error());
        s.timeout_s = d->v;
        timeout_value = *d;
      }
    }
    if (!for_value) {
      return Unexpected(error(end_column(),
                              "'settle' needs 'for <duration>': how long the reading must stay "
                              "settled"));
    }
    const double timeout_s = timeout_value ? timeout_value->v : default_settle_timeout_s;
    if (timeout_s < s.stable_s) {
      const int column = timeout_value ? timeout_value->tok.column : for_value->tok.column;
      return Unexpected(error(
          column, "the settle can never be met: its timeout (" + detail::format_number(timeout_s) +
                      " s) is shorter than its 'for' time (" +
                      detail::format_number(s.stable_s) + " s)"));
    }
    return s;
  }

  std::string_view source_;
  int line_no_;
  std::string_view line_;
  std::vector<Token> tokens_;
  std::size_t pos_ = 0;
};

}  // namespace

std::expected<Profile, ProfileError> parse_profile(std::string_view text,
                                                   std::string_view source_name) {
  Profile profile;
  profile.source_name = std::string(source_name);
  double setpoint_c = 0.0;  // tracked so that a ramp that goes nowhere can be refused
  double plateau_used_s = 0.0;  // the rate steps' time so far in the last temperature step, s
  int line_no = 0;
  std::string_view first_line;
  std::size_t from = 0;
  while (from < text.size()) {
    auto to = text.find('\n', from);
    if (to == std::string_view::npos) to = text.size();
    std::string_view line = text.substr(from, to - from);
    from = to + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++line_no;
    if (line_no == 1) first_line = line;

    LineParser p(source_name, line_no, line);
    if (p.empty()) continue;
    if (p.first().text == "rate") {
      auto r = p.rate();
      if (!r) return Unexpected(r.error());
      if (profile.steps.empty()) {
        return Unexpected(p.error(p.first().column, "a profile must open with 'setpoint <T> C', found 'rate'"));
      }
      // The plateau: the hold this line follows, with only rate lines between.
      const std::size_t plateau = profile.steps.size() - 1;
      const Step& last = profile.steps.back();
      const auto* hold = std::get_if<HoldStep>(&last.action);
      if (hold == nullptr) {
        return Unexpected(p.error(p.first().column,
                                  "a rate step runs during a temperature plateau: put it after a 'hold' (line " +
                                      std::to_string(last.line) + " is a '" + std::string(to_string(last.kind())) +
                                      "')"));
      }
      const double used_s = plateau_used_s;
      if (used_s + r->duration_s > hold->duration_s) {
        return Unexpected(p.error(
            p.first().column, "the rate sequence does not fit in its plateau: " + detail::format_number(used_s) +
                                  " s before this step and its " + detail::format_number(r->duration_s) +
                                  " s exceed the hold of " + detail::format_number(hold->duration_s) +
                                  " s on line " + std::to_string(last.line)));
      }
      r->plateau = plateau;
      plateau_used_s += r->duration_s;
      profile.rate_steps.push_back(std::move(*r));
      continue;
    }
    auto step = p.statement(setpoint_c, !profile.steps.empty());
    if (!step) return Unexpected(step.error());
    // The executor commands a setpoint from the first moment; only a setpoint defines it.
    if (profile.steps.empty() && step->kind() != StepKind::setpoint) {
      return Unexpected(p.error(p.first().column,
                                "a profile must open with 'setpoint <T> C', found " +
                                    quoted(p.first().text)));
    }
    if (const auto* s = std::get_if<SetpointStep>(&step->action)) setpoint_c = s->temp_c;
    if (const auto* r = std::get_if<RampStep>(&step->action)) setpoint_c = r->target_c;
    profile.steps.push_back(std::move(*step));
    plateau_used_s = 0.0;  // a new temperature step: a new plateau for the rate lines after it
  }
  if (profile.steps.empty()) {
    return Unexpected(ProfileError{std::string(source_name), 1, 1,
                                   "the profile has no statements; it must open with "
                                   "'setpoint <T> C'",
                                   std::string(first_line)});
  }
  return profile;
}

}  // namespace fogbench::profiles
