// Physics of the chamber, the coil and the gyro; see sim.hpp.
#include "fogbench/sim/sim.hpp"

#include "fogbench/model/term_ops.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fogbench::sim {
namespace {

// One exact step of a first-order lag y' = (x - y)/tau over dt for x held constant.
double lag_step(double y, double x, double tau_s, double dt_s) { return x + (y - x) * std::exp(-dt_s / tau_s); }

// The seconds of history a simulated term needs before its first sample: each operator's
// kind of history is a column of model::kTermOps (no default: a new kind of history must say
// what it needs here).
int history_needed(const model::Expr& e) {
  const model::TermOp& op = model::term_op(e.kind);
  int own = 0;
  switch (op.history) {
    case model::OpHistory::none: break;
    case model::OpHistory::derivative: own = 2 * model::kDerivativeHalfWidth * op.derivatives; break;
    case model::OpHistory::lowpass: own = static_cast<int>(8.0 * e.value); break;
    case model::OpHistory::delay: own = e.delay_s; break;
  }
  return own + std::max(e.a ? history_needed(*e.a) : 0, e.b ? history_needed(*e.b) : 0);
}

}  // namespace

std::expected<DriftLaw, std::string> make_drift_law(const UnitParams& u) {
  DriftLaw law;
  law.mu0_dph = u.gyro.mu0_dph;
  law.tref_c = u.gyro.tref_c;
  // A distributed coil's drift is read off its field: the truth terms are the lumped coil's.
  const bool lumped = u.coil.model == CoilModel::lumped;
  for (const auto& [what, text] : {std::pair{"gyro terms", lumped ? u.gyro.terms : std::string()}, std::pair{"effect", u.effects}}) {
    if (text.empty()) continue;
    auto l = model::parse_terms(text);
    if (!l) return std::unexpected(std::string(what) + " '" + text + "': " + l.error().pretty());
    for (auto t : l->terms) {
      if (t.lag.automatic) return std::unexpected(std::string(what) + ": a simulated term needs a fixed lag, not @auto: '" + model::to_string(t) + "'");
      // The simulated gyro has no power-on clock: a term of ton (or warm(tau), which reads it)
      // would evaluate to nothing and leave the run without the effect asked for.
      if (model::uses_signal(*t.expr, model::Signal::ton))
        return std::unexpected(std::string(what) + " '" + model::to_string(t) +
                               "': the simulated gyro has no time since power-on, so ton and warm(tau) cannot be simulated; "
                               "add a warm-up to a run's gyro_dph with its since_power_on_s column instead (docs/simulation.md)");
      law.history_s = std::max(law.history_s, history_needed(*t.expr) + t.lag.seconds);
      law.terms.push_back(std::move(t));
    }
  }
  return law;
}

std::expected<AxisEffects, std::string> parse_axis_effects(std::span<const std::string> options, bool cross_axis) {
  AxisEffects by_axis;
  for (const auto& e : options) {
    const auto eq = e.find('=');
    const auto axis = eq == std::string::npos ? std::nullopt : model::axis_from_string(e.substr(0, eq));
    if (!axis) return std::unexpected("--axis-effect " + e + ": expected AXIS=TERMS, AXIS x, y or z, e.g. y=0.05*T1");
    UnitParams check;
    check.gyro.terms.clear();
    check.effects = e.substr(eq + 1);
    auto law = make_drift_law(check);
    if (!law) return std::unexpected("--axis-effect " + e + ": " + law.error());
    if (!cross_axis)
      for (const auto& t : law->terms)
        if (model::uses_axis_thermistor(*t.expr))
          return std::unexpected("--axis-effect " + e + ": '" + model::to_string(t) +
                                 "' reads an axis's own coil thermistor (T1x..T2z), which this simulation does not give its axes "
                                 "(they share the unit's thermistors; --axis-thermistors gives each its own)");
    const auto k = static_cast<std::size_t>(*axis);
    by_axis.text[k] += (by_axis.text[k].empty() ? "" : " + ") + check.effects;
    for (auto& t : law->terms) by_axis.terms[k].push_back(std::move(t));
  }
  return by_axis;
}

