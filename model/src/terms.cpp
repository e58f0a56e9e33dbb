// Parser, printer and evaluator of the term language (shared/TERMS.md).
// Over 600 lines: the parser, the printer and the evaluator of one small language, kept
// together because a new operator changes all three. The operators' names, syntax,
// precedence and units are rows of kTermOps (term_ops.hpp); what is code here (the grammar's
// recursion, evaluation) switches over Expr::Kind with no default.
//
// Grammar (whitespace ignored):
//   list    := 'paper' | ['-'] summand (('+' | '-') summand)*
//   summand := product ['@' (INTEGER ['s'] | 'auto')]
//   product := power ('*' power)*
//   power   := primary ['^' INTEGER]
//   primary := NUMBER | SIGNAL | FUNC '(' expr [',' NUMBER] ')' | 'warm' '(' NUMBER ')' | '(' expr ')'
//   expr    := product-with-delays joined by + and - (inside parentheses only)
// Numbers multiplying a summand form its coefficient; the rest is the term.
#include "fogbench/model/terms.hpp"
#include "fogbench/model/term_ops.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>

namespace fogbench::model {
namespace {

using K = Expr::Kind;

ExprPtr make(K k, ExprPtr a = nullptr, ExprPtr b = nullptr) {
  auto e = std::make_shared<Expr>();
  e->kind = k;
  e->a = std::move(a);
  e->b = std::move(b);
  return e;
}

bool depends_on_signal(const Expr& e) {
  if (e.kind == K::signal || e.kind == K::warm) return true;
  return (e.a && depends_on_signal(*e.a)) || (e.b && depends_on_signal(*e.b));
}

// Moves the numeric factors and negations of a product into `coef`; returns what is left
// (null when the product was only numbers).
ExprPtr pull_coefficient(const ExprPtr& e, double& coef, bool& given) {
  if (e->kind == K::number) {
    coef *= e->value;
    given = true;
    return nullptr;
  }
  if (e->kind == K::neg) {
    coef = -coef;
    given = true;
    return pull_coefficient(e->a, coef, given);
  }
  if (e->kind == K::mul) {
    ExprPtr a = pull_coefficient(e->a, coef, given);
    ExprPtr b = pull_coefficient(e->b, coef, given);
    if (!a) return b;
    if (!b) return a;
    if (a == e->a && b == e->b) return e;
    return make(K::mul, a, b);
  }
  return e;
}

std::string fmt_limit(double v) {
  std::ostringstream o;
  o.precision(12);
  o << v;
  return o.str();
}

constexpr const char* kNoPowerOn =
    "term uses ton, the time since the gyro's power-on, which this run did not record (no since_power_on_s column): "
    "record it (the daemon does, from the gyro's first frame) rather than guess it";

class Parser {
 public:
  explicit Parser(std::string_view text) : s_(text) {}

  std::expected<TermList, ParseError> list() {
    skip();
    TermList out;
    if (peek_word() == "paper") {
      pos_ += 5;
      skip();
      if (!at_end()) return fail("expected the end after 'paper'");
      out.paper = true;
      for (auto spec : {"d(T1)", "grad"}) {
        Parser p(spec);
        auto t = p.summand(1.0);
        t->lag.automatic = true;
        out.terms.push_back(*t);
      }
      return out;
    }
    double sign = 1.0;
    if (peek() == '-') {
      sign = -1.0;
      ++pos_;
    } else if (peek() == '+') {
      ++pos_;
    }
    for (;;) {
      auto t = summand(sign);
      if (!t) return std::unexpected(t.error());
      out.terms.push_back(std::move(*t));
      skip();
      if (at_end()) break;
      if (peek() == '+') sign = 1.0;
      else if (peek() == '-') sign = -1.0;
      else return fail("expected '+', '-', '*', '@' or the end");
      ++pos_;
    }
    return out;
  }

