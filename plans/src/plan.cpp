// The plan text parser (docs/plans.md): one statement per line, `#` comments, errors that point
// at the line and column of the offending word, as the profile parser does.
#include <array>
#include <charconv>
#include <cmath>
#include <map>
#include <system_error>

#include "fogbench/model/terms.hpp"
#include "fogbench/plans/plan.hpp"

namespace fogbench::plans {

std::string_view to_string(StepPurpose p) {
  switch (p) {
    case StepPurpose::fit: return "fit";
    case StepPurpose::verify: return "verify";
    case StepPurpose::soak: return "soak";
    case StepPurpose::custom: return "custom";
  }
  return "?";
}

std::optional<StepPurpose> step_purpose_from_string(std::string_view s) {
  for (auto p : {StepPurpose::fit, StepPurpose::verify, StepPurpose::soak, StepPurpose::custom})
    if (to_string(p) == s) return p;
  return std::nullopt;
}

namespace {
constexpr std::array kMeasurements = {Measurement::comp_raw,       Measurement::noise_factor,
                                      Measurement::fail_s,         Measurement::peak_excursion,
                                      Measurement::sensitivity,    Measurement::arw,
                                      Measurement::bias_instability, Measurement::firmware,
                                      Measurement::sf_tc_ppm_per_c, Measurement::sf_nonlinearity_ppm,
                                      Measurement::sf_asymmetry_ppm};
}

std::string_view to_string(Measurement m) {
  switch (m) {
    case Measurement::comp_raw: return "comp_raw";
    case Measurement::noise_factor: return "noise_factor";
    case Measurement::fail_s: return "fail_s";
    case Measurement::peak_excursion: return "peak_excursion";
    case Measurement::sensitivity: return "sensitivity";
    case Measurement::arw: return "arw";
    case Measurement::bias_instability: return "bias_instability";
    case Measurement::firmware: return "firmware";
    case Measurement::sf_tc_ppm_per_c: return "sf_tc_ppm_per_c";
    case Measurement::sf_nonlinearity_ppm: return "sf_nonlinearity_ppm";
    case Measurement::sf_asymmetry_ppm: return "sf_asymmetry_ppm";
  }
  return "?";
}

bool measured_in(Measurement m, StepPurpose p) {
  switch (m) {
    case Measurement::comp_raw:
    case Measurement::noise_factor:
    case Measurement::fail_s:
    case Measurement::peak_excursion: return p == StepPurpose::verify;
    case Measurement::sensitivity:
    case Measurement::firmware: return p == StepPurpose::fit;
    case Measurement::arw:
    case Measurement::bias_instability: return p == StepPurpose::fit || p == StepPurpose::soak;
    case Measurement::sf_tc_ppm_per_c:
    case Measurement::sf_nonlinearity_ppm:
    case Measurement::sf_asymmetry_ppm: return p == StepPurpose::fit || p == StepPurpose::verify;
  }
  return false;
}

bool needs_rate_steps(Measurement m) {
  return m == Measurement::sf_tc_ppm_per_c || m == Measurement::sf_nonlinearity_ppm || m == Measurement::sf_asymmetry_ppm;
}

std::string_view unit_of(Measurement m) {
  switch (m) {
    case Measurement::fail_s: return "s";
    case Measurement::peak_excursion:
    case Measurement::bias_instability: return "deg/h";
    case Measurement::arw: return "deg/sqrt(h)";
    case Measurement::sf_tc_ppm_per_c: return "ppm/degC";
    case Measurement::sf_nonlinearity_ppm:
    case Measurement::sf_asymmetry_ppm: return "ppm";
    default: return "";
  }
}

std::string_view to_string(OnFail a) {
  switch (a) {
    case OnFail::stop: return "stop";
    case OnFail::go_on: return "continue";
    case OnFail::retest: return "retest";
  }
  return "?";
}

namespace {
std::string number(double v) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
}
}  // namespace

std::string Limit::name() const {
  std::string n(to_string(measurement));
  if (measurement == Measurement::sensitivity) n += " " + term;
  return n;
}

