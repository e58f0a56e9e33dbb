// The Prometheus exposition rendered from a status (no daemon): it parses by the format's
// grammar, names and types follow Prometheus' conventions, label values are escaped, and the
// values are the status' own.
#include <catch2/catch.hpp>

#include "exposition.hpp"
#include "fogbench/daemon/config.hpp"
#include "fogbench/daemon/metrics.hpp"

using namespace fogbench;
using nlohmann::json;

namespace {
json status_with_run() {
  return json::parse(R"({"version":"0.1.0","simulated":true,"time_scale":20.0,"clock_s":660.0,"setpoint_c":21.0,
    "chamber":{"chamber_c":20.98,"setpoint_c":20.97,"alarm":false,"link":"up"},
    "units":[{"serial":"FOG-0001","gyro_dph":-8.11,"frames":100,"t1_c":20.03,"t2_c":null},
             {"serial":"FOG \"2\"\\b\nc","gyro_dph":null,"frames":0,"t1_c":19.5,"t2_c":19.75}],
    "run":{"id":7,"state":"running","profile":"short","purpose":"fit","units":["FOG-0001"],"elapsed_s":660.0,
           "remaining_s":1140.0,"phase":"heating","step":2,
           "quality":[{"unit":0,"serial":"FOG-0001","frames_lost":3,"frames_corrupt":1,"samples_flagged":2}]}})");
}
}  // namespace

TEST_CASE("metrics: the exposition parses, with Prometheus names, escaped labels and the status' values") {
  daemon::MetricsInput in;
  in.status = status_with_run();
  in.store_bytes = 123456;
  in.socket_clients = 2;
  in.web_clients = 1;
  in.ticks = 660;
  in.ticks_skipped = 4;
  in.tick_lateness_s = 0.0125;
  in.tick_lateness_max_s = 0.5;
  const std::string text = daemon::render_metrics(in);
  INFO(text);
  const auto e = web_test::parse_exposition(text);
  for (const auto& err : e.errors) FAIL_CHECK(err);
  CHECK(e.errors.empty());
  // Every family: the prefix, a HELP, a TYPE; counters end in _total, gauges do not.
  for (const auto& [name, type] : e.type) {
    INFO(name);
    CHECK(name.starts_with("fogbench_"));
    CHECK(e.help.contains(name));
    CHECK(!e.help.at(name).empty());
    CHECK((type == "counter") == name.ends_with("_total"));
  }
  auto one = [&](const std::string& name, std::map<std::string, std::string> labels = {}) {
    auto v = e.find(name, labels);
    INFO(name);
    REQUIRE(v.size() == 1u);
    return v[0].value;
  };
  CHECK(one("fogbench_run_active") == 1.0);
  CHECK(one("fogbench_run_state", {{"state", "running"}}) == 1.0);
  CHECK(one("fogbench_run_state", {{"state", "settling"}}) == 0.0);
  CHECK(one("fogbench_run_id") == 7.0);
  CHECK(one("fogbench_run_elapsed_seconds") == 660.0);
  CHECK(one("fogbench_run_remaining_seconds") == 1140.0);
  CHECK(one("fogbench_chamber_air_celsius") == 20.98);  // shortest round-trip text: exact
  CHECK(one("fogbench_chamber_link_up") == 1.0);
  CHECK(one("fogbench_unit_rate_degrees_per_hour", {{"serial", "FOG-0001"}}) == -8.11);
  CHECK(one("fogbench_unit_temperature_celsius", {{"serial", "FOG-0001"}, {"sensor", "t1"}}) == 20.03);
  // Not read (null): no sample, rather than a made-up value.
  CHECK(e.find("fogbench_unit_temperature_celsius", {{"serial", "FOG-0001"}, {"sensor", "t2"}}).empty());
  // The serial with a quote, a backslash and a newline comes back whole through the escaping.
  const std::string odd = "FOG \"2\"\\b\nc";
  CHECK(one("fogbench_unit_temperature_celsius", {{"serial", odd}, {"sensor", "t2"}}) == 19.75);
  CHECK(e.find("fogbench_unit_rate_degrees_per_hour", {{"serial", odd}}).empty());
  CHECK(one("fogbench_unit_frames_lost_total", {{"serial", "FOG-0001"}}) == 3.0);
  CHECK(one("fogbench_unit_frames_corrupt_total", {{"serial", "FOG-0001"}}) == 1.0);
  CHECK(one("fogbench_unit_samples_flagged_total", {{"serial", "FOG-0001"}}) == 2.0);
  CHECK(one("fogbench_store_size_bytes") == 123456.0);
  CHECK(one("fogbench_clients", {{"transport", "socket"}}) == 2.0);
  CHECK(one("fogbench_clients", {{"transport", "web"}}) == 1.0);
  CHECK(one("fogbench_ticks_skipped_total") == 4.0);
  CHECK(one("fogbench_tick_lateness_seconds") == 0.0125);
  CHECK(one("fogbench_tick_lateness_max_seconds") == 0.5);
  CHECK(one("fogbench_build_info", {{"version", "0.1.0"}}) == 1.0);
}