std::expected<std::vector<double>, std::string> drift_series(const DriftLaw& law, std::span<const double> t1_c,
                                                             std::span<const double> t2_c, std::span<const double> ta_c,
                                                             const AxisCoilTemps& axes) {
  const std::size_t n = t1_c.size();
  std::vector<double> t1(n), t2(n), ta(ta_c.size());
  for (std::size_t i = 0; i < n; ++i) {
    t1[i] = t1_c[i] - law.tref_c;
    t2[i] = t2_c[i] - law.tref_c;
  }
  for (std::size_t i = 0; i < ta.size(); ++i) ta[i] = ta_c[i] - law.tref_c;
  model::Signals s{t1, t2, ta, 1.0};
  // Per-axis thermistors as deviations from Tref, as the unit's own are (all six or none).
  std::array<std::vector<double>, 3> at1, at2;
  if (!axes.t1_c[0].empty() || !axes.t1_c[1].empty() || !axes.t1_c[2].empty()) {
    for (std::size_t k = 0; k < 3; ++k) {
      if (axes.t1_c[k].size() != n || axes.t2_c[k].size() != n)
        return std::unexpected(std::string("the per-axis thermistors of axis ") + "xyz"[k] + " are not one per sample (" +
                               std::to_string(axes.t1_c[k].size()) + " and " + std::to_string(axes.t2_c[k].size()) + " for " +
                               std::to_string(n) + " samples)");
      at1[k].resize(n);
      at2[k].resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        at1[k][i] = axes.t1_c[k][i] - law.tref_c;
        at2[k][i] = axes.t2_c[k][i] - law.tref_c;
      }
      s.axis_t1[k] = at1[k];
      s.axis_t2[k] = at2[k];
    }
  }
  std::vector<double> d(n, law.mu0_dph);
  for (const auto& t : law.terms) {
    auto v = model::evaluate(*t.expr, s);
    if (!v) return std::unexpected("'" + model::to_string(t) + "': " + v.error());
    const auto lag = static_cast<std::size_t>(t.lag.seconds);
    for (std::size_t i = 0; i < n; ++i) d[i] += t.coef * (*v)[i >= lag ? i - lag : 0];
  }
  return d;
}

double nonthermal_drift(const GyroTruth& g, double t_run_s) {
  double d = 0.0;
  if (g.ageing_dph_per_h != 0.0) d += g.ageing_dph_per_h * t_run_s / 3600.0;
  if (g.periodic_amplitude_dph != 0.0 && g.periodic_period_s > 0.0)
    d += g.periodic_amplitude_dph * std::sin(2.0 * std::numbers::pi * t_run_s / g.periodic_period_s + g.periodic_phase_rad);
  return d;
}