  std::expected<Term, ParseError> summand(double sign) {
    skip();
    // A sign of its own: `T1 + -0.3*T2`.
    while (peek() == '-' || peek() == '+') {
      if (peek() == '-') sign = -sign;
      ++pos_;
      skip();
    }
    Term t;
    t.coef = sign;
    t.coef_given = sign < 0.0;
    ExprPtr term;
    for (;;) {
      auto f = power();
      if (!f) return std::unexpected(f.error());
      if ((*f)->kind == K::number) {
        t.coef *= (*f)->value;
        t.coef_given = true;
      } else {
        term = term ? mul(term, *f) : *f;
      }
      skip();
      if (peek() != '*') break;
      ++pos_;
    }
    if (!term) return fail("expected a term (a signal such as T1, or a function such as d(T1)), found only a number");
    // One spelling per term: numbers and signs anywhere in the top-level product, `(T1*5)` or
    // `(-T1)`, are part of the coefficient, so that printing and parsing again give the same.
    term = pull_coefficient(term, t.coef, t.coef_given);
    if (!term) return fail("expected a term (a signal such as T1, or a function such as d(T1)), found only a number");
    if (!std::isfinite(t.coef))
      return std::unexpected(error("the term's numeric factors multiply to a number out of the range of a double"));
    if (!depends_on_signal(*term))
      return std::unexpected(error("a term must contain a signal (" + signal_names(true) + "); '" + to_string(*term) + "' is a constant"));
    t.expr = term;
    skip();
    if (peek() == '@') {
      ++pos_;
      skip();
      if (peek_word() == "auto") {
        pos_ += 4;
        t.lag.automatic = true;
      } else {
        auto n = lag_seconds("a lag in seconds or 'auto' after '@'");
        if (!n) return std::unexpected(n.error());
        t.lag.seconds = *n;
      }
    }
    return t;
  }

  bool at_end() {
    skip();
    return pos_ >= s_.size();
  }

  ParseError error(std::string msg) const { return ParseError{pos_, std::move(msg), std::string(s_)}; }
  std::unexpected<ParseError> fail(std::string expected) const {
    std::string found = pos_ < s_.size() ? "'" + std::string(s_.substr(pos_, 1)) + "'" : "the end";
    return std::unexpected(error(expected + ", found " + found));
  }

 private:
  static ExprPtr mul(ExprPtr a, ExprPtr b) { return make(K::mul, std::move(a), std::move(b)); }

  std::expected<ExprPtr, ParseError> expr() {
    auto lhs = delayed_product();
    if (!lhs) return lhs;
    ExprPtr e = *lhs;
    for (;;) {
      skip();
      char c = peek();
      if (c != '+' && c != '-') return e;
      ++pos_;
      auto rhs = delayed_product();
      if (!rhs) return rhs;
      e = make(c == '+' ? K::add : K::sub, e, *rhs);
    }
  }

  std::expected<ExprPtr, ParseError> delayed_product() {
    skip();
    bool neg = false;
    if (peek() == '-') {
      neg = true;
      ++pos_;
    }
    auto p = power();
    if (!p) return p;
    ExprPtr e = *p;
    for (;;) {
      skip();
      if (peek() != '*') break;
      ++pos_;
      auto f = power();
      if (!f) return f;
      e = mul(e, *f);
    }
    skip();
    if (peek() == '@') {
      ++pos_;
      skip();
      if (peek_word() == "auto") return fail("'@auto' is allowed only at the end of a whole term, not inside a function");
      auto n = lag_seconds("a lag in seconds after '@'");
      if (!n) return std::unexpected(n.error());
      if (*n > 0) {  // x@0 is x
        auto d = make(K::delay, e);
        std::const_pointer_cast<Expr>(d)->delay_s = *n;
        e = d;
      }
    }
    return neg ? make(K::neg, e) : e;
  }