std::string Limit::describe() const {
  static constexpr std::array<const char*, 4> ops = {"<", "<=", ">", ">="};
  std::string u(unit_of(measurement));
  u = u.empty() ? "" : " " + u;
  if (compare == Compare::required) return name() + " required";
  if (compare == Compare::within) return name() + " within " + number(value) + " .. " + number(high) + u;
  return name() + " " + ops[static_cast<std::size_t>(compare)] + " " + number(value) + u;
}

bool Limit::met(double v) const {
  if (!std::isfinite(v)) return false;
  switch (compare) {
    case Compare::lt: return v < value;
    case Compare::le: return v <= value;
    case Compare::gt: return v > value;
    case Compare::ge: return v >= value;
    case Compare::within: return v >= value && v <= high;
    case Compare::required: return v >= 1.0;
  }
  return false;
}

std::string PlanError::to_string() const {
  if (line <= 0) return source + ": " + message;
  return source + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message;
}

std::string PlanError::excerpt() const {
  if (line <= 0) return {};
  std::string caret;
  for (int i = 0; i + 1 < column; ++i) {
    const auto u = static_cast<std::size_t>(i);
    caret += (u < line_text.size() && line_text[u] == '\t') ? '\t' : ' ';
  }
  return line_text + "\n" + caret + "^";
}

namespace {

struct Token {
  std::string_view text;
  int column;
};

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

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
    out.push_back({code.substr(i, j - i), static_cast<int>(i) + 1});
    i = j;
  }
  return out;
}

// -?digits(.digits)? exactly, as in profiles.
std::optional<double> parse_number(std::string_view s) {
  std::size_t i = 0;
  if (i < s.size() && s[i] == '-') ++i;
  const std::size_t from = i;
  while (i < s.size() && s[i] >= '0' && s[i] <= '9') ++i;
  if (i == from) return std::nullopt;
  if (i < s.size() && s[i] == '.') {
    const std::size_t d = ++i;
    while (i < s.size() && s[i] >= '0' && s[i] <= '9') ++i;
    if (i == d) return std::nullopt;
  }
  if (i != s.size()) return std::nullopt;
  double v = 0.0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || !std::isfinite(v)) return std::nullopt;
  return v;
}

bool valid_name(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '_' || (i > 0 && (c == '-' || c == '.'));
    if (!ok) return false;
  }
  return true;
}

class Parser {
 public:
  Parser(std::string_view source) { plan_.source = std::string(source); }

  std::expected<Plan, PlanError> run(std::string_view text) {
    int line_no = 0;
    std::size_t pos = 0;
    while (pos <= text.size()) {
      std::size_t nl = text.find('\n', pos);
      if (nl == std::string_view::npos) nl = text.size();
      std::string_view line = text.substr(pos, nl - pos);
      ++line_no;
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      line_ = line;
      line_no_ = line_no;
      std::string_view code = line.substr(0, line.find('#'));
      auto toks = tokenize(code);
      if (!toks.empty())
        if (auto ok = statement(toks); !ok) return std::unexpected(ok.error());
      if (nl == text.size()) break;
      pos = nl + 1;
    }
    if (plan_.steps.empty()) return fail(0, 0, "a plan needs at least one 'step <profile> <purpose>'");
    for (const Limit& l : plan_.limits) {
      bool measured = false;
      for (const Step& s : plan_.steps) measured = measured || measured_in(l.measurement, s.purpose);
      if (!measured)
        return fail_at(l.line, 1, lines_[l.line],
                       "no step of this plan measures " + std::string(to_string(l.measurement)) + " (" +
                           std::string(l.measurement == Measurement::sensitivity || l.measurement == Measurement::firmware
                                           ? "a fit step"
                                       : (l.measurement == Measurement::arw ||
                                          l.measurement == Measurement::bias_instability)
                                           ? "a fit or soak step"
                                       : needs_rate_steps(l.measurement)
                                           ? "a fit or verify step whose profile has rate steps"
                                           : "a verify step") +
                           " does)");
    }
    if (plan_.name.empty()) {
      std::string stem = plan_.source;
      if (auto slash = stem.find_last_of('/'); slash != std::string::npos) stem = stem.substr(slash + 1);
      if (auto dot = stem.rfind(".plan"); dot != std::string::npos && dot + 5 == stem.size()) stem.resize(dot);
      // The name is stored and printed (fogctl queue list): a file name that is no plan name
      // (a space, an escape sequence, 100,000 characters) is refused, not stored raw.
      if (!valid_name(stem))
        return fail(0, 0, "the plan has no 'plan <name>' line and its file name is no plan name (1 to 64 letters, "
                          "digits, '_', '-' or '.'): add a line 'plan <name>'");
      plan_.name = stem;
    }
    return std::move(plan_);
  }

