// Certificates of the daemon's shape (signing/certificate.hpp) for fogctl cert's tests
// (cert_test.cpp, cert_print_test.cpp), signed by one station key per test executable.
#pragma once

#include <catch2/catch.hpp>

#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/signing/certificate.hpp"
#include "fogbench/signing/signing.hpp"

namespace fogbench::cli::test {

using nlohmann::json;

inline const signing::SigningKey& station_key() {
  static const signing::SigningKey k = *signing::SigningKey::generate();
  return k;
}

// A certificate of per-verification verdicts (page 2), before its signature.
inline json unsigned_cert() {
  return {{"format", "fogbench.certificate"}, {"format_version", 1}, {"serial", "FOG-1"}, {"station_id", "line </script> 2"},
          {"issued_at", "2026-11-25T09:00:00Z"}, {"verdict", "pass"},
          {"model", {{"id", 1}, {"version", 1}, {"method", "paper"}, {"terms", "d(T1)@40 + grad@40"}, {"sigma_a_dph", 0.05},
                     {"coefficients", {{{"term", "mu0"}, {"value", -8.0123}, {"sigma", 0.01}, {"unit", "deg/h"}, {"lag_s", 0}}}}}},
          {"verdicts", json::array()}, {"runs", json::array()}, {"allan", json::array()},
          {"software", {{"version", "0.1.0"}, {"git_hash", "abc"}}}};
}

// A one-verdict certificate of `rows` verifications, signed by the station's key.
inline json one_verdict_cert(const std::string& serial, const std::string& verdict, int rows) {
  json c = unsigned_cert();
  c.erase("verdicts");
  c["serial"] = serial;
  c["verdict"] = verdict;
  c["verifications"] = json::array();
  for (int i = 0; i < rows; ++i)
    c["verifications"].push_back({{"run_id", 10 + i}, {"verification_id", 1 + i},
                                  {"checks", {{{"check", "compensated std / raw std"}, {"value", 0.12}, {"limit", 0.2},
                                               {"rule", "value < limit"}, {"met", true}}}}});
  c["qualification"] = {{"verdict_id", 4}, {"serial", serial}, {"verdict", verdict}, {"rule", "analysis"},
                        {"run_id", 10}, {"unit", 0}, {"model_id", 1}, {"decided_at", "2026-11-27 10:00:00"},
                        {"limits", json::array()}, {"reasons", json::array()}};
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  return c;
}

// A three-axis unit's certificate as the daemon issues it (certificate.cpp): y failed, x and z
// passed, each axis' model and the decision's evidence per axis (`axes`, and the qualification's
// `axes`); a run whose identity carries a 16-digit git hash; signed by the station's key.
inline json three_axis_cert(const std::string& serial) {
  json c = one_verdict_cert(serial, "fail", 1);
  c.erase("sha256");
  c.erase("signature");
  c.erase("signed_by");
  json evidence = json::array(), axes = json::array();
  for (const auto& [axis, id, ratio] : std::vector<std::tuple<std::string, int, double>>{{"x", 1, 0.126}, {"y", 2, 0.821}, {"z", 3, 0.127}}) {
    const bool y = axis == "y";
    const json reasons = y ? json::array({"step 2 (exp2, run 11): comp_raw = 0.821, limit comp_raw < 0.2 (line 4)"}) : json::array();
    evidence.push_back({{"axis", axis}, {"verdict", y ? "fail" : "pass"}, {"model_id", id},
                        {"limits", {{{"measurement", "comp_raw"}, {"limit", "comp_raw < 0.2"}, {"line", 4}, {"value", ratio},
                                     {"met", !y}, {"on_fail", "stop"}, {"run_id", 11}, {"axis", axis}}}},
                        {"reasons", reasons}});
    axes.push_back({{"axis", axis}, {"verdict", y ? "fail" : "pass"}, {"decided_on_model", id},
                    {"model", {{"id", id}, {"version", id}, {"method", "paper"}, {"terms", y ? "d(T1)@600 + grad@600" : "d(T1)@38 + grad@38"},
                               {"fitted_on_run", 10}}},
                    {"reasons", reasons}});
  }
  c["qualification"]["axes"] = evidence;
  c["qualification"]["limits"] = json::array();
  for (const auto& e : evidence) c["qualification"]["limits"].push_back(e["limits"][0]);
  c["qualification"]["reasons"] = json::array({"step 2 (exp2, run 11): axis y: comp_raw = 0.821, limit comp_raw < 0.2 (line 4)"});
  c["qualification"]["rule"] = "plan";
  c["qualification"]["plan"] = {{"id", 1}, {"name", "axes"}, {"sha256", std::string(64, 'b')}};
  c["axes"] = axes;
  c["runs"] = json::array({{{"id", 10}, {"role", "fit"}, {"profile", "exp1"}, {"ended_at", "2026-11-30T00:10:00.000Z"},
                            {"identity", {{"station_id", "line 2"}, {"operator", "Ada"}, {"software_version", "0.1.0"},
                                          {"git_hash", "62756e985c7e4dfb"}}}}});
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  return c;
}

}  // namespace fogbench::cli::test
