// The coil models: the lumped coil is the two-node coil of before, bit for bit; the distributed
// coil's conduction against the heat equation's steady ramp, its thermistor placements, the
// drift read off its field, and the paper's model on it near the paper's Table 1.
#include <catch2/catch.hpp>
#include <cmath>

#include "fogbench/model/model.hpp"
#include "fogbench/sim/coil.hpp"
#include "fogbench/sim/sim.hpp"
#include "programs.hpp"

using namespace fogbench;
using fogbench::test::program;

namespace {

sim::SimConfig distributed(std::uint64_t seed) {
  sim::SimConfig cfg;
  cfg.seed = seed;
  cfg.units[0].coil.model = sim::CoilModel::distributed;
  return cfg;
}

}  // namespace

TEST_CASE("lumped coil: the same run, bit for bit, as the two-node coil before the distributed one") {
  // Recorded with the simulator of commit 1d4731d (before coil.hpp existed): exp1, seed 1,
  // default configuration, whole-run simulate() and the streaming World after 3000 s. The
  // temperatures bit for bit; the drift to 1e-9 relative since d(x)'s window sums were made
  // exact on long runs (2026-11-29, docs/model.md): its last bits moved (1e-11 relative).
  sim::SimConfig cfg;
  cfg.seed = 1;
  REQUIRE(cfg.units[0].coil.model == sim::CoilModel::lumped);  // the library's default
  const auto prog = program("exp1");
  auto r = sim::simulate(cfg, prog);
  REQUIRE(r);
  const auto& d = r->front();
  CHECK(d.gyro_dph[0] == Approx(-0x1.ffca5267ee7c6p+2).epsilon(1e-9));
  CHECK(d.t1_c[0] == 0x1.3ff813e332c86p+4);
  CHECK(d.t2_c[0] == 0x1.3fff316e45f13p+4);
  CHECK(d.gyro_dph[1000] == Approx(-0x1.7275d33cd0594p+2).epsilon(1e-9));
  CHECK(d.t1_c[1000] == 0x1.116bfaf10d39p+4);
  CHECK(d.t2_c[1000] == 0x1.0863ce666cce3p+4);
  CHECK(d.gyro_dph[2500] == Approx(-0x1.0a6a3e26b08f8p+3).epsilon(1e-9));
  CHECK(d.t1_c[2500] == 0x1.42941919f0ffap+3);
  CHECK(d.gyro_dph[5400] == Approx(-0x1.45ccaf2de77efp+2).epsilon(1e-9));
  CHECK(d.t2_c[5400] == 0x1.7690891d1fb35p+4);
  auto w = sim::World::create(cfg);
  REQUIRE(w);
  for (int i = 0; i < 3000; ++i) w->step(prog[static_cast<std::size_t>(i)].setpoint_c);
  CHECK(w->sample(0).gyro_dph == Approx(-0x1.5fe3ab9d12447p+3).epsilon(1e-9));
  CHECK(w->sample(0).t1_c == 0x1.fe8b13161162dp+3);
  CHECK(w->sample(0).t2_c == 0x1.09509e5e96e46p+4);
  CHECK(w->field(0) == nullptr);
  CHECK(w->field_drift_dph(0) == 0.0);
}

