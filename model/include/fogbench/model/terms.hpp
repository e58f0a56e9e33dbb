// The term language of shared/TERMS.md: what users type to name a model's terms, e.g.
// `d(T1)@auto + grad@auto`, `T1*d(T1)@40`, `0.05*T1` (a simulated effect with its coefficient).
// A parser whose errors give the position and what was expected, a canonical printer, and
// evaluation of any term over a run's signals.
#pragma once

#include <cstddef>
#include <expected>
#include <array>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fogbench::model {

// ton: time since the gyro's last power-on, s (RunData::since_power_on_s, CSV since_power_on_s).
// trun: time since the run's start, h (sample index x dt_s / 3600): a drift in time (ageing,
// outgassing) on a run that has no power-on column.
// T1x..T2z: one axis's own coil thermistors in a three-axis unit whose axes each have their own
// (absolute axis names: T1y is axis y's coil centre whichever axis is analysed): the signals of
// a cross-axis term (issue 29 point 3: an axis's drift driven by another axis's coil).
enum class Signal { T1, T2, Ta, grad, ton, trun, T1x, T2x, T1y, T2y, T1z, T2z };
inline constexpr std::size_t kSignals = 12;  // enumerators of Signal (term_ops.hpp's table checks it)

// One node of an expression. Immutable once parsed; shared between copies of a model.
struct Expr {
  // warm: exp(-ton/tau), the warm-up of a gyro after power-on (value: tau in s).
  // An operator is a row of kTermOps (term_ops.hpp): see docs/adding-a-term-operator.md.
  enum class Kind { number, signal, d, dd, up, down, lp, pow, mul, add, sub, neg, delay, warm };
  Kind kind = Kind::number;
  double value = 0.0;        // number: the value; lp, warm: tau in s
  Signal signal = Signal::T1;
  int power = 1;             // pow: the integer exponent
  int delay_s = 0;           // delay: N seconds
  std::shared_ptr<const Expr> a, b;
};
using ExprPtr = std::shared_ptr<const Expr>;
inline constexpr std::size_t kExprKinds = 14;  // enumerators of Expr::Kind (term_ops.hpp's table checks it)

// The lag of a model term: fixed (seconds) or estimated by the fit within [0, max_lag_s].
struct Lag {
  bool automatic = false;
  int seconds = 0;  // fixed lag, or the estimate once fitted
  bool operator==(const Lag&) const = default;
};

// A term of a model: expression and lag. `coef` is the coefficient written in front of it
// (effects for the simulator: `0.05*T1`); a model's fitted coefficients live in the model.
struct Term {
  ExprPtr expr;
  Lag lag;
  double coef = 1.0;
  bool coef_given = false;  // the text had a numeric factor
};

struct TermList {
  std::vector<Term> terms;
  bool paper = false;  // written as `paper`: d(T1)@auto + grad@auto with one shared lag
};

struct ParseError {
  std::size_t position = 0;  // 0-based offset into the text
  std::string message;       // what was expected and what was found
  std::string text;          // the text parsed
  // "expected ... at position N" followed by the text and a caret line under the position.
  std::string pretty() const;
};

// Parses a sum of terms. `paper` alone expands to the paper's model.
std::expected<TermList, ParseError> parse_terms(std::string_view text);
// Parses exactly one term (no top-level `+`).
std::expected<Term, ParseError> parse_term(std::string_view text);

// Canonical spelling (no spaces, the names of TERMS.md): used to compare terms and in JSON.
std::string to_string(const Expr& e);
// The term with its lag: `d(T1)@auto`, `grad@38`, `T1` (lag 0 is not written).
std::string to_string(const Term& t, bool with_lag = true);
std::string to_string(const TermList& l);
// Unit of a coefficient multiplying this expression, to give deg/h: e.g. "deg/h per degC/min".
std::string coef_unit(const Expr& e);
// Limits of the language (a term outside them is a parse error naming the limit).
inline constexpr double kMinTau_s = 1.0;       // lp and warm time constants, s
inline constexpr double kMaxTau_s = 86400.0;   // a day
inline constexpr int kMaxPower = 4;            // x^N, N = 1..4
inline constexpr int kMaxLag_s = 86400;        // x@N
// Signals the expression reads (Ta needs the chamber temperature recorded, ton the power-on time).
bool uses_signal(const Expr& e, Signal s);
// For T1x..T2z: the axis (0 x, 1 y, 2 z) and whether it is the outer wall (T2); else nullopt.
std::optional<std::pair<std::size_t, bool>> axis_thermistor(Signal s);
bool uses_axis_thermistor(const Expr& e);  // any of T1x..T2z

// The signals a term is evaluated over: temperatures as deviations from Tref, degC, at dt_s.
struct Signals {
  std::span<const double> t1;  // T1 - Tref, degC
  std::span<const double> t2;  // T2 - Tref, degC
  std::span<const double> ta;  // Ta - Tref, degC (empty when not recorded)
  double dt_s = 1.0;
  std::span<const double> ton = {};  // time since the gyro's power-on, s (empty when not recorded)
  // A three-axis unit's per-axis coil thermistors (x, y, z), T - Tref in degC: T1x..T2z (empty
  // when the axes share the unit's thermistors).
  std::array<std::span<const double>, 3> axis_t1 = {}, axis_t2 = {};
  std::size_t size() const { return t1.size(); }
};

// Half-width of the derivative window, s: d(x) is the least-squares slope over a centred
// window of 2*30+1 = 61 samples (first-order Savitzky-Golay), in degC/min; at the ends of the
// run the window is cut to the samples available.
inline constexpr int kDerivativeHalfWidth = 30;
std::vector<double> derivative_per_min(std::span<const double> x, double dt_s, int half_width = kDerivativeHalfWidth);

// Evaluates an expression (without the term's own lag) at every sample.
std::expected<std::vector<double>, std::string> evaluate(const Expr& e, const Signals& s);

// The rates of a run's bare signals (d(T1), d(T2), d(Ta), d(grad), ...), each computed once for
// the many expressions that contain them (diagnose's language search evaluates about 90
// derivatives per step, 41 of them of a bare signal: 4 distinct). Tied to the Signals it was made
// for (the same spans, the same dt_s); evaluate with it returns exactly what evaluate without it
// returns (the same calls in the same order for each rate; tests/model/terms_test.cpp). Safe to
// share between threads. Holds one column per signal used (8 B per sample each, at most 6).
class RateMemo {
 public:
  explicit RateMemo(const Signals& s) : s_(s) {}
  RateMemo(const RateMemo&) = delete;
  RateMemo& operator=(const RateMemo&) = delete;
  // d(signal) on s, as evaluate computes it; nullptr when s is not the memo's signals.
  const std::expected<std::vector<double>, std::string>* rate(Signal sig, const Signals& s);
  std::size_t computed() const;  // how many rates were computed (not found kept)

 private:
  Signals s_;
  mutable std::mutex mu_;
  std::array<std::once_flag, kSignals> once_;
  std::array<std::optional<std::expected<std::vector<double>, std::string>>, kSignals> rate_;
  std::size_t computed_ = 0;
};

// evaluate, with the bare signals' rates taken from memo (when memo is null or made for other
// signals: evaluate(e, s)).
std::expected<std::vector<double>, std::string> evaluate(const Expr& e, const Signals& s, RateMemo* memo);

}  // namespace fogbench::model
