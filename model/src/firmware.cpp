// Compiling a model to the firmware's causal program, and running it (see firmware.hpp).
#include "fogbench/model/firmware.hpp"
#include "fogbench/model/term_ops.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

namespace fogbench::model::firmware {
namespace {

using K = Op::Kind;

// A slope's half-window in samples at this sample interval: 30 s whatever dt is (at least 1).
int half_window(double dt_s) { return std::max(1, static_cast<int>(std::lround(kSlopeHalfWindow_s / dt_s))); }

// An operation's output stream at sample i is the fit's value at sample i - delay.
struct Node {
  int op = -1;
  int delay = 0;  // samples
};

struct Compiler {
  Program& p;
  std::string term;  // the term being compiled, for errors
  std::string error;

  int emit(Op op) {
    if (op.kind == K::slope || op.kind == K::delay) {
      op.ring = p.ring_size;
      p.ring_size += op.n;
    }
    p.ops.push_back(op);
    return static_cast<int>(p.ops.size()) - 1;
  }
  // Delays a node's stream by `by` samples.
  Node later(Node x, int by) {
    if (by <= 0) return x;
    Op d;
    d.kind = K::delay;
    d.a = x.op;
    d.n = by;
    return {emit(d), x.delay + by};
  }
  // An operator kTermOps marks refused fails with its named error; the others compile below
  // (a switch with no default: a new Expr::Kind is a -Wswitch error here).
  std::optional<Node> compile(const Expr& e) {
    if (const TermOp& top = term_op(e.kind); top.firmware == OpFirmware::refused) {
      error = std::string(top.firmware_form);
      return std::nullopt;
    }
    switch (e.kind) {
      case Expr::Kind::number: {
        Op o;
        o.p = e.value;
        return Node{emit(o), 0};
      }
      case Expr::Kind::signal: {
        auto sig = [&](int n) {
          Op o;
          o.kind = K::signal;
          o.n = n;
          return emit(o);
        };
        // kTermSignals says which input a signal is, or that it is T1 - T2, or refused.
        const TermSignal& ts = term_signal(e.signal);
        if (ts.firmware_input == -1) {
          error = std::string(ts.firmware_refusal);
          return std::nullopt;
        }
        if (ts.firmware_input == -2) {
          Op o;
          o.kind = K::sub;
          o.a = sig(0);
          o.b = sig(1);
          return Node{emit(o), 0};
        }
        if (ts.firmware_input == 2) p.uses_ta = true;
        if (ts.firmware_input == 3) p.uses_ton = true;
        return Node{sig(ts.firmware_input), 0};
      }
      case Expr::Kind::d: case Expr::Kind::dd: {
        auto x = compile(*e.a);
        if (!x) return x;
        const int hw = half_window(p.dt_s);
        for (int k = 0; k < term_op(e.kind).derivatives; ++k) {
          Op o;
          o.kind = K::slope;
          o.a = x->op;
          o.n = 2 * hw + 1;
          x = Node{emit(o), x->delay + hw};
        }
        return x;
      }
      case Expr::Kind::lp: case Expr::Kind::up: case Expr::Kind::down: case Expr::Kind::pow: case Expr::Kind::neg: {
        auto x = compile(*e.a);
        if (!x) return x;
        Op o;
        o.a = x->op;
        if (e.kind == Expr::Kind::lp && !(e.value > 0.0 && std::isfinite(e.value))) {
          error = "lp's time constant must be a positive number of seconds";
          return std::nullopt;
        }
        if (e.kind == Expr::Kind::lp) {
          o.kind = K::lp;
          o.p = 1.0 - std::exp(-p.dt_s / e.value);
        } else if (e.kind == Expr::Kind::pow) {
          o.kind = K::pow;
          o.n = e.power;
        } else {
          o.kind = e.kind == Expr::Kind::up ? K::up : e.kind == Expr::Kind::down ? K::down : K::neg;
        }
        return Node{emit(o), x->delay};
      }
      case Expr::Kind::warm: {
        if (!(e.value > 0.0 && std::isfinite(e.value))) {
          error = "warm's time constant must be a positive number of seconds";
          return std::nullopt;
        }
        Op s;
        s.kind = K::signal;
        s.n = 3;
        p.uses_ton = true;
        Op o;
        o.kind = K::warm;
        o.a = emit(s);
        o.p = e.value;
        return Node{emit(o), 0};
      }
      case Expr::Kind::delay: {
        auto x = compile(*e.a);
        if (!x) return x;
        // The value at sample i is the operand's at i - n; the operand's stream already shows
        // it x->delay samples late, so only the rest of n is a delay of its own: a slope's
        // look-ahead is absorbed by a delay around it ((d(T1)@300) is causal, 0 samples late).
        const int n = static_cast<int>(std::lround(e.delay_s / p.dt_s));
        if (n <= 0) return x;
        if (n <= x->delay) return Node{x->op, x->delay - n};
        Op o;
        o.kind = K::delay;
        o.a = x->op;
        o.n = n - x->delay;
        return Node{emit(o), 0};
      }
      case Expr::Kind::add: case Expr::Kind::sub: case Expr::Kind::mul: {
        auto a = compile(*e.a);
        if (!a) return a;
        auto b = compile(*e.b);
        if (!b) return b;
        // Both operands must show the same instant: the earlier one waits for the later.
        const int d = std::max(a->delay, b->delay);
        *a = later(*a, d - a->delay);
        *b = later(*b, d - b->delay);
        Op o;
        o.kind = e.kind == Expr::Kind::add ? K::add : e.kind == Expr::Kind::sub ? K::sub : K::mul;
        o.a = a->op;
        o.b = b->op;
        return Node{emit(o), d};
      }
    }
    error = "internal: unknown expression kind";
    return std::nullopt;
  }
};


}  // namespace

std::string_view to_string(Op::Kind k) {
  switch (k) {
    case K::signal: return "signal";
    case K::number: return "number";
    case K::slope: return "slope";
    case K::lp: return "lp";
    case K::delay: return "delay";
    case K::up: return "up";
    case K::down: return "down";
    case K::pow: return "pow";
    case K::neg: return "neg";
    case K::add: return "add";
    case K::sub: return "sub";
    case K::mul: return "mul";
    case K::warm: return "warm";
  }
  return "?";
}

int causal_lag_s(const Expr& e) {
  Program scratch;  // at 1 s per sample a delay in samples is in seconds
  Compiler c{scratch, {}, {}};
  const auto node = c.compile(e);
  return node ? node->delay : 0;
}

std::expected<Program, std::string> compile(const Model& m, double dt_s, bool allow_late) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) return std::unexpected("the firmware's sample interval must be a positive number of seconds");
  Program p;
  p.dt_s = dt_s;
  p.tref_c = m.tref_c;
  p.mu0_dph = m.mu0_dph;
  // Each term's expression first; its lag is applied once every term's latency is known.
  struct Compiled {
    std::string name;
    Node node;
    int lag = 0;  // samples
    const FittedTerm* ft = nullptr;
  };
  std::vector<Compiled> compiled;
  int late = 0;  // samples: how late the whole model is computed (allow_late)
  for (const auto& ft : m.terms) {
    Compiler c{p, ft.name(), {}};
    const std::string name = to_string(*ft.term.expr) + (ft.term.lag.seconds ? "@" + std::to_string(ft.term.lag.seconds) : "");
    auto node = c.compile(*ft.term.expr);
    if (!node) return std::unexpected("term " + name + ": " + c.error);
    const int lag = static_cast<int>(std::lround(ft.term.lag.seconds / dt_s));
    if (lag < node->delay && !allow_late)
      return std::unexpected("term " + name + " cannot be computed by firmware: its rates are least-squares slopes over " +
                             std::to_string(2 * kSlopeHalfWindow_s + 1) + " s centred on their instant, so the term reads its signals " +
                             std::to_string(static_cast<int>(std::lround((node->delay - lag) * dt_s))) +
                             " s ahead of now; a causal filter needs a lag of at least " +
                             std::to_string(static_cast<int>(std::lround(node->delay * dt_s))) + " s (refit with that lag, e.g. `" +
                             to_string(*ft.term.expr) + "@" + std::to_string(static_cast<int>(std::lround(node->delay * dt_s))) +
                             "`, or with @auto, which the fit holds at lags the firmware can meet; or accept it computed late)");
    late = std::max(late, node->delay - lag);
    compiled.push_back({name, *node, lag, &ft});
  }
  // Every term late by the same amount: mu(t - late), not terms shifted against each other.
  for (const auto& c : compiled) {
    Compiler k{p, c.name, {}};
    const Node out = k.later(c.node, c.lag + late - c.node.delay);
    p.terms.push_back({c.name, out.op, c.ft->coef, coef_unit(*c.ft->term.expr), static_cast<int>(std::lround(late * dt_s))});
  }
  if (static_cast<int>(p.ops.size()) > kMaxOps)
    return std::unexpected("the model needs " + std::to_string(p.ops.size()) + " operations; the firmware holds at most " + std::to_string(kMaxOps));
  if (static_cast<int>(p.terms.size()) > kMaxTerms)
    return std::unexpected("the model has " + std::to_string(p.terms.size()) + " terms; the firmware holds at most " + std::to_string(kMaxTerms));
  if (p.ring_size > kMaxRing)
    return std::unexpected("the model's delays and windows need " + std::to_string(p.ring_size) + " samples of history; the firmware holds at most " +
                           std::to_string(kMaxRing) + " (shorter lags or a longer sample interval)");
  return p;
}