TEST_CASE("distributed coil: a steady ramp gives the heat equation's gradient and the Shupe term its full rate") {
  // Hub and mount decoupled (time constants of 1e9 s), a thin winding far from the axis (a
  // slab): heated through the outer face only at b = 1 degC/min, the quasi-steady profile is
  // T(x) = T_out - b/(2 alpha) (D^2 - x^2) with x from the insulated inner face, so between the
  // centres of the inner (x = h/2) and outer (x = D - h/2) layers, h = D/N:
  //   T_out - T_in = b D^2/(2 alpha) (1 - 1/N) = (b tau_w / 2)(1 - 1/N)
  //   = (1/60 degC/s)(200 s / 2)(7/8) = 1.4583 degC.
  // The slab's curvature correction is of order D/r = 10/1000 (1%); the film lags the whole
  // winding behind the air but does not change the profile.
  sim::DistributedCoil p;
  p.inner_radius_mm = 1000.0;
  p.outer_radius_mm = 1010.0;
  p.winding_tau_s = 200.0;
  p.mount_tau_s = 1e9;
  p.contact_tau_s = 1e9;
  auto f = sim::CoilField::create(p, 20.0);
  REQUIRE(f);
  CHECK(f->substeps() >= 1);
  // 4000 s: the slowest transient (the film, 300 s, with the conduction) has decayed by e^-10.
  for (int t = 1; t <= 4000; ++t) f->step(20.0 + t / 60.0);
  const auto layers = f->layers_c();
  REQUIRE(layers.size() == 8);
  CHECK(layers.back() - layers.front() == Approx(200.0 / 2.0 / 60.0 * 7.0 / 8.0).epsilon(0.02));
  // Every layer ramps with the air: the weighted rate is b, the Shupe term S * 1 degC/min.
  CHECK(f->weighted_rate_c_per_min() == Approx(1.0).epsilon(1e-3));
  CHECK(f->shupe_dph() == Approx(p.shupe_dph_per_c_per_min).epsilon(1e-3));
  // Stress on the inner-minus-outer gradient (negative when heating).
  CHECK(f->stress_dph() == Approx(p.stress_dph_per_c * (layers.front() - layers.back())));
  for (std::size_t i = 1; i < layers.size(); ++i) CHECK(layers[i] > layers[i - 1]);
}

TEST_CASE("distributed coil: placements, weights, rest and refusals") {
  sim::DistributedCoil p;
  auto f = sim::CoilField::create(p, 20.0);
  REQUIRE(f);
  // At rest at tref nothing drifts.
  f->step(20.0);
  CHECK(f->drift_dph(20.0) == 0.0);
  // The Shupe weights sum to 1 and lean outwards (the fibre's distance from its midpoint).
  double sum = 0.0;
  const auto w = f->shupe_weights();
  for (std::size_t i = 0; i < w.size(); ++i) {
    sum += w[i];
    if (i > 0) CHECK(w[i] > w[i - 1]);
  }
  CHECK(sum == Approx(1.0).epsilon(1e-12));
  // Heat from the air for a while: the outer layer is warmest, the hub (through the mount's
  // 600 s) coolest; placements read what they name.
  for (int t = 0; t < 300; ++t) f->step(40.0);
  const auto layers = f->layers_c();
  CHECK(f->at(sim::Placement::inner) == layers.front());
  CHECK(f->at(sim::Placement::outer) == layers.back());
  CHECK(f->at(sim::Placement::middle) == Approx(0.5 * (layers[3] + layers[4])));
  CHECK(f->at(sim::Placement::hub) == f->hub_c());
  CHECK(layers.back() > layers.front());
  CHECK(f->hub_c() < layers.front());
  // Held long enough, the whole field settles at the air's temperature.
  for (int t = 0; t < 20000; ++t) f->step(40.0);
  for (double x : f->layers_c()) CHECK(x == Approx(40.0).margin(1e-6));
  CHECK(f->hub_c() == Approx(40.0).margin(1e-6));

  sim::DistributedCoil bad = p;
  bad.layers = 5;
  CHECK_THAT(sim::CoilField::create(bad, 20.0).error(), Catch::Contains("layers"));
  bad = p;
  bad.outer_radius_mm = 30.0;
  CHECK_THAT(sim::CoilField::create(bad, 20.0).error(), Catch::Contains("outer_radius_mm"));
  CHECK_THAT(sim::parse_placement("centre").error(), Catch::Contains("hub, inner, middle, outer"));
  CHECK(*sim::parse_coil_model("lumped") == sim::CoilModel::lumped);
  auto cfg = distributed(1);
  cfg.units[0].coil.distributed.film_tau_s = -1.0;
  CHECK_THAT(sim::World::create(cfg).error(), Catch::Contains("film_tau_s"));
}

