// The term language's operators and signals in one table each (shared/TERMS.md is the
// contract; docs/adding-a-term-operator.md lists what a new operator touches).
//
// Every reader of the language reads these tables: the parser (names, syntax), the printer
// (spelling, precedence), coef_unit (unit rule), the firmware form (supported or refused, and
// why), the simulator (how much history the operator needs) and diagnose's search (which
// operators it generates and how they are spelled). A row per Expr::Kind, in the enum's order:
// the static_asserts below fail to compile when a kind has no row or a row is out of place, and
// tests/model/term_ops_test.cpp runs every row through parse -> print, evaluation against a
// hand-computed value, the firmware and the simulator. What cannot be a table cell (the
// evaluation itself, the firmware's compilation) is a switch over Expr::Kind with no default,
// so that -Wswitch (in -Wall; an error in the Debug CI build) names a kind left out.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fogbench/model/terms.hpp"

namespace fogbench::model {

// How an operator is written.
enum class OpSyntax : std::uint8_t {
  number,    // a literal, 0.05 (a factor of the whole term becomes the term's coefficient)
  signal,    // one of kSignals' names
  call,      // name(x)
  call_tau,  // name(x, tau), tau a time constant in s (kMinTau_s..kMaxTau_s)
  tau_only,  // name(tau): a time constant in s and no operand
  power,     // x^N, N = 1..kMaxPower
  infix,     // x name y
  prefix,    // name x
  delay,     // (x@N): N s, inside a term; a term's own @N or @auto is its lag, not this operator
};

// How the unit of a coefficient multiplying the operator follows from its operands' (coef_unit).
enum class OpUnit : std::uint8_t {
  none,      // a pure number (number, warm)
  signal,    // the signal's own unit (kSignals)
  operand,   // the operand's unit (up, down, lp, neg, delay; add and sub: the first operand's)
  rate,      // the operand's unit per minute^derivatives
  power,     // the operand's unit to the power N
  product,   // the operands' units multiplied
};

// What the simulator keeps of history before a run's first sample (sim::make_drift_law):
// a simulated effect's value at the first sample must not lean on samples it does not have.
enum class OpHistory : std::uint8_t {
  none,
  derivative,  // 2 * kDerivativeHalfWidth s per derivative
  lowpass,     // 8 time constants (the filter has forgotten its start to 3e-4)
  delay,       // the delay itself
};

// Whether the firmware form (firmware.hpp) computes the operator.
enum class OpFirmware : std::uint8_t { compiled, refused };

struct TermOp {
  Expr::Kind kind;
  std::string_view name;      // the spelling: "d", "lp", "^", "*", "@"; a description for number and signal
  OpSyntax syntax;
  int operands;               // sub-expressions: 0 (number, signal, warm), 1, 2
  int precedence;             // printing: an operand of lower precedence is parenthesised
  OpUnit unit;
  int derivatives;            // d 1, dd 2, others 0: windows of derivative_per_min
  OpFirmware firmware;
  std::string_view firmware_form;  // compiled: how (firmware.hpp's operations); refused: the named error
  OpHistory history;
  bool searched;              // diagnose's language search generates it (docs/workbench.md)
  std::string_view example;   // a term using it, canonical spelling (tests: parse -> print round trip)
  std::string_view meaning;   // shared/TERMS.md
};

inline constexpr std::array<TermOp, kExprKinds> kTermOps = {{
    {Expr::Kind::number, "number", OpSyntax::number, 0, 4, OpUnit::none, 0, OpFirmware::compiled, "number", OpHistory::none, false,
     "up(T1-0.5)", "a constant; a factor of a whole term is its coefficient"},
    {Expr::Kind::signal, "signal", OpSyntax::signal, 0, 4, OpUnit::signal, 0, OpFirmware::compiled,
     "signal input (grad: sub of T1 and T2); trun refused (kSignals)", OpHistory::none, true, "T1", "a measured signal (kSignals)"},
    {Expr::Kind::d, "d", OpSyntax::call, 1, 4, OpUnit::rate, 1, OpFirmware::compiled,
     "slope over the last 61 s: 30 s late, paid by the term's lag", OpHistory::derivative, true, "d(T1)",
     "first time derivative, degC/min: least-squares slope over a centred 61 s window"},
    {Expr::Kind::dd, "dd", OpSyntax::call, 1, 4, OpUnit::rate, 2, OpFirmware::compiled, "two slopes: 60 s late", OpHistory::derivative, true,
     "dd(T1)", "second time derivative, degC/min^2: d of d"},
    {Expr::Kind::up, "up", OpSyntax::call, 1, 4, OpUnit::operand, 0, OpFirmware::compiled, "up", OpHistory::none, true, "up(d(T1))",
     "max(x, 0)"},
    {Expr::Kind::down, "down", OpSyntax::call, 1, 4, OpUnit::operand, 0, OpFirmware::compiled, "down", OpHistory::none, true, "down(d(T1))",
     "min(x, 0)"},
    {Expr::Kind::lp, "lp", OpSyntax::call_tau, 1, 4, OpUnit::operand, 0, OpFirmware::compiled, "lp: first-order IIR, alpha = 1 - exp(-dt/tau)",
     OpHistory::lowpass, true, "lp(T1,300)", "first-order low-pass of time constant tau s, started at the first sample"},
    {Expr::Kind::pow, "^", OpSyntax::power, 1, 3, OpUnit::power, 0, OpFirmware::compiled, "pow: repeated product", OpHistory::none, true,
     "T1^2", "integer power"},
    {Expr::Kind::mul, "*", OpSyntax::infix, 2, 2, OpUnit::product, 0, OpFirmware::compiled, "mul, the earlier operand delayed to the later",
     OpHistory::none, true, "T1*d(T1)", "product"},
    {Expr::Kind::add, "+", OpSyntax::infix, 2, 1, OpUnit::operand, 0, OpFirmware::compiled, "add, the earlier operand delayed to the later",
     OpHistory::none, false, "(T1+T2)", "sum, inside parentheses"},
    {Expr::Kind::sub, "-", OpSyntax::infix, 2, 1, OpUnit::operand, 0, OpFirmware::compiled, "sub, the earlier operand delayed to the later",
     OpHistory::none, false, "(T1-T2)", "difference, inside parentheses"},
    {Expr::Kind::neg, "-", OpSyntax::prefix, 1, 1, OpUnit::operand, 0, OpFirmware::compiled, "neg", OpHistory::none, false, "up(-T1)",
     "negation (of a whole term: its coefficient)"},
    {Expr::Kind::delay, "@", OpSyntax::delay, 1, 4, OpUnit::operand, 0, OpFirmware::compiled,
     "delay of round(N/dt) samples, less what the operand's slopes are already late", OpHistory::delay, false, "(T1@30)",
     "x delayed by N s inside a term (diagnose's second thermal path)"},
    {Expr::Kind::warm, "warm", OpSyntax::tau_only, 0, 4, OpUnit::none, 0, OpFirmware::compiled, "warm: exp(-max(ton, 0)/tau) of the ton input",
     OpHistory::none, true, "warm(600)", "exp(-ton/tau): the warm-up after power-on"},
}};

constexpr const TermOp& term_op(Expr::Kind k) { return kTermOps[static_cast<std::size_t>(k)]; }

namespace detail {
// True for every enumerator of Expr::Kind. No default, and -Wswitch an error here in every
// build: a new kind left out does not compile, and once added here the static_assert below
// asks for kExprKinds and a row of kTermOps.
#pragma GCC diagnostic push
#pragma GCC diagnostic error "-Wswitch"
constexpr bool is_expr_kind(Expr::Kind k) {
  switch (k) {
    case Expr::Kind::number: case Expr::Kind::signal: case Expr::Kind::d: case Expr::Kind::dd: case Expr::Kind::up: case Expr::Kind::down: case Expr::Kind::lp:
    case Expr::Kind::pow: case Expr::Kind::mul: case Expr::Kind::add: case Expr::Kind::sub: case Expr::Kind::neg: case Expr::Kind::delay: case Expr::Kind::warm:
      return true;
  }
  return false;
}
#pragma GCC diagnostic pop
constexpr bool rows_in_kind_order() {
  for (std::size_t i = 0; i < kTermOps.size(); ++i)
    if (static_cast<std::size_t>(kTermOps[i].kind) != i) return false;
  return true;
}
}  // namespace detail
static_assert(detail::is_expr_kind(static_cast<Expr::Kind>(kExprKinds - 1)) && !detail::is_expr_kind(static_cast<Expr::Kind>(kExprKinds)),
              "kExprKinds must count Expr::Kind's enumerators");
static_assert(detail::rows_in_kind_order(), "kTermOps: one row per Expr::Kind, in the enum's order");

// The signals: name, what the firmware reads for it (its input index 0 T1, 1 T2, 2 Ta, 3 ton;
// -2 grad, computed as T1 - T2; -1 refused with firmware_refusal).
struct TermSignal {
  Signal signal;
  std::string_view name;
  int firmware_input;
  std::string_view firmware_refusal;
};
inline constexpr std::string_view kCrossAxisRefusal =
    "a per-axis coil thermistor (T1x..T2z) is a cross-axis term found on a three-axis unit's runs; the firmware form has one axis's "
    "inputs (T1, T2, Ta, ton): refit without it";
inline constexpr std::array<TermSignal, kSignals> kTermSignals = {{
    {Signal::T1, "T1", 0, ""},
    {Signal::T2, "T2", 1, ""},
    {Signal::Ta, "Ta", 2, ""},
    {Signal::grad, "grad", -2, ""},
    {Signal::ton, "ton", 3, ""},
    {Signal::trun, "trun", -1,
     "trun (time since the run's start) is a drift in time found on runs, not a compensation: the firmware has no run clock; refit "
     "without it"},
    {Signal::T1x, "T1x", -1, kCrossAxisRefusal},
    {Signal::T2x, "T2x", -1, kCrossAxisRefusal},
    {Signal::T1y, "T1y", -1, kCrossAxisRefusal},
    {Signal::T2y, "T2y", -1, kCrossAxisRefusal},
    {Signal::T1z, "T1z", -1, kCrossAxisRefusal},
    {Signal::T2z, "T2z", -1, kCrossAxisRefusal},
}};
constexpr const TermSignal& term_signal(Signal s) { return kTermSignals[static_cast<std::size_t>(s)]; }
namespace detail {
#pragma GCC diagnostic push
#pragma GCC diagnostic error "-Wswitch"
constexpr bool is_signal(Signal s) {
  switch (s) {
    case Signal::T1: case Signal::T2: case Signal::Ta: case Signal::grad: case Signal::ton: case Signal::trun:
    case Signal::T1x: case Signal::T2x: case Signal::T1y: case Signal::T2y: case Signal::T1z: case Signal::T2z:
      return true;
  }
  return false;
}
#pragma GCC diagnostic pop
constexpr bool signals_in_order() {
  for (std::size_t i = 0; i < kTermSignals.size(); ++i)
    if (static_cast<std::size_t>(kTermSignals[i].signal) != i) return false;
  return true;
}
}  // namespace detail
static_assert(detail::is_signal(static_cast<Signal>(kSignals - 1)) && !detail::is_signal(static_cast<Signal>(kSignals)),
              "kSignals must count Signal's enumerators");
static_assert(detail::signals_in_order(), "kTermSignals: one row per Signal, in the enum's order");

// The operator applied to spelled operands, as the printer writes it (no parentheses added
// around the operands: the printer adds them by precedence). param: lp's and warm's tau, the
// power's exponent, the delay's seconds, the number itself, the signal's name.
std::string spell(const TermOp& op, std::string_view a, std::string_view b = {}, std::string_view param = {});
inline std::string spell(Expr::Kind k, std::string_view a, std::string_view b = {}, std::string_view param = {}) {
  return spell(term_op(k), a, b, param);
}

// "d, dd, up, down, lp, warm": the names of the function-call operators, for messages.
std::string function_names();
// "T1, T2, Ta, grad, ton, trun" ("..., ton or trun" with or_last).
std::string signal_names(bool or_last = false);

}  // namespace fogbench::model
