// The model as a gyro's firmware evaluates it: every term a causal recursion at the firmware's
// own sample rate (rates as a least-squares slope over the last 61 s, lp as a first-order
// IIR, lags as whole-sample delays), compiled to a flat program of operations that the C99
// reference implementation (firmware/fogcomp.h) runs with fixed-size state and no allocation.
// Compensator runs the same program here, sample by sample: fogctl's reference vectors and the
// daemon's live compensation come from it.
//
// Causality. The fit's d(x) is a slope centred on its sample (30 s either side). A causal slope
// over the last 61 s is that centred slope 30 s late, so every d adds 30 s of delay to what
// follows it; a term's lag pays for it. The fit searches @auto lags only where the lag pays
// (FitOptions::causal_lags, causal_lag_s below), so a fitted model has a firmware form; a term
// whose written lag is shorter than the delays inside it would read the future (d(T2)@13 ends
// 17 s ahead): compile() refuses it, naming the term. Up to that shift, and after the opening
// samples (the firmware starts its windows and filters from the first sample as a steady hold),
// the program computes exactly what predict() does.
//
// Windows and delays are in seconds: a slope spans 60 s (2 round(30 s / dt) + 1 samples, the
// fit's 61 one-second samples), a lag of L s is round(L / dt) samples, whatever dt is.
#pragma once

#include <cstddef>
#include <cstdint>
#include <expected>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fogbench/model/model.hpp"

namespace fogbench::model::firmware {

// One operation. Inputs are earlier operations (a, b: indices into Program::ops).
struct Op {
  enum class Kind : std::uint8_t {
    signal,  // n: 0 T1, 1 T2, 2 Ta, 3 ton; temperatures minus tref_c (degC), ton in s
    number,  // p: the value
    slope,   // least-squares slope of a over its last n samples, per minute
    lp,      // y += p * (a - y), p = 1 - exp(-dt/tau)
    delay,   // a, n samples earlier
    up,      // max(a, 0)
    down,    // min(a, 0)
    pow,     // a^n, n = 2..4
    neg,     // -a
    add,     // a + b
    sub,     // a - b
    mul,     // a * b
    warm,    // exp(-max(a, 0) / p), a the time since power-on in s, p = tau in s
  };
  Kind kind = Kind::number;
  int a = -1, b = -1;
  int n = 0;           // signal index, window or delay length in samples, power
  double p = 0.0;      // number, lp's alpha, warm's tau (s)
  int ring = -1;       // slope, delay: first index of its history in the state's ring pool
};
std::string_view to_string(Op::Kind k);

struct ProgramTerm {
  std::string name;   // the term as the model writes it, e.g. "d(T1)@38"
  int op = -1;        // the operation whose value is the term (its lag applied)
  double beta = 0.0;  // deg/h per unit of the term (unit: coef_unit of the term)
  std::string unit;   // e.g. "deg/h per degC/min"
  int late_s = 0;     // compiled with allow_late: how much later than the model the term is, s
};

struct Program {
  double dt_s = 1.0;      // the firmware's sample interval, s
  double tref_c = 20.0;   // temperatures enter as T - tref_c, degC
  double mu0_dph = 0.0;   // constant bias, deg/h
  std::vector<Op> ops;
  std::vector<ProgramTerm> terms;
  int ring_size = 0;      // doubles of history the state needs
  bool uses_ta = false, uses_ton = false;
};

// The least lag (s) at which a firmware computes the term on time: 30 s per rate d() that no
// delay written inside the term pays for (0 for a term without a rate; d(T1) 30, dd(T1) 60,
// (d(T1)@300) 0). The fit holds @auto lags at or above it (FitOptions::causal_lags).
int causal_lag_s(const Expr& e);

// Slope half-window, s: the fit's d() is a least-squares slope over 61 one-second samples.
inline constexpr int kSlopeHalfWindow_s = 30;

// Limits of the C reference implementation's fixed-size state (firmware/fogcomp.h).
inline constexpr int kMaxOps = 64;
inline constexpr int kMaxTerms = 16;
inline constexpr int kMaxRing = 8192;

// Compiles a fitted model for a firmware sampling every dt_s. Errors name the term and why
// (a lag the firmware cannot meet, a filter or warm-up time constant that is not positive).
// allow_late: when a term would read the future, the whole model is computed as late as its
// latest term requires (every ProgramTerm::late_s the same): mu(t) is the model's mu(t - late),
// never terms shifted against each other (two correlated terms, d(T1) and grad, that cancel in
// the model would stop cancelling). The compensation is then no longer the model's.
std::expected<Program, std::string> compile(const Model& m, double dt_s = 1.0, bool allow_late = false);

// How many opening samples of a program lean on the steady-hold fill of its windows and delays:
// from sample index warm_up_samples(p) on (0-based), every slope and delay reads only samples
// really given (lp filters start at their first input, as in the firmware, and never "fill").
int warm_up_samples(const Program& p);

// Which of the four inputs (t1, t2, ta, ton) a program reads.
struct InputsUsed {
  bool t1 = false, t2 = false, ta = false, ton = false;
};
InputsUsed inputs_used(const Program& p);

// One sample of the firmware's inputs: temperatures in degC (absolute), ton in s.
struct Input {
  double t1_c = 0.0, t2_c = 0.0, ta_c = 0.0, ton_s = 0.0;
};

// The arithmetic of a firmware build: fogcomp.h in double (the default), or in float
// (FOGCOMP_FLOAT, a microcontroller's single-precision FPU).
enum class Precision : std::uint8_t { double_precision, single_precision };

// Tolerances of a port against fogctl's reference vector (deg/h), the same precision on both
// sides. Double: every operation the same, in the same order (1e-9, far below any rounding that
// matters). Float: a float's 24 bits keep ~1e-7 relative; what differs between two float builds
// is the order and contraction (FMA) of the slope's 61-term sums and of the lp recursion: a few
// float ulps of the terms, times betas of tens of deg/h per unit: about 1e-5 deg/h, held to 1e-4
// (a thousandth of a gyro's 1 s noise, 0.1-0.2 deg/h). A float build differs from the double
// reference by ~1e-4 deg/h.
inline constexpr double kToleranceDouble_dph = 1e-9;
inline constexpr double kToleranceFloat_dph = 1e-4;

// Runs a program sample by sample, as firmware/fogcomp.h does (same operations, same order), in
// double or, with Precision::single_precision, in float as a FOGCOMP_FLOAT build does.
class Compensator {
 public:
  explicit Compensator(const Program& program, Precision precision = Precision::double_precision);
  // The drift mu(t) of this sample, deg/h; the compensated rate is the gyro's minus it.
  double step(const Input& in);

 private:
  template <typename Real>
  double step_as(const Input& in);
  const Program* program_;
  Precision precision_;
  std::vector<double> value_, state_, ring_;
  std::vector<int> pos_;
  bool started_ = false;
};

// The program as text: JSON (the canonical form), CSV (one operation per line) or a C
// initializer for firmware/fogcomp.h (`static const fogcomp_model NAME = {...};`).
std::string to_json_text(const Program& p);
std::string to_csv(const Program& p);
std::string to_c(const Program& p, std::string_view name);

}  // namespace fogbench::model::firmware