TEST_CASE("distributed coil: the thermistors read the placed layers, the gyro the field's drift") {
  auto cfg = distributed(3);
  cfg.units[0].coil.t_noise_c = 0.0;
  cfg.units[0].coil.distributed.t1_at = sim::Placement::middle;
  cfg.units[0].coil.distributed.t2_at = sim::Placement::hub;
  cfg.units[0].gyro.sigma_a_dph = 0.0;
  cfg.units[0].gyro.outlier_rate_per_s = 0.0;
  auto w = sim::World::create(cfg);
  REQUIRE(w);
  for (int t = 0; t < 900; ++t) w->step(t < 300 ? 20.0 : 30.0);
  const auto* f = w->field(0);
  REQUIRE(f);
  CHECK(w->sample(0).t1_c == f->at(sim::Placement::middle));
  CHECK(w->sample(0).t2_c == f->hub_c());
  // Noise off: the gyro is mu0 plus the field's drift (the default truth terms are the lumped
  // coil's and are not applied).
  CHECK(w->sample(0).gyro_dph == Approx(cfg.units[0].gyro.mu0_dph + f->drift_dph(20.0)).margin(1e-12));
  CHECK(w->field_drift_dph(0) == f->drift_dph(20.0));
  CHECK(std::abs(f->drift_dph(20.0)) > 0.01);  // still warming 10 min after the step

  // simulate() gives the same gyro as the streaming world (the field's drift is added either way).
  auto sp = program("exp2");
  sp.resize(1500);
  auto r = sim::simulate(cfg, sp);
  REQUIRE(r);
  auto w2 = sim::World::create(cfg);
  for (const auto& s : sp) w2->step(s.setpoint_c);
  CHECK(r->front().gyro_dph.back() == Approx(w2->sample(0).gyro_dph).margin(1e-9));
}

TEST_CASE("distributed coil: the paper's model fitted on exp1 lands near the paper's Table 1") {
  // The paper (METHOD.md): raw std 1.26 to 1.98 deg/h, compensated 0.21 to 0.32 with a noise
  // of sigma_a 0.146, i.e. 1.4 to 2.2 times it, and comp/raw 13 to 17%. The lumped coil with
  // the same seeds has the same noise realisation (the field draws no random numbers) and
  // leaves only it: its compensated std is this run's noise floor.
  const char* names[] = {"exp1", "exp2", "exp3"};
  std::vector<model::RunData> dist, lump;
  for (std::uint64_t i = 0; i < 3; ++i) {
    auto cfg = distributed(61 + i);
    auto r = sim::simulate(cfg, program(names[i]));
    REQUIRE(r);
    dist.push_back(r->front());
    cfg.units[0].coil.model = sim::CoilModel::lumped;
    auto l = sim::simulate(cfg, program(names[i]));
    REQUIRE(l);
    lump.push_back(l->front());
  }
  auto m = model::fit(dist[0], *model::parse_terms("paper"), model::FitOptions{});
  REQUIRE(m);
  auto ml = model::fit(lump[0], *model::parse_terms("paper"), model::FitOptions{});
  REQUIRE(ml);
  for (std::size_t i = 0; i < 3; ++i) {
    auto v = model::verify(*m, dist[i]);
    auto vl = model::verify(*ml, lump[i]);
    REQUIRE(v);
    REQUIRE(vl);
    const double floor = vl->run.comp_std;
    INFO(names[i] << ": raw " << v->run.meas_std << " comp " << v->run.comp_std << " floor " << floor);
    // Measured with seeds 1, 7, 11, 41, 61: raw 2.1/1.35/1.8 deg/h, comp 1.55 to 1.75 x the
    // floor, comp/raw 11 to 18%. Bounds: 1.3 to 2.2 x, the paper's span with a margin.
    CHECK(v->run.meas_std > 1.1);
    CHECK(v->run.meas_std < 2.5);
    CHECK(v->run.comp_std > 1.3 * floor);
    CHECK(v->run.comp_std < 2.2 * floor);
    CHECK(v->run.ratio < 0.2);  // the paper's rule still passes
  }
}
