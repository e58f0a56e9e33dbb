// The model as a gyro's firmware evaluates it: every term a causal recursion at the firmware's
// own sample rate (rates as a least-squares slope over the last 61 samples, lp as a first-order
// IIR, lags as whole-sample delays), compiled to a flat program of operations that the C99
// reference implementation (firmware/fogcomp.h) runs with fixed-size state and no allocation.
// Compensator runs the same program here, sample by sample: fogctl's reference vectors and the
// daemon's live compensation come from it.
//
// Causality. The fit's d(x) is a slope centred on its sample (30 s either side). A causal slope
// over the last 61 samples is that centred slope 30 s late, so every d adds 30 s of delay to
// what follows it; a term's lag pays for it. A term whose lag is shorter than the delays inside
// it would read the future (d(T2)@13 ends 17 s ahead): compile() refuses it, naming the term.
// Up to that shift, and after the opening samples (the firmware starts its windows and filters
// from the first sample as a steady hold), the program computes exactly what predict() does.
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

// Limits of the C reference implementation's fixed-size state (firmware/fogcomp.h).
inline constexpr int kMaxOps = 64;
inline constexpr int kMaxTerms = 16;
inline constexpr int kMaxRing = 8192;

// Compiles a fitted model for a firmware sampling every dt_s. Errors name the term and why.
// allow_late: a term that would read the future is computed as late as causality requires
// instead (ProgramTerm::late_s says by how much); the compensation is then no longer the model's.
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

// Runs a program sample by sample, as firmware/fogcomp.h does (same operations, same order).
class Compensator {
 public:
  explicit Compensator(const Program& program);
  // The drift mu(t) of this sample, deg/h; the compensated rate is the gyro's minus it.
  double step(const Input& in);

 private:
  const Program* program_;
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
