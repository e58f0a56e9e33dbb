// A station's signing key (issue 24, point 2): Ed25519 through OpenSSL 3's libcrypto, the one
// place in fogbench that does cryptography. The daemon signs its certificates with its key;
// fogctl verifies them with the station's public key, offline. docs/daemon.md "The station key".
//
// Key id: the SHA-256 (lower-case hex) of the public key's DER SubjectPublicKeyInfo, the same as
//   openssl pkey -pubin -in station.pub -outform DER | sha256sum
// Signatures travel in base64 (RFC 4648, with padding): 64 bytes, 88 characters.
//
// No exceptions: every failure is a returned message that names the file or the field.
#pragma once

#include <expected>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::signing {

inline constexpr std::string_view kAlgorithm = "ed25519";

class PublicKey {
 public:
  // One PEM block ("-----BEGIN PUBLIC KEY-----"), an Ed25519 key.
  static std::expected<PublicKey, std::string> from_pem(std::string_view pem);
  std::string pem() const;
  const std::string& key_id() const { return key_id_; }
  // Whether `signature_b64` is this key's Ed25519 signature of `message`. A signature that is
  // not base64 or not 64 bytes is simply not valid.
  bool verify(std::string_view message, std::string_view signature_b64) const;

 private:
  std::shared_ptr<void> key_;  // EVP_PKEY, freed with EVP_PKEY_free
  std::string key_id_;
  friend class SigningKey;
};

class SigningKey {
 public:
  static std::expected<SigningKey, std::string> generate();
  // A PKCS#8 PEM block ("-----BEGIN PRIVATE KEY-----") of an Ed25519 key.
  static std::expected<SigningKey, std::string> from_pem(std::string_view pem);
  std::string private_pem() const;
  const PublicKey& public_key() const { return public_; }
  const std::string& key_id() const { return public_.key_id(); }
  // The base64 Ed25519 signature of `message`.
  std::expected<std::string, std::string> sign(std::string_view message) const;

 private:
  static std::expected<SigningKey, std::string> adopt(void* evp_pkey);  // takes ownership
  std::shared_ptr<void> key_;  // EVP_PKEY
  PublicKey public_;
};

// The public key's file beside a key file: station.key -> station.pub.
std::filesystem::path public_path_of(const std::filesystem::path& key_path);

struct LoadedKey {
  SigningKey key;
  bool created = false;  // made now (first start)
};
// The station's key: read from `key_path`, or created there when absent (mode 0600 from its
// creation, O_EXCL, its folder made 0700 if missing) with its public key written beside it
// (public_path_of, mode 0644; rewritten when missing). Refused, naming the path: a key file
// that group or others may read or write, one owned by another user, one not readable, not a
// regular file, or not an Ed25519 private key.
std::expected<LoadedKey, std::string> load_or_create(const std::filesystem::path& key_path);

// Public keys from a file (one or several PEM blocks: a keyring) or a directory (every
// *.pub and *.pem file in it, in name order). An empty result is an error naming the path.
std::expected<std::vector<PublicKey>, std::string> load_public_keys(const std::filesystem::path& path);

// Revoked keys: a text file of lines "KEY_ID DATE [reason...]" (DATE as ISO 8601, e.g.
// 2026-11-27 or 2026-11-27T10:00:00Z), '#' starts a comment. Errors name the file and line.
struct Revocation {
  std::string key_id;
  std::string revoked_at;
  std::string reason;
};
std::expected<std::vector<Revocation>, std::string> load_revocations(const std::filesystem::path& path);

}  // namespace fogbench::signing
