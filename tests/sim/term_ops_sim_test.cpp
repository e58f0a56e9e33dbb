// The simulator's side of the operators' table (model/include/fogbench/model/term_ops.hpp):
// every operator, as a simulated effect, adds its coefficient times the model's evaluation of
// it to the drift, and keeps the history its table row asks for; one that reads the power-on
// time (which the simulated bench does not give the drift) is refused naming ton.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>

#include "fogbench/model/term_ops.hpp"
#include "fogbench/sim/sim.hpp"

using namespace fogbench;

namespace {
// Whether any operator of the expression asks the simulator for history (its row's OpHistory).
bool needs_history(const model::Expr& e) {
  return model::term_op(e.kind).history != model::OpHistory::none || (e.a && needs_history(*e.a)) || (e.b && needs_history(*e.b));
}
}  // namespace

TEST_CASE("sim term ops: every operator of the table is applied as the model evaluates it", "[sim][term_ops]") {
  std::vector<double> t1, t2, ta;
  for (int i = 0; i < 400; ++i) {
    const double x = i;
    t1.push_back(20.0 + 0.8 * std::sin(x / 40.0));
    t2.push_back(20.0 + 0.3 * std::cos(x / 55.0));
    ta.push_back(21.0 + (i < 50 ? 0.0 : 1.0));
  }
  for (const model::TermOp& op : model::kTermOps) {
    INFO(op.name << " example " << op.example);
    sim::UnitParams u;
    u.coil.model = sim::CoilModel::lumped;
    u.gyro.terms = "";
    u.gyro.mu0_dph = -2.0;
    u.effects = "0.5*" + std::string(op.example);
    auto law = sim::make_drift_law(u);
    auto parsed = model::parse_terms(u.effects);
    REQUIRE(parsed);
    if (model::uses_signal(*parsed->terms.at(0).expr, model::Signal::ton)) {
      // Refused where the law is made (so fogctl simulate and the mock bench refuse it too),
      // naming ton: never a run silently without the effect asked for.
      REQUIRE_FALSE(law);
      CHECK(law.error().find("ton") != std::string::npos);
      sim::SimConfig cfg;
      cfg.units = {u};
      auto world = sim::World::create(cfg);
      REQUIRE_FALSE(world);
      CHECK(world.error().find("power-on") != std::string::npos);
      continue;
    }
    REQUIRE(law);
    REQUIRE(law->terms.size() == 1);
    CHECK((law->history_s > 0) == needs_history(*law->terms[0].expr));
    auto d = sim::drift_series(*law, t1, t2, ta);
    const auto& expr = *law->terms[0].expr;
    REQUIRE(d);
    std::vector<double> d1(t1.size()), d2(t2.size()), da(ta.size());
    for (std::size_t i = 0; i < t1.size(); ++i) {
      d1[i] = t1[i] - law->tref_c;
      d2[i] = t2[i] - law->tref_c;
      da[i] = ta[i] - law->tref_c;
    }
    auto v = model::evaluate(expr, model::Signals{d1, d2, da, 1.0});
    REQUIRE(v);
    double worst = 0.0;
    for (std::size_t i = 0; i < t1.size(); ++i) worst = std::max(worst, std::abs((*d)[i] - (-2.0 + 0.5 * (*v)[i])));
    CHECK(worst < 1e-12);
    bool moves = false;  // the effect is not silently left out
    for (std::size_t i = 0; i < t1.size(); ++i) moves = moves || std::abs((*d)[i] + 2.0) > 1e-6;
    CHECK(moves);
  }
}