  std::expected<ExprPtr, ParseError> power() {
    auto p = primary();
    if (!p) return p;
    skip();
    if (peek() != '^') return p;
    ++pos_;
    skip();
    const std::size_t at = pos_;
    auto n = integer("an integer exponent after '^'");
    if (!n) return std::unexpected(n.error());
    if (*n < 1 || *n > kMaxPower) {
      pos_ = at;
      return std::unexpected(error("exponent must be 1 to " + std::to_string(kMaxPower) + ", got " + std::to_string(*n)));
    }
    const int power = static_cast<int>(*n);
    if ((*p)->kind == K::number) {
      const double v = std::pow((*p)->value, power);
      if (!std::isfinite(v)) {
        pos_ = at;
        return std::unexpected(error("the number to the power " + std::to_string(power) + " is out of the range of a double"));
      }
      auto e = make(K::number);
      std::const_pointer_cast<Expr>(e)->value = v;
      return e;
    }
    auto e = make(K::pow, *p);
    std::const_pointer_cast<Expr>(e)->power = power;
    return e;
  }

  // Nesting deeper than this is surely not a model term, and unbounded recursion would
  // overflow the stack on hostile input.
  static constexpr int kMaxDepth = 32;

  std::expected<ExprPtr, ParseError> primary() {
    skip();
    const std::size_t start = pos_;
    if (depth_ >= kMaxDepth) return std::unexpected(error("expression nested deeper than " + std::to_string(kMaxDepth) + " levels"));
    struct Depth {
      int& d;
      explicit Depth(int& x) : d(x) { ++d; }
      ~Depth() { --d; }
    } depth_guard(depth_);
    char c = peek();
    if (c == '(') {
      ++pos_;
      auto e = expr();
      if (!e) return e;
      skip();
      if (peek() != ')') return fail("expected ')' to close the '(' at position " + std::to_string(start));
      ++pos_;
      return e;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
      auto v = number();
      if (!v) return std::unexpected(v.error());
      auto e = make(K::number);
      std::const_pointer_cast<Expr>(e)->value = *v;
      return e;
    }
    std::string_view w = peek_word();
    if (w.empty()) return fail("expected a signal (" + signal_names() + "), a function (" + function_names() + "), a number or '('");
    pos_ += w.size();
    for (const TermSignal& sig : kTermSignals)
      if (w == sig.name) {
        auto e = make(K::signal);
        std::const_pointer_cast<Expr>(e)->signal = sig.signal;
        return e;
      }
    const TermOp* op = nullptr;
    for (const TermOp& o : kTermOps)
      if ((o.syntax == OpSyntax::call || o.syntax == OpSyntax::call_tau || o.syntax == OpSyntax::tau_only) && w == o.name) op = &o;
    if (!op) {
      pos_ = start;
      return std::unexpected(error("unknown name '" + std::string(w) + "': expected a signal (" + signal_names() + ") or a function (" +
                                   function_names() + ")"));
    }
    const std::string name(op->name);
    if (op->syntax == OpSyntax::tau_only) {  // warm(tau) = exp(-ton/tau): a number, not an expression, inside
      skip();
      if (peek() != '(') return fail("expected '(' and a time constant in seconds after '" + name + "': " + name + "(tau)");
      ++pos_;
      auto tau = time_constant(name + "(tau)");
      if (!tau) return std::unexpected(tau.error());
      skip();
      if (peek() != ')') return fail("expected ')' to close '" + name + "(' (" + name + " takes one number, the time constant in s)");
      ++pos_;
      auto e = make(op->kind);
      std::const_pointer_cast<Expr>(e)->value = *tau;
      return e;
    }
    skip();
    if (peek() != '(') return fail("expected '(' after '" + std::string(w) + "'");
    ++pos_;
    auto arg = expr();
    if (!arg) return arg;
    auto e = make(op->kind, *arg);
    skip();
    if (op->syntax == OpSyntax::call_tau) {
      if (peek() != ',') return fail("expected ',' and a time constant in seconds: " + name + "(x, tau)");
      ++pos_;
      auto tau = time_constant(name + "(x, tau)");
      if (!tau) return std::unexpected(tau.error());
      std::const_pointer_cast<Expr>(e)->value = *tau;
      skip();
    }
    if (peek() != ')') return fail("expected ')' to close '" + std::string(w) + "('");
    ++pos_;
    return e;
  }