std::expected<World, std::string> World::create(const SimConfig& cfg) {
  if (cfg.units.empty()) return std::unexpected(std::string("the simulation needs at least one unit"));
  World w;
  w.cfg_ = cfg;
  w.rng_.seed(cfg.seed);
  w.air_c_ = cfg.start_c;
  for (const auto& u : cfg.units) {
    auto law = make_drift_law(u);
    if (!law) return std::unexpected("unit " + u.serial + ": " + law.error());
    if (u.coil.wall_tau_s <= 0 || u.coil.core_tau_s <= 0) return std::unexpected("unit " + u.serial + ": coil time constants must be positive");
    UnitState st;
    st.law = std::move(*law);
    st.t1 = st.t2 = cfg.start_c;
    if (u.coil.model == CoilModel::distributed) {
      auto f = CoilField::create(u.coil.distributed, cfg.start_c);
      if (!f) return std::unexpected("unit " + u.serial + ": coil: " + f.error());
      st.field = std::move(*f);
    }
    int history_s = st.law.history_s;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string& text = k == 0 ? u.x_effects : u.axis_effects[k - 1];
      if (text.empty()) continue;
      UnitParams own;  // the axis's effect alone: no mu0, no truth terms
      own.gyro.mu0_dph = 0.0;
      own.gyro.tref_c = u.gyro.tref_c;
      own.gyro.terms.clear();
      own.effects = text;
      auto al = make_drift_law(own);
      if (!al) return std::unexpected("unit " + u.serial + ": axis " + std::string(1, "xyz"[k]) + ": " + al.error());
      if (!u.axis_coils)
        for (const auto& t : al->terms)
          if (model::uses_axis_thermistor(*t.expr))
            return std::unexpected("unit " + u.serial + ": axis " + std::string(1, "xyz"[k]) + ": '" + model::to_string(t) +
                                   "' reads an axis's own coil (T1x..T2z), and this unit's axes share one coil");
      history_s = std::max(history_s, al->history_s);
      st.axis_law[k] = std::move(*al);
    }
    if (u.axis_coils) {
      for (std::size_t k = 0; k < 2; ++k) {
        const CoilParams& c = (*u.axis_coils)[k];
        if (c.wall_tau_s <= 0 || c.core_tau_s <= 0)
          return std::unexpected("unit " + u.serial + ": axis " + std::string(1, "yz"[k]) + "'s coil: time constants must be positive");
        UnitState::AxisCoil ac;
        ac.t1 = ac.t2 = cfg.start_c;
        if (c.model == CoilModel::distributed) {
          auto f = CoilField::create(c.distributed, cfg.start_c);
          if (!f) return std::unexpected("unit " + u.serial + ": axis " + std::string(1, "yz"[k]) + "'s coil: " + f.error());
          ac.field = std::move(*f);
        }
        st.axis_coils.push_back(std::move(ac));
      }
    } else {
      for (const auto& t : st.law.terms)
        if (model::uses_axis_thermistor(*t.expr))
          return std::unexpected("unit " + u.serial + ": '" + model::to_string(t) +
                                 "' reads an axis's own coil (T1x..T2z), and this unit's axes share one coil");
    }
    w.window_ = std::max<std::size_t>(w.window_, static_cast<std::size_t>(history_s) + 2 * model::kDerivativeHalfWidth + 64);
    w.units_.push_back(std::move(st));
  }
  return w;
}

AxisCoilTemps World::axis_history(const UnitState& u) const {
  AxisCoilTemps a;
  if (u.axis_coils.empty()) return a;
  a.t1_c = {std::span<const double>(u.h1), std::span<const double>(u.axis_coils[0].h1), std::span<const double>(u.axis_coils[1].h1)};
  a.t2_c = {std::span<const double>(u.h2), std::span<const double>(u.axis_coils[0].h2), std::span<const double>(u.axis_coils[1].h2)};
  return a;
}

CoilParams deeper_in_housing(CoilParams c, std::size_t axis) {
  const double factor = axis == 1 ? 1.6 : axis == 2 ? 2.4 : 1.0;
  c.wall_tau_s *= factor;
  c.distributed.film_tau_s *= factor;
  c.distributed.mount_tau_s *= factor;
  return c;
}

double World::gyro_noise(UnitState& u, const UnitParams& p) {
  std::normal_distribution<double> a(0.0, p.gyro.sigma_a_dph);
  const double k1 = p.gyro.ar.size() > 0 ? p.gyro.ar[0] : 0.0;
  const double k2 = p.gyro.ar.size() > 1 ? p.gyro.ar[1] : 0.0;
  const double n = k1 * u.n1 + k2 * u.n2 + a(rng_);
  u.n2 = u.n1;
  u.n1 = n;
  double extra = 0.0;
  std::normal_distribution<double> unit(0.0, 1.0);
  if (p.gyro.bias_instability_dph > 0.0) {
    // Flicker: Markov processes with time constants tau_j = 2 s * 3^j up to 10^6 s, each of
    // variance h ln(3), h = B^2 / pi: their sum has the one-sided PSD h / f between the
    // corners (each process's PSD integrated over log-spaced tau, h / (f ln r) per unit
    // variance), whose Allan variance is 2 ln2 h = (2 ln2 / pi) B^2, the IEEE 952 floor.
    const double var_j = p.gyro.bias_instability_dph * p.gyro.bias_instability_dph * std::log(3.0) / std::numbers::pi;
    std::size_t j = 0;
    for (double tau = 2.0; tau <= 1e6; tau *= 3.0, ++j) {
      if (u.flicker.size() <= j) u.flicker.push_back(std::sqrt(var_j) * unit(rng_));  // started stationary
      const double decay = std::exp(-1.0 / tau);
      u.flicker[j] = decay * u.flicker[j] + std::sqrt(var_j * (1.0 - decay * decay)) * unit(rng_);
      extra += u.flicker[j];
    }
  }
  if (p.gyro.rrw_dph_per_sqrt_h > 0.0) {
    // K deg/h/sqrt(h): after t s the walk's variance is K^2 t / 3600, a step of K / 60 a second.
    u.walk += p.gyro.rrw_dph_per_sqrt_h / 60.0 * unit(rng_);
    extra += u.walk;
  }
  double spike = 0.0;
  if (std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < p.gyro.outlier_rate_per_s)
    spike = (std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < 0.5 ? -1.0 : 1.0) * p.gyro.outlier_dph;
  return n + extra + spike;
}

