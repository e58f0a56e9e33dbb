// The end-of-run analysis as configured (analysis in the daemon config): a joint fit that did not
// converge is stored with a warning, and the verdict's second test uses the configured limits.
#include "fixture.hpp"

#include "fogbench/daemon/handler.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
// The `note` events of a run's automatic analysis, as stored.
std::vector<json> analysis_notes(storage::Store& store, std::int64_t run_id) {
  std::vector<json> notes;
  auto d = store.get_run(run_id);
  REQUIRE(d.has_value());
  for (const auto& e : d->events) {
    if (e.kind != storage::EventKind::note) continue;
    json j = json::parse(e.detail_json);
    if (j.contains("analysis")) notes.push_back(j);
  }
  return notes;
}
}  // namespace

TEST_CASE("analysis: a joint fit that did not converge is stored with a warning, in the note and the reply") {
  auto store = memory_store();
  // One Cochrane-Orcutt iteration cannot show the estimates settled: the fit ends unconverged.
  Station st(golden_config({{"analysis", {{"method", "joint"}, {"max_iterations", 1}}}}), store);
  SyntheticBench bench(1);
  double clock_s = 0.0;
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  run_to_end(st, bench, clock_s);
  const auto notes = analysis_notes(store, *id);
  REQUIRE(notes.size() == 1);
  CHECK(notes[0]["ok"] == true);  // stored: a model is better than none, but it is said
  REQUIRE(notes[0].contains("warning"));
  CHECK_THAT(notes[0]["warning"].get<std::string>(), Catch::Contains("did not converge") && Catch::Contains("1 iteration"));
  auto m = store.current_model("FOG-0001");
  REQUIRE(m->has_value());

  Handler h(st);
  SessionState s;
  const json r = h.handle_line(R"({"id":1,"cmd":"model.fit","run_id":1})", s);
  REQUIRE(r.contains("result"));
  CHECK_THAT(r["result"]["warning"].get<std::string>(), Catch::Contains("did not converge"));
}

TEST_CASE("analysis: a converged fit carries no warning") {
  auto store = memory_store();
  Station st(golden_config({{"analysis", {{"method", "joint"}}}}), store);
  SyntheticBench bench(1);
  double clock_s = 0.0;
  auto id = st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}});
  REQUIRE(id.has_value());
  run_to_end(st, bench, clock_s);
  const auto notes = analysis_notes(store, *id);
  REQUIRE(notes.size() == 1);
  CHECK(notes[0]["ok"] == true);
  CHECK_FALSE(notes[0].contains("warning"));
}

namespace {
// A fit run, then a verify run, of the same seeded bench under `analysis`: the verification.
json verify_run(const json& analysis) {
  auto store = memory_store();
  Station st(golden_config({{"analysis", analysis}}), store);
  SyntheticBench bench(1);
  double clock_s = 0.0;
  REQUIRE(st.start_run("short", {"FOG-0001"}, storage::Purpose::fit, {{"cmd", "run.start"}}).has_value());
  run_to_end(st, bench, clock_s);
  auto v = st.start_run("short", {"FOG-0001"}, storage::Purpose::verify, {{"cmd", "run.start"}});
  REQUIRE(v.has_value());
  run_to_end(st, bench, clock_s);
  auto vs = store.list_verifications(*v);
  REQUIRE(vs->size() == 1);
  return json::parse(vs->at(0).result_json);
}
}  // namespace

TEST_CASE("analysis: the marginal verdict's limits come from the configuration") {
  // The defaults pass the seeded bench's verify run; a limit set just under what that run
  // measured (its noise factor, else its longest failing interval) makes the same run marginal.
  const json pass = verify_run(json::object());
  REQUIRE(pass["verdict"] == "pass");
  const double factor = pass["noise_factor"].get<double>();
  const double fail_s = pass["longest_fail_s"].get<double>();
  json tight;
  if (factor > 1.0) tight = {{"verify_max_noise_factor", std::max(1.0, factor * 0.99)}};
  else if (fail_s >= 1.0) tight = {{"verify_max_fail_s", fail_s}};
  else FAIL("the bench's verify run has no margin to test with: noise factor " << factor << ", longest failing interval " << fail_s << " s");
  INFO("tight limits " << tight.dump());
  const json marginal = verify_run(tight);
  CHECK(marginal["verdict"] == "marginal");
  CHECK(marginal["noise_factor"] == pass["noise_factor"]);  // the same run, judged by other limits
}

TEST_CASE("analysis: the daemon config refuses analysis limits out of range, naming the key") {
  for (const auto& [key, bad] : std::vector<std::pair<std::string, json>>{
           {"verify_max_noise_factor", 0.5}, {"verify_max_fail_s", 0}, {"max_iterations", 0}, {"verify_max_fail_s", "60"}}) {
    INFO(key);
    json j = golden_config_json();
    j["analysis"] = {{key, bad}};
    auto c = parse_daemon_config(j, golden_dir());
    REQUIRE_FALSE(c.has_value());
    CHECK_THAT(c.error(), Catch::Contains("analysis." + key));
  }
}