TEST_CASE("metrics: idle, no run: the run's families say so and the per-run counters have no samples") {
  daemon::MetricsInput in;
  in.status = status_with_run();
  in.status["run"] = nullptr;
  in.status["chamber"]["link"] = "unknown";
  const auto e = web_test::parse_exposition(daemon::render_metrics(in));
  CHECK(e.errors.empty());
  REQUIRE(e.find("fogbench_run_active").size() == 1u);
  CHECK(e.find("fogbench_run_active")[0].value == 0.0);
  for (const auto& s : e.find("fogbench_run_state")) CHECK(s.value == 0.0);
  CHECK(e.find("fogbench_run_elapsed_seconds").empty());
  CHECK(e.find("fogbench_unit_frames_lost_total").empty());
  CHECK(e.find("fogbench_chamber_link_up").empty());  // unknown before the first poll
  CHECK(e.find("fogbench_store_size_bytes").empty());  // an in-memory store has no files
}

TEST_CASE("metrics: the test's parser refuses what the format does not allow") {
  // The parser is what checks the exposition: it must catch the mistakes it is there for.
  CHECK(!web_test::parse_exposition("fogbench_x 1\n").errors.empty());                                      // no TYPE/HELP
  CHECK(!web_test::parse_exposition("# HELP a_total h\n# TYPE a_total counter\na_total{s=\"x\\q\"} 1\n").errors.empty());  // bad escape
  CHECK(!web_test::parse_exposition("# HELP a h\n# TYPE a counter\na 1\n").errors.empty());               // counter without _total
  CHECK(!web_test::parse_exposition("# HELP a h\n# TYPE a gauge\na{s=\"x} 1\n").errors.empty());           // unclosed
  CHECK(!web_test::parse_exposition("# HELP a h\n# TYPE a gauge\na 1\na 2\n").errors.empty());             // a series twice
  CHECK(!web_test::parse_exposition("# HELP a h\n# TYPE a gauge\na one\n").errors.empty());                // not a number
  CHECK(web_test::parse_exposition("# HELP a h\n# TYPE a gauge\na{s=\"q\\\"\\\\\\n\"} -1.5e3\n").errors.empty());
}

TEST_CASE("config: listen parsed, loopback by default, other addresses only with allow_remote") {
  auto ok = daemon::parse_web_config(json{{"listen", "127.0.0.1:8080"}});
  REQUIRE(ok.has_value());
  CHECK(ok->address == "127.0.0.1");
  CHECK(ok->port == 8080);
  auto v6 = daemon::parse_web_config(json{{"listen", "[::1]:0"}});
  REQUIRE(v6.has_value());
  CHECK(v6->address == "::1");
  CHECK(v6->port == 0);
  auto remote = daemon::parse_web_config(json{{"listen", "0.0.0.0:8080"}});
  REQUIRE(!remote.has_value());
  CHECK(remote.error().find("web.listen: 0.0.0.0 is not a loopback address") == 0);
  CHECK(remote.error().find("allow_remote") != std::string::npos);
  CHECK(daemon::parse_web_config(json{{"listen", "0.0.0.0:8080"}, {"allow_remote", true}}).has_value());
  CHECK(daemon::parse_web_config(json{{"listen", "localhost:8080"}}).error() == "web.listen: not an IP address: \"localhost\"");
  CHECK(daemon::parse_web_config(json{{"listen", "127.0.0.1:99999"}}).error().find("web.listen: expected a port") == 0);
  CHECK(daemon::parse_web_config(json{{"listen", "127.0.0.1"}}).error().find("web.listen: expected \"address:port\"") == 0);
  CHECK(daemon::parse_web_config(json{{"port", 80}}).error() ==
        "web.port: unknown field (known: listen, allow_remote, enabled, token_file, hosts)");
  CHECK(daemon::parse_web_config(json::object()).error().find("web.listen: missing") == 0);
}
