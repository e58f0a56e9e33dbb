// A configuration reload while a run is active (Station::reload_config): the run keeps the
// analysis settings and slot names it started with, so its automatic fit (and a verification's
// verdict) follows the rule of its start; idle slots show their new default serials at once and
// the next run takes the new settings.
#include "fixture.hpp"

#include "fogbench/model/json.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
int lag_of_first_term(storage::Store& store, const std::string& serial) {
  auto m = store.current_model(serial);
  REQUIRE(m.has_value());
  REQUIRE(m->has_value());
  auto model = model::model_from_text((*m)->model_json);
  REQUIRE(model.has_value());
  REQUIRE(!model->terms.empty());
  return static_cast<int>(model->terms[0].term.lag.seconds);
}
}  // namespace

TEST_CASE("station reload: the active run keeps its analysis settings and slots, the next run takes the new ones") {
  auto store = memory_store();
  Station st(golden_config({{"analysis", {{"causal_lags", true}}}}), store, 1.0,
             [] { return std::string("2026-01-01T00:00:00Z"); });
  SyntheticBench bench(1);
  double clock_s = 0.0;
  REQUIRE(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}}).has_value());

  // Reloaded while the run is active: held lags off, slot A renamed, slot B a new default serial.
  json next = golden_config_json();
  next["drivers"]["units"][0]["slot"] = "LEFT";
  next["drivers"]["units"][1]["serial"] = "FOG-0777";
  auto reloaded = parse_daemon_config(next, golden_dir());
  REQUIRE(reloaded.has_value());
  st.reload_config(*reloaded);
  const json s = st.status();
  CHECK(s["run"]["slots"] == json{"A"});        // as the run started
  CHECK(s["units"][0]["slot"] == "A");          // in use: the run's name for it
  CHECK(s["units"][0]["next_slot"] == "LEFT");  // the configuration's name now, for the next run
  CHECK_FALSE(s["units"][1].contains("next_slot"));
  CHECK(s["units"][0]["serial"] == "FOG-0001");  // the run's unit
  CHECK(s["units"][1]["serial"] == "FOG-0777");  // idle: the new default

  run_to_end(st, bench, clock_s);
  // Fitted with the settings of its start: the rate term held at a lag the firmware meets (the
  // synthetic drift's own lag is 0).
  CHECK(lag_of_first_term(store, "FOG-0001") >= 30);
  auto runs = store.get_run(1);
  REQUIRE(runs.has_value());
  REQUIRE(runs->run.units.size() == 1);
  REQUIRE(runs->run.units[0].slot.has_value());
  CHECK(*runs->run.units[0].slot == "A");  // stored as it started, never rewritten

  // The next run: the new settings (lags unconstrained) and the new names.
  REQUIRE(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}}).has_value());
  CHECK(st.status()["run"]["slots"] == json{"LEFT"});
  CHECK(st.status()["units"][0]["slot"] == "LEFT");
  CHECK_FALSE(st.status()["units"][0].contains("next_slot"));
  run_to_end(st, bench, clock_s);
  CHECK(lag_of_first_term(store, "FOG-0001") < 30);
}