double World::chamber_reading_c() {
  return air_c_ + std::normal_distribution<double>(0.0, cfg_.chamber.air_noise_c)(rng_);
}

void World::step(double setpoint_c) {
  // Air: first-order lag to the setpoint, its rate capped by the chamber's capacity.
  const double target = lag_step(air_c_, setpoint_c, cfg_.chamber.air_tau_s, 1.0);
  const double cap = cfg_.chamber.max_rate_c_per_min / 60.0;
  air_c_ += std::clamp(target - air_c_, -cap, cap);
  time_s_ += 1.0;
  for (std::size_t i = 0; i < units_.size(); ++i) {
    auto& u = units_[i];
    const auto& p = cfg_.units[i];
    if (u.field) {
      u.field->step(air_c_);
      u.t1 = u.field->at(p.coil.distributed.t1_at);
      u.t2 = u.field->at(p.coil.distributed.t2_at);
      u.field_drift = u.field->drift_dph(p.gyro.tref_c);
    } else {
      u.t2 = lag_step(u.t2, air_c_, p.coil.wall_tau_s, 1.0);
      u.t1 = lag_step(u.t1, u.t2, p.coil.core_tau_s, 1.0);
    }
    for (std::size_t k = 0; k < u.axis_coils.size(); ++k) {
      auto& ac = u.axis_coils[k];
      const CoilParams& c = (*p.axis_coils)[k];
      if (ac.field) {
        ac.field->step(air_c_);
        ac.t1 = ac.field->at(c.distributed.t1_at);
        ac.t2 = ac.field->at(c.distributed.t2_at);
        ac.field_drift = ac.field->drift_dph(p.gyro.tref_c);
      } else {
        ac.t2 = lag_step(ac.t2, air_c_, c.wall_tau_s, 1.0);
        ac.t1 = lag_step(ac.t1, ac.t2, c.core_tau_s, 1.0);
      }
    }
    u.h1.push_back(u.t1);
    u.h2.push_back(u.t2);
    u.ha.push_back(air_c_);
    for (auto& ac : u.axis_coils) {
      ac.h1.push_back(ac.t1);
      ac.h2.push_back(ac.t2);
    }
    if (!streaming_drift_) {
      u.h1.clear();
      u.h2.clear();
      u.ha.clear();
      for (auto& ac : u.axis_coils) {
        ac.h1.clear();
        ac.h2.clear();
      }
    } else if (u.h1.size() > 2 * window_) {  // keep a trailing window: amortised O(1) per step
      const auto drop = static_cast<std::ptrdiff_t>(u.h1.size() - window_);
      for (auto* h : {&u.h1, &u.h2, &u.ha}) h->erase(h->begin(), h->begin() + drop);
      for (auto& ac : u.axis_coils)
        for (auto* h : {&ac.h1, &ac.h2}) h->erase(h->begin(), h->begin() + drop);
    }
    // The drift of the newest second from the trailing window; terms whose lag is shorter
    // than a centred filter's half-width see the window's one-sided edge (as a run's end does).
    const AxisCoilTemps axes = axis_history(u);
    double drift = u.law.mu0_dph;
    if (!streaming_drift_) {
      drift = 0.0;
    } else if (auto d = drift_series(u.law, u.h1, u.h2, u.ha, axes)) {
      drift = d->back();
    }
    for (std::size_t k = 0; k < 3; ++k) {
      u.axis_drift[k] = 0.0;
      if (!streaming_drift_) continue;
      if (u.axis_law[k])
        if (auto d = drift_series(*u.axis_law[k], u.h1, u.h2, u.ha, axes)) u.axis_drift[k] = d->back();
      // An axis with a coil of its own: the unit's drift read on that coil, less x's.
      if (k > 0 && !u.axis_coils.empty()) {
        const auto& ac = u.axis_coils[k - 1];
        if (auto d = drift_series(u.law, ac.h1, ac.h2, u.ha, axes)) u.axis_drift[k] += d->back() - drift;
        if (ac.field) u.axis_drift[k] += ac.field_drift - u.field_drift;
      }
    }
    drift += u.axis_drift[0];
    if (u.field) drift += u.field_drift;
    drift += nonthermal_drift(p.gyro, time_s_ - 1.0);
    std::normal_distribution<double> tn(0.0, p.coil.t_noise_c);
    u.last.t1_c = u.t1 + tn(rng_);
    u.last.t2_c = u.t2 + tn(rng_);
    // Drawn only for axis coils, so a unit without them draws the numbers it always did.
    for (std::size_t k = 0; k < u.axis_coils.size(); ++k) {
      std::normal_distribution<double> an(0.0, (*p.axis_coils)[k].t_noise_c);
      u.last.axis_t1_c[k] = u.axis_coils[k].t1 + an(rng_);
      u.last.axis_t2_c[k] = u.axis_coils[k].t2 + an(rng_);
    }
    u.last.noise_dph = gyro_noise(u, p);
    u.last.gyro_dph = drift + u.last.noise_dph;
  }
}