 private:
  using Ok = std::expected<void, PlanError>;

  std::unexpected<PlanError> fail(int line, int column, std::string message) {
    return fail_at(line, column, line > 0 ? std::string(line_) : std::string(), std::move(message));
  }
  std::unexpected<PlanError> fail_at(int line, int column, std::string text, std::string message) {
    return std::unexpected(PlanError{plan_.source, line, column, std::move(message), std::move(text)});
  }
  std::unexpected<PlanError> here(int column, std::string message) { return fail(line_no_, column, std::move(message)); }
  int end_column() const { return static_cast<int>(line_.size()) + 1; }
  static std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

  Ok statement(const std::vector<Token>& t) {
    lines_[line_no_] = std::string(line_);
    const auto kw = t[0].text;
    if (kw == "plan") return plan_statement(t);
    if (kw == "step") return step_statement(t);
    if (kw == "limit") return limit_statement(t);
    return here(t[0].column, "unknown statement " + quoted(kw) + "; expected 'plan', 'step' or 'limit'");
  }

  Ok no_more(const std::vector<Token>& t, std::size_t i, std::string_view what) {
    if (i < t.size())
      return here(t[i].column, "unexpected " + quoted(t[i].text) + " after the end of the '" + std::string(what) +
                                   "' statement");
    return {};
  }

  Ok plan_statement(const std::vector<Token>& t) {
    if (!plan_.name.empty()) return here(t[0].column, "'plan' given twice (first on line " + std::to_string(name_line_) + ")");
    if (!plan_.steps.empty() || !plan_.limits.empty())
      return here(t[0].column, "'plan <name>' must come before the steps and limits");
    if (t.size() < 2) return here(end_column(), "expected a plan name after 'plan', found end of line");
    if (!valid_name(t[1].text))
      return here(t[1].column, "expected a plan name of letters, digits, '_', '-' or '.', found " + quoted(t[1].text));
    plan_.name = std::string(t[1].text);
    name_line_ = line_no_;
    return no_more(t, 2, "plan");
  }

  Ok step_statement(const std::vector<Token>& t) {
    if (t.size() < 2) return here(end_column(), "expected a profile name after 'step', found end of line");
    if (!valid_name(t[1].text))
      return here(t[1].column, "expected a profile name of letters, digits, '_', '-' or '.', found " + quoted(t[1].text));
    if (t.size() < 3)
      return here(end_column(), "expected a purpose 'fit', 'verify', 'soak' or 'custom' after " + quoted(t[1].text) +
                                    ", found end of line");
    auto p = step_purpose_from_string(t[2].text);
    if (!p) return here(t[2].column, "expected a purpose 'fit', 'verify', 'soak' or 'custom', found " + quoted(t[2].text));
    plan_.steps.push_back(Step{std::string(t[1].text), *p, line_no_});
    return no_more(t, 3, "step");
  }