  std::expected<double, ParseError> number() {
    skip();
    const char* b = s_.data() + pos_;
    const char* end = s_.data() + s_.size();
    double v = 0.0;
    auto [p, ec] = std::from_chars(b, end, v);
    if (ec != std::errc() || p == b) return fail("expected a number");
    if (!std::isfinite(v)) return fail("expected a finite number");  // from_chars reads 'inf' and 'nan'
    pos_ += static_cast<std::size_t>(p - b);
    return v;
  }

  // A time constant in seconds (warm(tau), lp(x, tau)) within kMinTau_s..kMaxTau_s; form names
  // the construct in the error, which points at the number.
  std::expected<double, ParseError> time_constant(const std::string& form) {
    skip();
    const std::size_t at = pos_;
    auto tau = number();
    if (!tau) return tau;
    if (!(*tau >= kMinTau_s && *tau <= kMaxTau_s)) {
      pos_ = at;
      return std::unexpected(error(form + ": the time constant must be " + fmt_limit(kMinTau_s) + " to " +
                                   fmt_limit(kMaxTau_s) + " s, got " + fmt_limit(*tau)));
    }
    return tau;
  }

  // A lag after '@': whole seconds 0..kMaxLag_s, an optional unit 's'.
  std::expected<int, ParseError> lag_seconds(const std::string& what) {
    skip();
    const std::size_t at = pos_;
    auto n = integer(what);
    if (!n) return std::unexpected(n.error());
    if (*n < 0 || *n > kMaxLag_s) {
      pos_ = at;
      return std::unexpected(error(*n < 0 ? std::string("a lag cannot be negative")
                                          : "lag of " + std::to_string(*n) + " s is longer than a day (" +
                                                std::to_string(kMaxLag_s) + " s)"));
    }
    if (peek() == 's') ++pos_;
    return static_cast<int>(*n);
  }

  // An integer, its range checked by the caller (a lag, an exponent) so that the error names
  // what is wrong with it; one beyond 64 bits is refused here.
  std::expected<long long, ParseError> integer(const std::string& what) {
    skip();
    const char* b = s_.data() + pos_;
    long long v = 0;
    auto [p, ec] = std::from_chars(b, s_.data() + s_.size(), v);
    if (ec == std::errc::result_out_of_range)
      return std::unexpected(error(std::string(b, p) + " is too large for " + what));
    if (ec != std::errc() || p == b) return fail("expected " + what);
    pos_ += static_cast<std::size_t>(p - b);
    return v;
  }

  void skip() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  std::string_view peek_word() const {
    std::size_t e = pos_;
    while (e < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[e])) || s_[e] == '_')) ++e;
    if (e == pos_ || std::isdigit(static_cast<unsigned char>(s_[pos_]))) return {};
    return s_.substr(pos_, e - pos_);
  }

  std::string_view s_;
  std::size_t pos_ = 0;
  int depth_ = 0;
};

std::string fmt_number(double v) {
  std::ostringstream o;
  o.precision(12);
  o << v;
  return o.str();
}

// kTermOps' precedence: neg is 1, parenthesised in products: (-T2)*T2 is not -(T2*T2).
int precedence(const Expr& e) { return term_op(e.kind).precedence; }

std::string wrap(const Expr& e, int min_prec) {
  std::string s = to_string(e);
  return precedence(e) < min_prec ? "(" + s + ")" : s;
}

}  // namespace

std::string ParseError::pretty() const {
  return message + " at position " + std::to_string(position + 1) + "\n  " + text + "\n  " +
         std::string(position, ' ') + "^";
}

std::expected<TermList, ParseError> parse_terms(std::string_view text) {
  Parser p(text);
  if (p.at_end()) return std::unexpected(ParseError{0, "expected a term, found an empty text", std::string(text)});
  return p.list();
}

std::expected<Term, ParseError> parse_term(std::string_view text) {
  auto l = parse_terms(text);
  if (!l) return std::unexpected(l.error());
  if (l->terms.size() != 1)
    return std::unexpected(ParseError{0, "expected exactly one term, found " + std::to_string(l->terms.size()), std::string(text)});
  return l->terms.front();
}

