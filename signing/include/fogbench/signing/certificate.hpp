// A certificate's signature (issue 24, point 2): how the daemon signs a certificate and how
// fogctl verifies one, in one place. docs/daemon.md "The station key", docs/cli.md "fogctl cert".
//
// A signed certificate (format_version 2) carries
//   "signed_by": {"algorithm": "ed25519", "key_id": <SHA-256 of the public key>, "station_id": ...,
//                 "public_key_pem": <the signing key's public half>}
//   "signature": <base64 Ed25519 signature>
// The embedded public key is for the plant store's keyring (station_keys, filled as the
// certificates replicate) and for reading; a check never trusts it: the checker's keys decide.
// The signature covers the canonical JSON of the certificate without its `signature` field
// (nlohmann's dump(): keys sorted bytewise, no whitespace): every other field, `sha256` and
// `signed_by` included, so neither the key id nor the station can be changed without it.
#pragma once

#include <expected>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/signing/signing.hpp"

namespace fogbench::signing {

// 2: signed (issue 24 point 2); 3: the one verdict with the rule that decided it
// (`qualification`) and the verifications as evidence (`verifications`, no verdict of their own).
inline constexpr int kCertificateFormatVersion = 3;

// The bytes the signature covers: the canonical JSON without `signature`.
std::string signed_text(const nlohmann::json& cert);
// SHA-256 (hex) of the canonical JSON without `sha256` and `signature`.
std::string content_sha256(const nlohmann::json& cert);

// Sets format_version, signed_by (this key, `station_id`), sha256 and signature on `cert`.
std::expected<void, std::string> sign_certificate(nlohmann::json& cert, const SigningKey& key,
                                                  const std::string& station_id);

// What a check of a certificate's signature concludes. exit_code: 0 valid, 1 altered or a bad
// signature (or a key revoked before the certificate's date), 2 cannot tell (unsigned, an
// unknown key id, no key at all, an unknown algorithm).
struct SignatureCheck {
  int exit_code = 2;
  std::string status;   // "valid", "altered", "bad signature", "revoked", "unsigned", "unknown key", "no key"
  std::string message;  // one sentence for a person
  std::string key_id;   // the key id the certificate names ("" when none)
};
SignatureCheck check_certificate(const nlohmann::json& cert, const std::vector<PublicKey>& keys,
                                 const std::vector<Revocation>& revoked = {});

}  // namespace fogbench::signing