  Ok limit_statement(const std::vector<Token>& t) {
    if (t.size() < 2) return here(end_column(), "expected a measurement after 'limit', found end of line");
    Limit l;
    l.line = line_no_;
    std::optional<Measurement> m;
    for (auto c : kMeasurements)
      if (to_string(c) == t[1].text) m = c;
    if (!m) {
      std::string names;
      for (auto c : kMeasurements) names += (names.empty() ? "'" : ", '") + std::string(to_string(c)) + "'";
      return here(t[1].column, "unknown measurement " + quoted(t[1].text) + "; expected one of " + names);
    }
    l.measurement = *m;
    std::size_t i = 2;
    if (l.measurement == Measurement::sensitivity) {
      if (t.size() <= i) return here(end_column(), "expected a term after 'sensitivity' (e.g. d(T1)), found end of line");
      auto term = model::parse_term(t[i].text);
      if (!term)
        return here(t[i].column + static_cast<int>(term.error().position),
                    "not a term of the term language: " + term.error().message);
      l.term = model::to_string(*term, false);
      ++i;
    }
    for (const Limit& o : plan_.limits)
      if (o.measurement == l.measurement && o.term == l.term)
        return here(t[1].column, "a limit on " + l.name() + " is given twice (first on line " + std::to_string(o.line) + ")");
    if (l.measurement == Measurement::firmware) {
      // `limit firmware required [stop|continue|retest]`: the fitted model must compile to the
      // firmware form (model::firmware::compile, lags the firmware can meet).
      if (t.size() <= i || t[i].text != "required")
        return here(i < t.size() ? t[i].column : end_column(),
                    "expected 'required' after 'firmware', found " + (i < t.size() ? quoted(t[i].text) : std::string("end of line")));
      l.compare = Compare::required;
      l.value = 1.0;
      ++i;
      if (auto ok = on_fail(t, i, l); !ok) return ok;
      plan_.limits.push_back(std::move(l));
      return no_more(t, i, "limit");
    }
    if (t.size() <= i)
      return here(end_column(), "expected '<', '<=', '>', '>=' or 'within' after " + quoted(l.name()) + ", found end of line");
    const auto op = t[i].text;
    if (op == "<") l.compare = Compare::lt;
    else if (op == "<=") l.compare = Compare::le;
    else if (op == ">") l.compare = Compare::gt;
    else if (op == ">=") l.compare = Compare::ge;
    else if (op == "within") l.compare = Compare::within;
    else return here(t[i].column, "expected '<', '<=', '>', '>=' or 'within', found " + quoted(op));
    ++i;
    auto value = [&](double& out) -> Ok {
      if (t.size() <= i) return here(end_column(), "expected a number after " + quoted(t[i - 1].text) + ", found end of line");
      auto v = parse_number(t[i].text);
      if (!v) return here(t[i].column, "expected a number after " + quoted(t[i - 1].text) + ", found " + quoted(t[i].text));
      out = *v;
      ++i;
      return {};
    };
    if (auto ok = value(l.value); !ok) return ok;
    if (l.compare == Compare::within) {
      if (t.size() <= i || t[i].text != "..")
        return here(i < t.size() ? t[i].column : end_column(),
                    "expected '..' between the ends of a 'within' band, found " +
                        (i < t.size() ? quoted(t[i].text) : std::string("end of line")));
      ++i;
      const int hi_col = i < t.size() ? t[i].column : end_column();
      if (auto ok = value(l.high); !ok) return ok;
      if (l.high <= l.value) return here(hi_col, "the upper end of a 'within' band must be above its lower end");
    }
    const std::string_view unit = unit_of(l.measurement);
    if (i < t.size() && !unit.empty() && t[i].text == unit) ++i;
    else if (i < t.size() && t[i].text != "stop" && t[i].text != "continue" && t[i].text != "retest")
      return here(t[i].column, unit.empty()
                                   ? "expected 'stop', 'continue' or 'retest', found " + quoted(t[i].text) +
                                         " (" + l.name() + " has no unit)"
                                   : "expected the unit '" + std::string(unit) + "' or 'stop', 'continue', 'retest', found " +
                                         quoted(t[i].text));
    if (auto ok = on_fail(t, i, l); !ok) return ok;
    plan_.limits.push_back(std::move(l));
    return no_more(t, i, "limit");
  }

  // The optional action after a limit: stop (the default), continue or retest.
  Ok on_fail(const std::vector<Token>& t, std::size_t& i, Limit& l) {
    if (i >= t.size()) return {};
    const auto a = t[i].text;
    if (a == "stop") l.on_fail = OnFail::stop;
    else if (a == "continue") l.on_fail = OnFail::go_on;
    else if (a == "retest") l.on_fail = OnFail::retest;
    else return here(t[i].column, "expected 'stop', 'continue' or 'retest', found " + quoted(a));
    ++i;
    return {};
  }

  Plan plan_;
  std::string_view line_;
  int line_no_ = 0;
  int name_line_ = 0;
  std::map<int, std::string> lines_;
};

}  // namespace

std::expected<Plan, PlanError> parse_plan(std::string_view text, std::string_view source) {
  return Parser(source).run(text);
}

}  // namespace fogbench::plans