int warm_up_samples(const Program& p) {
  std::vector<int> need(p.ops.size(), 0);  // earlier samples each op's value depends on
  for (std::size_t k = 0; k < p.ops.size(); ++k) {
    const Op& o = p.ops[k];
    const int a = o.a >= 0 ? need[static_cast<std::size_t>(o.a)] : 0;
    const int b = o.b >= 0 ? need[static_cast<std::size_t>(o.b)] : 0;
    switch (o.kind) {
      case K::slope: need[k] = a + o.n - 1; break;
      case K::delay: need[k] = a + o.n; break;
      default: need[k] = std::max(a, b); break;
    }
  }
  int w = 0;
  for (const auto& t : p.terms) w = std::max(w, need[static_cast<std::size_t>(t.op)]);
  return w;
}

InputsUsed inputs_used(const Program& p) {
  InputsUsed u;
  for (const auto& o : p.ops) {
    if (o.kind != K::signal) continue;
    (o.n == 0 ? u.t1 : o.n == 1 ? u.t2 : o.n == 2 ? u.ta : u.ton) = true;
  }
  return u;
}

Compensator::Compensator(const Program& program, Precision precision)
    : program_(&program), precision_(precision), value_(program.ops.size(), 0.0), state_(program.ops.size(), 0.0),
      ring_(static_cast<std::size_t>(program.ring_size), 0.0), pos_(program.ops.size(), 0) {}