std::string to_string(const Expr& e) {
  const TermOp& op = term_op(e.kind);
  switch (e.kind) {
    case K::number: return spell(op, {}, {}, fmt_number(e.value));
    case K::signal: return spell(op, {}, {}, term_signal(e.signal).name);
    case K::warm: return spell(op, {}, {}, fmt_number(e.value));
    case K::d: case K::dd: case K::up: case K::down: return spell(op, to_string(*e.a));
    case K::lp: return spell(op, to_string(*e.a), {}, fmt_number(e.value));
    case K::pow: return spell(op, wrap(*e.a, 4), {}, std::to_string(e.power));
    case K::mul: return spell(op, wrap(*e.a, 2), wrap(*e.b, 3));
    case K::add: case K::sub: return spell(op, to_string(*e.a), wrap(*e.b, 2));
    case K::neg: return spell(op, wrap(*e.a, 3));
    // Always in parentheses: `(T1@30)*T2` and `(T1@30)@auto` must not read as a term's lag.
    case K::delay: return spell(op, wrap(*e.a, 3), {}, std::to_string(e.delay_s));
  }
  return "?";
}

std::string spell(const TermOp& op, std::string_view a, std::string_view b, std::string_view param) {
  const std::string name(op.name);
  switch (op.syntax) {
    case OpSyntax::number: case OpSyntax::signal: return std::string(param);
    case OpSyntax::call: return name + "(" + std::string(a) + ")";
    case OpSyntax::call_tau: return name + "(" + std::string(a) + "," + std::string(param) + ")";
    case OpSyntax::tau_only: return name + "(" + std::string(param) + ")";
    case OpSyntax::power: return std::string(a) + name + std::string(param);
    case OpSyntax::infix: return std::string(a) + name + std::string(b);
    case OpSyntax::prefix: return name + std::string(a);
    case OpSyntax::delay: return "(" + std::string(a) + name + std::string(param) + ")";
  }
  return "?";
}

std::string function_names() {
  std::string s;
  for (const TermOp& o : kTermOps)
    if (o.syntax == OpSyntax::call || o.syntax == OpSyntax::call_tau || o.syntax == OpSyntax::tau_only)
      s += (s.empty() ? "" : ", ") + std::string(o.name);
  return s;
}

std::string signal_names(bool or_last) {
  std::string s;
  for (std::size_t i = 0; i < kTermSignals.size(); ++i)
    s += (i == 0 ? "" : or_last && i + 1 == kTermSignals.size() ? " or " : ", ") + std::string(kTermSignals[i].name);
  return s;
}

std::string to_string(const Term& t, bool with_lag) {
  std::string s = to_string(*t.expr);
  if (t.expr->kind == K::add || t.expr->kind == K::sub) s = "(" + s + ")";
  if (!with_lag) return s;
  if (t.lag.automatic) return s + "@auto";
  if (t.lag.seconds != 0) return s + "@" + std::to_string(t.lag.seconds);
  return s;
}

std::string to_string(const TermList& l) {
  if (l.paper) return "paper";
  std::string s;
  for (const auto& t : l.terms) {
    if (!s.empty()) s += " + ";
    s += to_string(t);
  }
  return s;
}

namespace {
// Unit of an expression's value as a string of degC powers and per-minute powers.
struct Unit {
  int temp = 0;     // power of degC
  int per_min = 0;  // power of 1/min
  int sec = 0;      // power of s (ton)
  int hour = 0;     // power of h (trun)
};
Unit unit_of(const Expr& e) {
  const TermOp& op = term_op(e.kind);
  switch (op.unit) {
    case OpUnit::none: return {};
    case OpUnit::signal: return e.signal == Signal::ton ? Unit{0, 0, 1, 0} : e.signal == Signal::trun ? Unit{0, 0, 0, 1} : Unit{1, 0, 0, 0};
    case OpUnit::rate: { auto u = unit_of(*e.a); u.per_min += op.derivatives; return u; }
    case OpUnit::operand: return unit_of(*e.a);
    case OpUnit::power: { auto u = unit_of(*e.a); u.temp *= e.power; u.per_min *= e.power; u.sec *= e.power; u.hour *= e.power; return u; }
    case OpUnit::product: { auto a = unit_of(*e.a), b = unit_of(*e.b); return {a.temp + b.temp, a.per_min + b.per_min, a.sec + b.sec, a.hour + b.hour}; }
  }
  return {};
}
}  // namespace

