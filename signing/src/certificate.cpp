// Signing and checking certificates (certificate.hpp).
#include "fogbench/signing/certificate.hpp"

#include <openssl/evp.h>

namespace fogbench::signing {

using nlohmann::json;

namespace {

std::string sha256_hex(const std::string& s) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  if (EVP_Digest(s.data(), s.size(), md, &n, EVP_sha256(), nullptr) != 1) return {};
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < n; ++i) {
    out += kDigits[md[i] >> 4];
    out += kDigits[md[i] & 0xf];
  }
  return out;
}

std::string short_id(const std::string& id) { return id.substr(0, 16); }

}  // namespace

std::string signed_text(const json& cert) {
  json body = cert;
  if (body.is_object()) body.erase("signature");
  return body.dump();
}

std::string content_sha256(const json& cert) {
  json body = cert;
  if (body.is_object()) {
    body.erase("sha256");
    body.erase("signature");
  }
  return sha256_hex(body.dump());
}

std::expected<void, std::string> sign_certificate(json& cert, const SigningKey& key, const std::string& station_id) {
  if (!cert.is_object()) return std::unexpected("a certificate is a JSON object");
  cert.erase("signature");
  cert["format_version"] = kCertificateFormatVersion;
  cert["signed_by"] = {{"algorithm", std::string(kAlgorithm)}, {"key_id", key.key_id()}, {"station_id", station_id},
                       {"public_key_pem", key.public_key().pem()}};
  cert["sha256"] = content_sha256(cert);
  auto sig = key.sign(signed_text(cert));
  if (!sig) return std::unexpected(sig.error());
  cert["signature"] = *sig;
  return {};
}

SignatureCheck check_certificate(const json& cert, const std::vector<PublicKey>& keys, const std::vector<Revocation>& revoked) {
  SignatureCheck r;
  if (!cert.is_object() || !cert.contains("signature")) {
    r.status = "unsigned";
    r.message = "an unsigned certificate (issued before fogbench signed them): nothing proves who issued it; ask the station to issue it again";
    return r;
  }
  const json sb = cert.value("signed_by", json(nullptr));
  if (!sb.is_object() || !sb.contains("key_id") || !sb["key_id"].is_string() || !cert["signature"].is_string()) {
    r.exit_code = 1;
    r.status = "altered";
    r.message = "its signature or signed_by field is malformed";
    return r;
  }
  r.key_id = sb["key_id"].get<std::string>();
  if (sb.value("algorithm", "") != kAlgorithm) {
    r.status = "unknown key";
    r.message = "signed with algorithm '" + sb.value("algorithm", std::string("?")) + "', which this fogctl does not know";
    return r;
  }
  if (cert.contains("sha256") && cert["sha256"] != content_sha256(cert)) {
    r.exit_code = 1;
    r.status = "altered";
    r.message = "ALTERED: its content no longer matches its SHA-256 (" + cert["sha256"].dump() + ", the content hashes to " +
                content_sha256(cert) + ")";
    return r;
  }
  if (keys.empty()) {
    r.status = "no key";
    r.message = "no public key to check it with (give the station's --key station.pub)";
    return r;
  }
  const PublicKey* key = nullptr;
  for (const auto& k : keys)
    if (k.key_id() == r.key_id) key = &k;
  if (!key) {
    std::string ids;
    for (const auto& k : keys) ids += (ids.empty() ? "" : ", ") + short_id(k.key_id());
    r.status = "unknown key";
    r.message = "signed by key " + r.key_id + ", which is none of the keys given (" + ids + ")";
    return r;
  }
  if (!key->verify(signed_text(cert), cert["signature"].get<std::string>())) {
    r.exit_code = 1;
    r.status = "bad signature";
    r.message = "BAD SIGNATURE: key " + short_id(r.key_id) + " did not sign this content (the certificate or its signature was changed)";
    return r;
  }
  const std::string station = sb.value("station_id", "");
  if (cert.value("station_id", "") != station) {
    r.exit_code = 1;
    r.status = "altered";
    r.message = "signed for station '" + station + "' but names station '" + cert.value("station_id", "") + "'";
    return r;
  }
  const std::string issued = cert.value("issued_at", "");
  for (const auto& rv : revoked) {
    if (rv.key_id != r.key_id) continue;
    // ISO 8601 texts compare as dates: the certificate's time cut to the revocation's precision.
    if (issued.empty() || issued.substr(0, rv.revoked_at.size()) >= rv.revoked_at) {
      r.exit_code = 1;
      r.status = "revoked";
      r.message = "signed by key " + short_id(r.key_id) + ", revoked on " + rv.revoked_at + (rv.reason.empty() ? "" : " (" + rv.reason + ")") +
                  ", at " + (issued.empty() ? "an unknown time" : issued) + ": not to be trusted";
      return r;
    }
  }
  r.exit_code = 0;
  r.status = "valid";
  r.message = "valid: signed by station '" + station + "' with key " + short_id(r.key_id);
  for (const auto& rv : revoked)
    if (rv.key_id == r.key_id) r.message += " (revoked on " + rv.revoked_at + ", after this certificate was issued)";
  return r;
}

}  // namespace fogbench::signing