double Compensator::step(const Input& in) {
  return precision_ == Precision::single_precision ? step_as<float>(in) : step_as<double>(in);
}

// Every number as Real, each operation as fogcomp.h writes it (the state keeps Real values, held
// in doubles exactly).
template <typename Real>
double Compensator::step_as(const Input& in) {
  const Program& p = *program_;
  const bool first = !started_;
  started_ = true;
  const Real zero = 0;
  const auto R = [](double v) { return static_cast<Real>(v); };
  for (std::size_t k = 0; k < p.ops.size(); ++k) {
    const Op& o = p.ops[k];
    const Real a = o.a >= 0 ? R(value_[static_cast<std::size_t>(o.a)]) : zero;
    const Real b = o.b >= 0 ? R(value_[static_cast<std::size_t>(o.b)]) : zero;
    Real v = zero;
    switch (o.kind) {
      case K::signal:
        v = o.n == 0 ? R(in.t1_c) - R(p.tref_c) : o.n == 1 ? R(in.t2_c) - R(p.tref_c) : o.n == 2 ? R(in.ta_c) - R(p.tref_c) : R(in.ton_s);
        break;
      case K::number: v = R(o.p); break;
      case K::slope: case K::delay: {
        // History of the input, oldest first from pos_; the first sample fills it (a steady hold).
        double* h = ring_.data() + o.ring;
        if (first)
          for (int j = 0; j < o.n; ++j) h[j] = a;
        int& pos = pos_[k];
        if (o.kind == K::delay) {
          v = R(h[pos]);
          h[pos] = a;
          pos = (pos + 1) % o.n;
        } else {
          h[pos] = a;
          pos = (pos + 1) % o.n;
          // Weights in half-steps (2j - n + 1): whole numbers, exact in float as in double.
          Real num = zero, den = zero;
          for (int j = 0; j < o.n; ++j) {
            const Real w = static_cast<Real>(2 * j - o.n + 1);
            num += w * R(h[(pos + j) % o.n]);
            den += w * w;
          }
          v = Real(2) * num / den * (Real(60) / R(p.dt_s));
        }
        break;
      }
      case K::lp: {
        const Real prev = first ? a : R(state_[k]);
        v = prev + R(o.p) * (a - prev);
        state_[k] = v;
        break;
      }
      case K::up: v = a > zero ? a : zero; break;
      case K::down: v = a < zero ? a : zero; break;
      case K::pow: {
        v = a;
        for (int j = 1; j < o.n; ++j) v *= a;
        break;
      }
      case K::neg: v = -a; break;
      case K::add: v = a + b; break;
      case K::sub: v = a - b; break;
      case K::mul: v = a * b; break;
      case K::warm: v = std::exp(-(a > zero ? a : zero) / R(o.p)); break;
    }
    value_[k] = v;
  }
  Real mu = R(p.mu0_dph);
  for (const auto& t : p.terms) mu += R(t.beta) * R(value_[static_cast<std::size_t>(t.op)]);
  return mu;
}