std::expected<std::vector<model::RunData>, std::string> simulate(const SimConfig& cfg,
                                                                 const std::vector<SetpointSample>& program) {
  auto world = World::create(cfg);
  if (!world) return std::unexpected(world.error());
  world->set_streaming_drift(false);  // evaluated over the whole run below
  const std::size_t n = program.size();
  const std::size_t nu = cfg.units.size();
  std::vector<model::RunData> runs(nu);
  std::vector<std::vector<double>> t1(nu), t2(nu), noise(nu), field(nu);
  std::vector<double> air(n);
  for (std::size_t u = 0; u < nu; ++u) {
    runs[u].name = cfg.units[u].serial;
    for (auto* v : {&runs[u].time_s, &runs[u].gyro_dph, &runs[u].t1_c, &runs[u].t2_c, &runs[u].setpoint_c, &runs[u].chamber_c}) v->reserve(n);
  }
  // The sample at time t describes the second that ended at t, as the daemon records it.
  for (std::size_t i = 0; i < n; ++i) {
    world->step(program[i].setpoint_c);
    air[i] = world->air_c();
    const double reading = world->chamber_reading_c();
    for (std::size_t u = 0; u < nu; ++u) {
      auto& r = runs[u];
      const auto s = world->sample(u);
      r.time_s.push_back(static_cast<double>(i));
      r.t1_c.push_back(s.t1_c);
      r.t2_c.push_back(s.t2_c);
      r.setpoint_c.push_back(program[i].setpoint_c);
      r.chamber_c.push_back(reading);
      r.phase.push_back(program[i].phase);
      r.step.push_back(program[i].step);
      t1[u].push_back(world->true_t1_c(u));
      t2[u].push_back(world->true_t2_c(u));
      noise[u].push_back(s.noise_dph);
      if (world->field(u)) field[u].push_back(world->field_drift_dph(u));
    }
  }
  // Offline the drift is evaluated over the whole run with centred filters, exactly as the
  // model computes its terms; the noise is the same realisation the streaming gyro had.
  for (std::size_t u = 0; u < nu; ++u) {
    auto law = make_drift_law(cfg.units[u]);
    auto exact = drift_series(*law, t1[u], t2[u], air);
    if (!exact) return std::unexpected("unit " + cfg.units[u].serial + ": " + exact.error());
    runs[u].gyro_dph.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      runs[u].gyro_dph[i] = (*exact)[i] + noise[u][i] + nonthermal_drift(cfg.units[u].gyro, static_cast<double>(i));
    // A distributed coil's drift comes from its field, stepped with the world.
    if (!field[u].empty())
      for (std::size_t i = 0; i < n; ++i) runs[u].gyro_dph[i] += field[u][i];
  }
  return runs;
}

}  // namespace fogbench::sim