std::string coef_unit(const Expr& e) {
  const Unit u = unit_of(e);
  std::string s;
  if (u.temp == 1) s = "degC";
  else if (u.temp > 1) s = "degC^" + std::to_string(u.temp);
  if (u.sec == 1) s += s.empty() ? "s" : " s";
  else if (u.sec > 1) s += (s.empty() ? "s^" : " s^") + std::to_string(u.sec);
  if (u.hour == 1) s += s.empty() ? "h" : " h";
  else if (u.hour > 1) s += (s.empty() ? "h^" : " h^") + std::to_string(u.hour);
  if (u.per_min == 1) s += "/min";
  else if (u.per_min > 1) s += "/min^" + std::to_string(u.per_min);
  if (s.empty()) return "deg/h";
  return "deg/h per " + s;
}

bool uses_axis_thermistor(const Expr& e) {
  if (e.kind == K::signal) return axis_thermistor(e.signal).has_value();
  return (e.a && uses_axis_thermistor(*e.a)) || (e.b && uses_axis_thermistor(*e.b));
}

std::optional<std::pair<std::size_t, bool>> axis_thermistor(Signal s) {
  switch (s) {
    case Signal::T1x: return std::pair<std::size_t, bool>{0, false};
    case Signal::T2x: return std::pair<std::size_t, bool>{0, true};
    case Signal::T1y: return std::pair<std::size_t, bool>{1, false};
    case Signal::T2y: return std::pair<std::size_t, bool>{1, true};
    case Signal::T1z: return std::pair<std::size_t, bool>{2, false};
    case Signal::T2z: return std::pair<std::size_t, bool>{2, true};
    case Signal::T1: case Signal::T2: case Signal::Ta: case Signal::grad: case Signal::ton: case Signal::trun: return std::nullopt;
  }
  return std::nullopt;
}

bool uses_signal(const Expr& e, Signal s) {
  if (e.kind == K::warm) return s == Signal::ton;
  if (e.kind == K::signal) return e.signal == s || (s != Signal::Ta && e.signal == Signal::grad && (s == Signal::T1 || s == Signal::T2));
  return (e.a && uses_signal(*e.a, s)) || (e.b && uses_signal(*e.b, s));
}