template double Compensator::step_as<float>(const Input&);
template double Compensator::step_as<double>(const Input&);

std::string to_json_text(const Program& p) {
  nlohmann::json ops = nlohmann::json::array();
  for (const auto& o : p.ops)
    ops.push_back({{"kind", to_string(o.kind)}, {"a", o.a}, {"b", o.b}, {"n", o.n}, {"p", o.p}, {"ring", o.ring}});
  nlohmann::json terms = nlohmann::json::array();
  for (const auto& t : p.terms)
    terms.push_back({{"name", t.name}, {"op", t.op}, {"beta", t.beta}, {"unit", t.unit}, {"late_s", t.late_s}});
  return nlohmann::json{{"dt_s", p.dt_s}, {"tref_c", p.tref_c}, {"mu0_dph", p.mu0_dph}, {"ring_size", p.ring_size},
                        {"uses_ta", p.uses_ta}, {"uses_ton", p.uses_ton}, {"ops", ops}, {"terms", terms}}
      .dump(2);
}

namespace {
std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
}  // namespace

std::string to_csv(const Program& p) {
  std::string s = "# fogbench firmware program: dt_s=" + num(p.dt_s) + " tref_c=" + num(p.tref_c) + " mu0_dph=" + num(p.mu0_dph) +
                  " ring_size=" + std::to_string(p.ring_size) + "\n";
  s += "record,index,kind,a,b,n,p,ring,name,beta,unit\n";
  for (std::size_t k = 0; k < p.ops.size(); ++k) {
    const auto& o = p.ops[k];
    s += "op," + std::to_string(k) + "," + std::string(to_string(o.kind)) + "," + std::to_string(o.a) + "," + std::to_string(o.b) + "," +
         std::to_string(o.n) + "," + num(o.p) + "," + std::to_string(o.ring) + ",,,\n";
  }
  for (std::size_t j = 0; j < p.terms.size(); ++j) {
    const auto& t = p.terms[j];
    s += "term," + std::to_string(j) + ",,,,,,," + std::to_string(t.op) + "," + "\"" + t.name + "\"," + num(t.beta) + ",\"" + t.unit + "\"\n";
  }
  return s;
}

std::string to_c(const Program& p, std::string_view name) {
  // Numbers through FOGCOMP_R(): the same initializer builds with doubles or, under
  // FOGCOMP_FLOAT, with floats (an explicit conversion: clean under -Wconversion too).
  auto r = [](double v) { return "FOGCOMP_R(" + num(v) + ")"; };
  std::string s = "/* fogbench firmware program: mu(t) = mu0 + sum beta_j term_j, deg/h. Include after fogcomp.h. */\n";
  s += "static const fogcomp_model " + std::string(name) + " = {\n";
  s += "  " + r(p.dt_s) + ", /* dt_s */\n  " + r(p.tref_c) + ", /* tref_c */\n  " + r(p.mu0_dph) + ", /* mu0_dph */\n";
  s += "  " + std::to_string(p.ops.size()) + ", /* n_ops */\n  {\n";
  for (std::size_t k = 0; k < p.ops.size(); ++k) {
    const auto& o = p.ops[k];
    std::string kind(to_string(o.kind));
    std::transform(kind.begin(), kind.end(), kind.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    s += "    {FOGCOMP_" + kind + ", " + std::to_string(o.a) + ", " + std::to_string(o.b) + ", " + std::to_string(o.n) + ", " + r(o.p) + ", " +
         std::to_string(o.ring) + "}, /* " + std::to_string(k) + " */\n";
  }
  if (p.ops.empty()) s += "    {0, -1, -1, 0, FOGCOMP_R(0), -1},\n";  /* C99 has no empty initializer */
  s += "  },\n  " + std::to_string(p.terms.size()) + ", /* n_terms */\n  {";
  for (const auto& t : p.terms) s += std::to_string(t.op) + ", ";
  if (p.terms.empty()) s += "0";
  s += "}, /* term_op */\n  {";
  for (const auto& t : p.terms) s += r(t.beta) + ", ";
  if (p.terms.empty()) s += "FOGCOMP_R(0)";
  s += "}, /* beta:";
  for (const auto& t : p.terms) s += " " + t.name + " [" + t.unit + "]";
  s += " */\n  " + std::to_string(p.ring_size) + " /* ring_size */\n};\n";
  return s;
}

}  // namespace fogbench::model::firmware
