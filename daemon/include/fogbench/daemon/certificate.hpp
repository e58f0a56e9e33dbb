// A certificate per serial (issue 13, point 2): what a line ships with a qualified gyro, built
// from the store: the serial's current model with its coefficients and 1-sigma errors, every
// verification of that model with each verdict's value and limit, the runs (fit and verify)
// with their identity, the software, and the Allan figures of the compensated output of each
// verification run (model::allan). docs/daemon.md "Certificates".
//
// Canonical form: the JSON object as nlohmann::json dumps it (std::map: keys sorted bytewise,
// no whitespace, numbers in their shortest round-trip form, UTF-8 as is). `sha256` is the
// SHA-256 of the canonical JSON of the certificate without its `sha256` and `signature` fields;
// the store keeps it (table certificates). Since issue 24 every certificate is signed with the
// station's key (fogbench/signing/certificate.hpp: format_version 2, `signed_by`, `signature`),
// and `fogctl cert --check FILE --key station.pub` verifies it offline.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/api.hpp"
#include "fogbench/daemon/config.hpp"
#include "fogbench/signing/signing.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::daemon::certificate {

// The certificate's content for the serial's current model, without `issued_at` and `sha256`
// (so two builds of the same facts are equal). A serial without a model is not_found naming it.
ApiResult<nlohmann::json> build(storage::Store& store, const AnalysisConfig& limits, const std::string& station_id,
                                const std::string& serial);

// SHA-256 (hex) of the canonical JSON of `cert` without its `sha256` and `signature` fields.
std::string hash_of(const nlohmann::json& cert);

// The certificate to hand out: the serial's latest stored one when its content equals `body`
// and `key` signed it (nothing changed since it was issued), else a new one (`issued_at` now,
// signed with `key` for the body's station_id) stored. Returns {certificate, stored_new}.
ApiResult<std::pair<nlohmann::json, bool>> issue(storage::Store& writer, const nlohmann::json& body,
                                                 const std::string& issued_at, const signing::SigningKey& key);

}  // namespace fogbench::daemon::certificate