std::vector<double> derivative_per_min(std::span<const double> x, double dt_s, int half_width) {
  const std::size_t n = x.size();
  std::vector<double> out(n, 0.0);
  if (n < 2) return out;
  // Each window's least-squares slope is sum (k - c) x_k / sum (k - c)^2 over its samples, c
  // its centre. The weights are centred on the window, so no sum grows with the index: prefix
  // sums of k x_k over a run (as this was once written) lose digits as n^2 x grows (a relative
  // error of 1e-4 at 262,200 samples, 3e-3 at 864,000). The denominator of a contiguous window
  // of m samples is m (m^2 - 1) / 12 exactly.
  const auto h = static_cast<std::size_t>(std::max(1, half_width));
  const double to_per_min = 60.0 / dt_s;
  auto direct = [&](std::size_t lo, std::size_t hi) {  // the slope over [lo, hi], per sample
    const double m = static_cast<double>(hi - lo + 1);
    const double c = 0.5 * (static_cast<double>(lo) + static_cast<double>(hi));
    double num = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) num += (static_cast<double>(k) - c) * x[k];
    const double den = m * (m * m - 1.0) / 12.0;
    return den > 0.0 ? num / den : 0.0;
  };
  bool finite = true;
  for (double v : x) finite = finite && std::isfinite(v);
  if (n <= 2 * h + 1 || !finite) {
    // Short runs, and runs with a value that is not finite (NaN only where a window holds one):
    // every window summed directly.
    for (std::size_t i = 0; i < n; ++i) out[i] = direct(i >= h ? i - h : 0, std::min(n - 1, i + h)) * to_per_min;
    return out;
  }
  // The windows cut at the run's ends, directly; the full ones slide: with M_i = sum_{j=-h..h}
  // j x_{i+j} and W_i = sum_{j=-h..h} x_{i+j}, W_{i+1} = W_i - x_{i-h} + x_{i+h+1} and
  // M_{i+1} = M_i + h x_{i-h} + (h + 1) x_{i+h+1} - W_{i+1}. Summed afresh every kReset
  // samples, so rounding cannot build up along a long run.
  for (std::size_t i = 0; i < h; ++i) {
    out[i] = direct(0, i + h) * to_per_min;
    out[n - 1 - i] = direct(n - 1 - i - h, n - 1) * to_per_min;
  }
  constexpr std::size_t kReset = 256;
  const double hd = static_cast<double>(h);
  const double den = (2.0 * hd + 1.0) * ((2.0 * hd + 1.0) * (2.0 * hd + 1.0) - 1.0) / 12.0;
  double mom = 0.0, win = 0.0;
  for (std::size_t i = h; i + h < n; ++i) {
    if ((i - h) % kReset == 0) {
      mom = 0.0;
      win = 0.0;
      for (std::size_t k = i - h; k <= i + h; ++k) {
        mom += (static_cast<double>(k) - static_cast<double>(i)) * x[k];
        win += x[k];
      }
    } else {
      win += x[i + h] - x[i - h - 1];
      mom += hd * x[i - h - 1] + (hd + 1.0) * x[i + h] - win;
    }
    out[i] = mom / den * to_per_min;
  }
  return out;
}

namespace {
bool same_signals(const Signals& a, const Signals& b) {
  auto same = [](std::span<const double> x, std::span<const double> y) { return x.data() == y.data() && x.size() == y.size(); };
  for (std::size_t k = 0; k < 3; ++k)
    if (!same(a.axis_t1[k], b.axis_t1[k]) || !same(a.axis_t2[k], b.axis_t2[k])) return false;
  return same(a.t1, b.t1) && same(a.t2, b.t2) && same(a.ta, b.ta) && same(a.ton, b.ton) && a.dt_s == b.dt_s;
}
}  // namespace

const std::expected<std::vector<double>, std::string>* RateMemo::rate(Signal sig, const Signals& s) {
  if (!same_signals(s, s_)) return nullptr;
  const auto k = static_cast<std::size_t>(sig);
  // Made once, outside the lock (two threads asking for two signals compute them together);
  // call_once publishes the value to every thread that waits on it.
  std::call_once(once_[k], [&] {
    Expr leaf;
    leaf.kind = Expr::Kind::signal;
    leaf.signal = sig;
    auto v = evaluate(leaf, s_);
    if (v) *v = derivative_per_min(*v, s_.dt_s);
    rate_[k] = std::move(v);
    const std::lock_guard<std::mutex> lock(mu_);
    ++computed_;
  });
  return &*rate_[k];
}

std::size_t RateMemo::computed() const {
  const std::lock_guard<std::mutex> lock(mu_);
  return computed_;
}

std::expected<std::vector<double>, std::string> evaluate(const Expr& e, const Signals& s) { return evaluate(e, s, nullptr); }

