// Certificates of the daemon's shape (signing/certificate.hpp) for fogctl cert's tests
// (cert_test.cpp, cert_print_test.cpp), signed by one station key per test executable.
#pragma once

#include <catch2/catch.hpp>

#include <string>

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

}  // namespace fogbench::cli::test
