// The certificate per serial (issue 13, point 2) from a real store after a fit and a verify run
// of the synthetic bench: issued automatically when the verify run completes, handed out again
// by cert.get while nothing changes, its SHA-256 that of its canonical JSON, one altered digit
// detected, the store knowing the hash; a serial without a model is not_found naming it.
#include "fixture.hpp"

#include "fogbench/daemon/certificate.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/model/sha256.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/storage/models.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {
struct Rig {
  storage::Store store = memory_store();
  Station station{golden_config({{"station", {{"id", "bench-7"}}}}), store};
  Handler handler{station};
  SessionState session;
  json send(const json& req) { return handler.handle(req, session); }
};
}  // namespace

TEST_CASE("certificate: issued when a verify run completes, the same from cert.get, its hash over the canonical JSON") {
  Rig r;
  SyntheticBench bench(1);
  double clock_s = 0.0;
  REQUIRE(r.send({{"id", 1}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}, {"operator", "Ada"}}).contains("result"));
  run_to_end(r.station, bench, clock_s);
  REQUIRE(r.store.current_model("FOG-0001")->has_value());
  // A fit alone certifies a model with no verdict yet, and stores nothing until asked.
  CHECK(r.store.list_certificates("FOG-0001")->empty());
  REQUIRE(r.send({{"id", 2}, {"cmd", "run.start"}, {"profile", "short"}, {"units", {"FOG-0001"}}, {"purpose", "verify"}})
              .contains("result"));
  run_to_end(r.station, bench, clock_s);

  // Issued automatically at the verify run's end; its note says which.
  auto stored = r.store.list_certificates("FOG-0001");
  REQUIRE(stored->size() == 1);
  auto run2 = r.store.get_run(2);
  std::string noted;
  for (const auto& e : run2->events)
    if (e.kind == storage::EventKind::note) {
      json d = json::parse(e.detail_json);
      if (d.contains("certificate_sha256")) noted = d["certificate_sha256"];
    }
  CHECK(noted == stored->front().sha256);

  json reply = r.send({{"id", 3}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}});
  REQUIRE(reply.contains("result"));
  CHECK(reply["result"]["issued_now"] == false);  // nothing changed: the stored one
  const json cert = reply["result"]["certificate"];
  CHECK(cert["sha256"] == stored->front().sha256);
  CHECK(r.store.list_certificates("FOG-0001")->size() == 1);

  // The hash is SHA-256 of the canonical JSON (sorted keys, no whitespace) without the field
  // and the signature.
  json body = cert;
  body.erase("sha256");
  body.erase("signature");
  CHECK(cert["sha256"] == model::sha256_hex(body.dump()));
  CHECK(certificate::hash_of(cert) == cert["sha256"]);
  CHECK(stored->front().json == cert.dump());

  // Content: coefficients with 1 sigma, each verdict with value and limit, runs with identity,
  // software, Allan figures of the compensated output.
  CHECK(cert["serial"] == "FOG-0001");
  CHECK(cert["station_id"] == "bench-7");
  // No run with rate steps: no scale-factor entry, the certificate is what it was before them.
  CHECK_FALSE(cert.contains("scale_factor"));
  const json& coefs = cert["model"]["coefficients"];
  REQUIRE(coefs.size() == 3);  // mu0, d(T1), grad
  CHECK(coefs[0]["term"] == "mu0");
  for (const auto& c : coefs) {
    CHECK(c["value"].is_number());
    CHECK(c["sigma"].get<double>() > 0.0);
  }
  // The synthetic bench's d(T1) coefficient is -2.7 deg/h per degC/min: within 5 sigma.
  CHECK(std::abs(coefs[1]["value"].get<double>() + 2.7) < 5.0 * coefs[1]["sigma"].get<double>() + 0.05);
  REQUIRE(cert["verifications"].size() == 1);
  const json& v = cert["verifications"][0];
  CHECK(v["run_id"] == 2);
  CHECK_FALSE(v.contains("verdict"));  // evidence only: the verdict is the serial's one
  REQUIRE(v["checks"].size() == 3);
  CHECK(v["checks"][0]["limit"] == 0.2);
  CHECK(v["checks"][0]["value"].get<double>() < 0.2);
  CHECK(v["checks"][1]["limit"] == 1.25);  // the one noise limit (model::NoiseRule), the daemon's default
  CHECK(v["checks"][2]["limit"] == 60.0);
  // The one verdict: decided by the bare verify run under the analysis settings, stored once,
  // and the certificate shows that row.
  auto decided = r.store.latest_verdict("FOG-0001");
  REQUIRE(decided->has_value());
  CHECK((*decided)->rule == "analysis");
  CHECK((*decided)->run_id == 2);
  CHECK(cert["verdict"] == (*decided)->verdict);
  CHECK(cert["qualification"]["verdict_id"] == (*decided)->id);
  CHECK(cert["qualification"]["rule"] == "analysis");
  CHECK(cert["qualification"]["plan"].is_null());
  CHECK(cert["qualification"]["limits"].size() == 3);
  REQUIRE(cert["runs"].size() == 2);
  CHECK(cert["runs"][0]["role"] == "fit");
  CHECK(cert["runs"][0]["identity"]["operator"] == "Ada");
  CHECK(cert["runs"][1]["role"] == "verify");
  CHECK(cert["software"]["git_hash"].is_string());
  REQUIRE(cert["allan"].size() == 1);
  CHECK(cert["allan"][0]["samples"].get<int>() > 100);
  CHECK(cert["allan"][0].contains("arw_deg_per_sqrt_h"));
  // Each figure read carries its interval's evidence: the EDF at its tau and its share there.
  for (const char* figure : {"arw_deg_per_sqrt_h", "bias_instability_dph", "rrw_dph_per_sqrt_h"}) {
    const json& e = cert["allan"][0][figure];
    INFO(figure << ": " << e.dump());
    if (e["value"].is_null()) continue;
    CHECK(e["edf"].get<double>() >= 1.0);
    CHECK(e["share"].get<double>() >= 0.0);
    // ARW and RRW are read only where their term is at least half of sigma^2 (a bias
    // instability given as an upper bound is read at the curve's minimum, whatever its share).
    if (std::string(figure) != "bias_instability_dph") CHECK(e["share"].get<double>() >= 0.5);
    CHECK(e["share"].get<double>() <= 1.0);
    CHECK(e["ci_low"].get<double>() <= e["value"].get<double>());
  }
  CHECK(!cert["allan"][0]["arw_deg_per_sqrt_h"]["value"].is_null());  // the white noise of the simulated gyro shows

  // One digit altered: the hash no longer matches; the store knows the true hash, not the other.
  json altered = cert;
  altered["model"]["coefficients"][1]["value"] = coefs[1]["value"].get<double>() + 0.1;
  CHECK(certificate::hash_of(altered) != cert["sha256"]);
  json known = r.send({{"id", 4}, {"cmd", "cert.check"}, {"sha256", cert["sha256"]}});
  CHECK(known["result"]["known"] == true);
  CHECK(known["result"]["certificates"][0]["serial"] == "FOG-0001");
  json unknown = r.send({{"id", 5}, {"cmd", "cert.check"}, {"sha256", certificate::hash_of(altered)}});
  CHECK(unknown["result"]["known"] == false);

  // Signed by the station's key for its station: valid with that key; the altered one is not,
  // even with its SHA-256 recomputed (a hash is not a signature).
  CHECK(cert["format_version"] == 3);
  CHECK(cert["signed_by"]["algorithm"] == "ed25519");
  CHECK(cert["signed_by"]["key_id"] == r.station.signing_key().key_id());
  CHECK(cert["signed_by"]["station_id"] == "bench-7");
  const std::vector<signing::PublicKey> keys{r.station.signing_key().public_key()};
  CHECK(signing::check_certificate(cert, keys).exit_code == 0);
  altered["sha256"] = certificate::hash_of(altered);
  const auto forged = signing::check_certificate(altered, keys);
  CHECK(forged.exit_code == 1);
  CHECK(forged.status == "bad signature");
  json pk = r.send({{"id", 8}, {"cmd", "cert.public_key"}});
  REQUIRE(pk.contains("result"));
  CHECK(pk["result"]["key_id"] == r.station.signing_key().key_id());
  CHECK(signing::PublicKey::from_pem(pk["result"]["public_key_pem"].get<std::string>())->key_id() == pk["result"]["key_id"]);
  CHECK(pk["result"]["key_path"].is_null());  // a station in a test: a key for the process only

  // A new model version: cert.get issues a new certificate.
  REQUIRE(r.send({{"id", 6}, {"cmd", "model.add_term"}, {"run_id", 1}, {"term", "T1"}}).contains("result"));
  json again = r.send({{"id", 7}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}});
  REQUIRE(again.contains("result"));
  CHECK(again["result"]["issued_now"] == true);
  CHECK(again["result"]["certificate"]["model"]["version"] == 2);
  CHECK(again["result"]["certificate"]["verifications"].empty());  // not verified yet
  CHECK(again["result"]["certificate"]["verdict"] == "not verified");  // the pass was version 1's
  CHECK(again["result"]["certificate"]["qualification"].is_null());
  CHECK(r.store.list_certificates("FOG-0001")->size() == 2);

  // A new station key (a rotation): the same facts are signed anew with it.
  auto rotated = signing::SigningKey::generate();
  REQUIRE(rotated.has_value());
  r.station.set_signing_key(*rotated, {});
  json resigned = r.send({{"id", 9}, {"cmd", "cert.get"}, {"serial", "FOG-0001"}});
  REQUIRE(resigned.contains("result"));
  CHECK(resigned["result"]["issued_now"] == true);
  CHECK(resigned["result"]["certificate"]["signed_by"]["key_id"] == rotated->key_id());
  CHECK(signing::check_certificate(resigned["result"]["certificate"], {rotated->public_key()}).exit_code == 0);
  // ... and checked with the old key alone: signed by a key it does not know (2, cannot tell).
  CHECK(signing::check_certificate(resigned["result"]["certificate"], keys).exit_code == 2);
}

TEST_CASE("certificate: a serial without a model is not_found naming it, nothing stored, a missing serial field is bad_request") {
  Rig r;
  json reply = r.send({{"id", 1}, {"cmd", "cert.get"}, {"serial", "FOG-0002"}});
  REQUIRE(reply.contains("error"));
  CHECK(reply["error"]["code"] == "not_found");
  CHECK(reply["error"]["message"].get<std::string>().find("FOG-0002") != std::string::npos);
  CHECK(r.send({{"id", 2}, {"cmd", "cert.get"}})["error"]["code"] == "bad_request");
  CHECK(r.send({{"id", 3}, {"cmd", "cert.check"}})["error"]["code"] == "bad_request");
  CHECK(r.store.list_certificates("FOG-0002")->empty());
}