std::expected<std::vector<double>, std::string> evaluate(const Expr& e, const Signals& s, RateMemo* memo) {
  const std::size_t n = s.size();
  auto sub = [&](const Expr& x) { return evaluate(x, s, memo); };
  switch (e.kind) {
    case K::number: return std::vector<double>(n, e.value);
    case K::signal: {
      if (e.signal == Signal::T1) return std::vector<double>(s.t1.begin(), s.t1.end());
      if (e.signal == Signal::T2) return std::vector<double>(s.t2.begin(), s.t2.end());
      if (e.signal == Signal::Ta) {
        if (s.ta.size() != n) return std::unexpected(std::string("term uses Ta, the chamber air temperature, which this run did not record (no chamber_c column)"));
        return std::vector<double>(s.ta.begin(), s.ta.end());
      }
      if (e.signal == Signal::ton) {
        if (s.ton.size() != n) return std::unexpected(std::string(kNoPowerOn));
        return std::vector<double>(s.ton.begin(), s.ton.end());
      }
      if (e.signal == Signal::trun) {  // the run's own clock: time since its first sample, h
        std::vector<double> v(n);
        for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<double>(i) * s.dt_s / 3600.0;
        return v;
      }
      if (const auto ax = axis_thermistor(e.signal)) {
        const auto& col = ax->second ? s.axis_t2[ax->first] : s.axis_t1[ax->first];
        if (col.size() != n) {
          return std::unexpected("term uses " + std::string(term_signal(e.signal).name) + ", axis " + std::string(1, "xyz"[ax->first]) +
                                 "'s own coil " + (ax->second ? "outer-wall" : "centre") +
                                 " thermistor, which this run did not record (no per-axis thermistor columns t1_y_c, t2_y_c, t1_z_c, "
                                 "t2_z_c: its axes share the unit's thermistors, or it is a one-axis gyro)");
        }
        return std::vector<double>(col.begin(), col.end());
      }
      std::vector<double> g(n);
      for (std::size_t i = 0; i < n; ++i) g[i] = s.t1[i] - s.t2[i];
      return g;
    }
    case K::d: case K::dd: {
      // A bare signal's first derivative from the memo: the same calls as below, made once.
      if (memo && e.a->kind == K::signal)
        if (const auto* r = memo->rate(e.a->signal, s)) {
          if (!*r) return std::unexpected((*r).error());
          std::vector<double> v = **r;
          for (int k = 1; k < term_op(e.kind).derivatives; ++k) v = derivative_per_min(v, s.dt_s);
          return v;
        }
      auto v = sub(*e.a);
      if (!v) return v;
      for (int k = 0; k < term_op(e.kind).derivatives; ++k) *v = derivative_per_min(*v, s.dt_s);
      return v;
    }
    case K::up: case K::down: {
      auto v = sub(*e.a);
      if (!v) return v;
      for (double& x : *v) x = e.kind == K::up ? std::max(x, 0.0) : std::min(x, 0.0);
      return v;
    }
    case K::warm: {
      if (s.ton.size() != n) return std::unexpected(std::string(kNoPowerOn));
      std::vector<double> v(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = std::exp(-std::max(0.0, s.ton[i]) / e.value);
      return v;
    }
    case K::lp: {
      auto v = sub(*e.a);
      if (!v || v->empty()) return v;
      // Exact discretisation of a first-order lag for a signal held over each step.
      const double alpha = 1.0 - std::exp(-s.dt_s / e.value);
      double y = (*v)[0];
      for (double& x : *v) x = y = y + alpha * (x - y);
      return v;
    }
    case K::pow: {
      auto v = sub(*e.a);
      if (!v) return v;
      for (double& x : *v) x = std::pow(x, e.power);
      return v;
    }
    case K::neg: {
      auto v = sub(*e.a);
      if (!v) return v;
      for (double& x : *v) x = -x;
      return v;
    }
    case K::mul: case K::add: case K::sub: {
      auto a = sub(*e.a);
      if (!a) return a;
      auto b = sub(*e.b);
      if (!b) return b;
      for (std::size_t i = 0; i < n; ++i)
        (*a)[i] = e.kind == K::mul ? (*a)[i] * (*b)[i] : e.kind == K::add ? (*a)[i] + (*b)[i] : (*a)[i] - (*b)[i];
      return a;
    }
    case K::delay: {
      auto v = sub(*e.a);
      if (!v) return v;
      const auto lag = static_cast<std::size_t>(std::lround(e.delay_s / s.dt_s));
      std::vector<double> out(n);
      for (std::size_t i = 0; i < n; ++i) out[i] = (*v)[i >= lag ? i - lag : 0];
      return out;
    }
  }
  return std::unexpected(std::string("internal: unknown expression kind"));
}

}  // namespace fogbench::model
