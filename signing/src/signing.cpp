// Ed25519 keys, signatures and key files through OpenSSL 3's libcrypto (signing.hpp).
#include "fogbench/signing/signing.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

namespace fogbench::signing {

namespace {

using Bytes = std::string;

std::string openssl_error() {
  const unsigned long e = ERR_get_error();
  ERR_clear_error();
  if (e == 0) return "OpenSSL gave no reason";
  char buf[256];
  ERR_error_string_n(e, buf, sizeof buf);
  return buf;
}

std::shared_ptr<void> own(EVP_PKEY* k) {
  return std::shared_ptr<void>(k, [](void* p) { EVP_PKEY_free(static_cast<EVP_PKEY*>(p)); });
}
EVP_PKEY* raw(const std::shared_ptr<void>& p) { return static_cast<EVP_PKEY*>(p.get()); }

std::string hex(const unsigned char* d, std::size_t n) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  s.reserve(2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    s += kDigits[d[i] >> 4];
    s += kDigits[d[i] & 0xf];
  }
  return s;
}

// SHA-256 of the DER SubjectPublicKeyInfo.
std::expected<std::string, std::string> key_id_of(EVP_PKEY* k) {
  unsigned char* der = nullptr;
  const int n = i2d_PUBKEY(k, &der);
  if (n <= 0) return std::unexpected("cannot encode the public key: " + openssl_error());
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int md_len = 0;
  const int ok = EVP_Digest(der, static_cast<std::size_t>(n), md, &md_len, EVP_sha256(), nullptr);
  OPENSSL_free(der);
  if (ok != 1) return std::unexpected("cannot hash the public key: " + openssl_error());
  return hex(md, md_len);
}

std::string bio_text(BIO* b) {
  char* data = nullptr;
  const long n = BIO_get_mem_data(b, &data);
  return n > 0 ? std::string(data, static_cast<std::size_t>(n)) : std::string();
}

std::string base64(const unsigned char* d, std::size_t n) {
  std::string out(4 * ((n + 2) / 3), '\0');
  const int len = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()), d, static_cast<int>(n));
  out.resize(static_cast<std::size_t>(std::max(len, 0)));
  return out;
}

constexpr std::size_t kSignatureBytes = 64;

// A signature's 64 bytes from its canonical base64 (88 characters ending "=="); anything else is none.
std::optional<Bytes> signature_bytes(std::string_view b64) {
  if (b64.size() != 88 || !b64.ends_with("==")) return std::nullopt;
  unsigned char out[66];
  if (EVP_DecodeBlock(out, reinterpret_cast<const unsigned char*>(b64.data()), static_cast<int>(b64.size())) != 66)
    return std::nullopt;
  // One encoding only: the re-encoding must give the same text (no unused bits set).
  if (base64(out, kSignatureBytes) != b64) return std::nullopt;
  return Bytes(reinterpret_cast<const char*>(out), kSignatureBytes);
}

std::expected<std::string, std::string> read_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) return std::unexpected(p.string() + ": cannot read: " + std::strerror(errno));
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::string mode_text(mode_t m) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04o", static_cast<unsigned>(m & 07777));
  return buf;
}

// Writes `text` to `path` through a temporary file and a rename, with `mode` from the start.
std::expected<void, std::string> write_file(const std::filesystem::path& path, const std::string& text, mode_t mode,
                                            bool exclusive) {
  const std::string target = path.string();
  const std::string tmp = exclusive ? target : target + ".tmp";
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | O_NOFOLLOW | (exclusive ? O_EXCL : O_TRUNC);
  const int fd = ::open(tmp.c_str(), flags, mode);
  if (fd < 0) return std::unexpected(tmp + ": cannot create: " + std::strerror(errno));
  bool ok = ::fchmod(fd, mode) == 0;  // the umask may have taken bits away; never added any
  std::size_t done = 0;
  while (ok && done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) ok = false;
    else done += static_cast<std::size_t>(n);
  }
  ok = ok && ::fsync(fd) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok) {
    ::unlink(tmp.c_str());
    return std::unexpected(tmp + ": cannot write: " + std::strerror(err));
  }
  if (!exclusive && ::rename(tmp.c_str(), target.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    return std::unexpected(target + ": cannot rename into place: " + std::strerror(e));
  }
  return {};
}

}  // namespace

std::expected<PublicKey, std::string> PublicKey::from_pem(std::string_view pem) {
  BIO* b = BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size()));
  if (!b) return std::unexpected("out of memory");
  EVP_PKEY* k = PEM_read_bio_PUBKEY(b, nullptr, nullptr, nullptr);
  BIO_free(b);
  if (!k) return std::unexpected("not a PEM public key: " + openssl_error());
  auto owned = own(k);
  if (EVP_PKEY_get_id(k) != EVP_PKEY_ED25519) return std::unexpected("not an Ed25519 public key");
  auto id = key_id_of(k);
  if (!id) return std::unexpected(id.error());
  PublicKey p;
  p.key_ = std::move(owned);
  p.key_id_ = std::move(*id);
  return p;
}

std::string PublicKey::pem() const {
  BIO* b = BIO_new(BIO_s_mem());
  if (!b) return {};
  std::string s;
  if (PEM_write_bio_PUBKEY(b, raw(key_)) == 1) s = bio_text(b);
  BIO_free(b);
  return s;
}

bool PublicKey::verify(std::string_view message, std::string_view signature_b64) const {
  if (!key_) return false;
  const auto sig = signature_bytes(signature_b64);
  if (!sig) return false;
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  if (!ctx) return false;
  const bool ok = EVP_DigestVerifyInit(ctx, nullptr, nullptr, nullptr, raw(key_)) == 1 &&
                  EVP_DigestVerify(ctx, reinterpret_cast<const unsigned char*>(sig->data()), sig->size(),
                                   reinterpret_cast<const unsigned char*>(message.data()), message.size()) == 1;
  EVP_MD_CTX_free(ctx);
  ERR_clear_error();
  return ok;
}

std::expected<SigningKey, std::string> SigningKey::generate() {
  EVP_PKEY* k = EVP_PKEY_Q_keygen(nullptr, nullptr, "ED25519");
  if (!k) return std::unexpected("cannot generate an Ed25519 key: " + openssl_error());
  return adopt(k);
}

std::expected<SigningKey, std::string> SigningKey::from_pem(std::string_view pem) {
  BIO* b = BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size()));
  if (!b) return std::unexpected("out of memory");
  EVP_PKEY* k = PEM_read_bio_PrivateKey(b, nullptr, nullptr, nullptr);
  BIO_free(b);
  if (!k) return std::unexpected("not a PEM private key: " + openssl_error());
  return adopt(k);
}

std::expected<SigningKey, std::string> SigningKey::adopt(void* evp_pkey) {
  auto* k = static_cast<EVP_PKEY*>(evp_pkey);
  auto owned = own(k);
  if (EVP_PKEY_get_id(k) != EVP_PKEY_ED25519) return std::unexpected("not an Ed25519 private key");
  auto id = key_id_of(k);
  if (!id) return std::unexpected(id.error());
  // The public half as its own key object: what a verifier loads from station.pub.
  unsigned char pub[32];
  std::size_t len = sizeof pub;
  if (EVP_PKEY_get_raw_public_key(k, pub, &len) != 1 || len != sizeof pub)
    return std::unexpected("cannot read the public half of the key: " + openssl_error());
  EVP_PKEY* p = EVP_PKEY_new_raw_public_key(EVP_PKEY_ED25519, nullptr, pub, len);
  if (!p) return std::unexpected("cannot make the public key: " + openssl_error());
  SigningKey s;
  s.key_ = std::move(owned);
  s.public_.key_ = own(p);
  s.public_.key_id_ = std::move(*id);
  return s;
}

std::string SigningKey::private_pem() const {
  BIO* b = BIO_new(BIO_s_mem());
  if (!b) return {};
  std::string s;
  if (PEM_write_bio_PrivateKey(b, raw(key_), nullptr, nullptr, 0, nullptr, nullptr) == 1) s = bio_text(b);
  BIO_free(b);
  return s;
}

std::expected<std::string, std::string> SigningKey::sign(std::string_view message) const {
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  if (!ctx) return std::unexpected("out of memory");
  unsigned char sig[kSignatureBytes];
  std::size_t len = sizeof sig;
  const bool ok = EVP_DigestSignInit(ctx, nullptr, nullptr, nullptr, raw(key_)) == 1 &&
                  EVP_DigestSign(ctx, sig, &len, reinterpret_cast<const unsigned char*>(message.data()), message.size()) == 1;
  EVP_MD_CTX_free(ctx);
  if (!ok || len != kSignatureBytes) return std::unexpected("cannot sign: " + openssl_error());
  return base64(sig, len);
}

std::filesystem::path public_path_of(const std::filesystem::path& key_path) {
  auto p = key_path;
  return p.replace_extension(".pub");
}

std::expected<LoadedKey, std::string> load_or_create(const std::filesystem::path& key_path) {
  const std::string path = key_path.string();
  const std::string me = "signing key " + path + ": ";
  if (key_path.empty()) return std::unexpected("signing key: no path");
  LoadedKey out{SigningKey{}, false};
  struct stat st{};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno != ENOENT) return std::unexpected(me + std::strerror(errno));
    // First start: a new key, readable by its owner only from the moment it exists.
    const auto dir = key_path.parent_path();
    if (!dir.empty() && !std::filesystem::exists(dir)) {
      std::error_code ec;
      std::filesystem::create_directories(dir, ec);
      if (ec) return std::unexpected(me + "cannot create its folder " + dir.string() + ": " + ec.message());
      std::filesystem::permissions(dir, std::filesystem::perms::owner_all, ec);
    }
    auto key = SigningKey::generate();
    if (!key) return std::unexpected(me + key.error());
    if (auto w = write_file(key_path, key->private_pem(), 0600, true); !w) return std::unexpected("signing key " + w.error());
    out.key = std::move(*key);
    out.created = true;
  } else {
    if (S_ISLNK(st.st_mode)) return std::unexpected(me + "a symbolic link; give the key file itself");
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0) return std::unexpected(me + "cannot read: " + std::strerror(errno));
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      return std::unexpected(me + "not a regular file");
    }
    if (st.st_uid != ::geteuid()) {
      ::close(fd);
      return std::unexpected(me + "owned by uid " + std::to_string(st.st_uid) + ", not by this daemon's user (uid " +
                             std::to_string(::geteuid()) + "): chown it");
    }
    if ((st.st_mode & 077) != 0) {
      ::close(fd);
      return std::unexpected(me + "mode " + mode_text(st.st_mode) +
                             " lets group or others at the station's private key; it must be 0600 (chmod 600 " + path +
                             "), and a key others could read should be replaced (docs/daemon.md \"The station key\")");
    }
    std::string text;
    char buf[4096];
    for (;;) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        const int e = errno;
        ::close(fd);
        return std::unexpected(me + "cannot read: " + std::strerror(e));
      }
      if (n == 0) break;
      text.append(buf, static_cast<std::size_t>(n));
      if (text.size() > 64 * 1024) {
        ::close(fd);
        return std::unexpected(me + "larger than 64 KiB: not a key");
      }
    }
    ::close(fd);
    auto key = SigningKey::from_pem(text);
    if (!key) return std::unexpected(me + key.error());
    out.key = std::move(*key);
  }
  // The public key beside it, for whoever checks certificates: rewritten when missing or stale.
  const auto pub_path = public_path_of(key_path);
  const std::string pem = out.key.public_key().pem();
  auto existing = read_file(pub_path);
  if (!existing || *existing != pem) {
    if (auto w = write_file(pub_path, pem, 0644, false); !w) return std::unexpected("public key " + w.error());
  }
  return out;
}

std::expected<std::vector<PublicKey>, std::string> load_public_keys(const std::filesystem::path& path) {
  std::error_code ec;
  std::vector<PublicKey> keys;
  if (std::filesystem::is_directory(path, ec)) {
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(path, ec))
      if (e.is_regular_file() && (e.path().extension() == ".pub" || e.path().extension() == ".pem")) files.push_back(e.path());
    if (ec) return std::unexpected(path.string() + ": cannot list: " + ec.message());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      auto some = load_public_keys(f);
      if (!some) return std::unexpected(some.error());
      keys.insert(keys.end(), some->begin(), some->end());
    }
    if (keys.empty()) return std::unexpected(path.string() + ": no *.pub or *.pem public key file in this folder");
    return keys;
  }
  auto text = read_file(path);
  if (!text) return std::unexpected(text.error());
  if (text->find("PRIVATE KEY-----") != std::string::npos)
    return std::unexpected(path.string() + ": a private key; give the station's public key (station.pub) instead");
  static constexpr std::string_view kBegin = "-----BEGIN PUBLIC KEY-----", kEnd = "-----END PUBLIC KEY-----";
  std::size_t at = 0;
  int n = 0;
  while ((at = text->find(kBegin, at)) != std::string::npos) {
    ++n;
    const auto end = text->find(kEnd, at);
    if (end == std::string::npos) return std::unexpected(path.string() + ": public key " + std::to_string(n) + " is not closed (" + std::string(kEnd) + ")");
    auto k = PublicKey::from_pem(std::string_view(*text).substr(at, end + kEnd.size() - at));
    if (!k) return std::unexpected(path.string() + ": public key " + std::to_string(n) + ": " + k.error());
    keys.push_back(std::move(*k));
    at = end + kEnd.size();
  }
  if (keys.empty()) return std::unexpected(path.string() + ": no PEM public key (-----BEGIN PUBLIC KEY-----) in it");
  return keys;
}

std::expected<std::vector<Revocation>, std::string> load_revocations(const std::filesystem::path& path) {
  auto text = read_file(path);
  if (!text) return std::unexpected(text.error());
  std::vector<Revocation> out;
  std::istringstream in(*text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream ls(line);
    Revocation r;
    if (!(ls >> r.key_id)) continue;
    const std::string where = path.string() + ":" + std::to_string(n) + ": ";
    if (r.key_id.size() != 64 || r.key_id.find_first_not_of("0123456789abcdef") != std::string::npos)
      return std::unexpected(where + "a key id is 64 lower-case hex digits (fogctl cert --public-key prints it), not '" + r.key_id + "'");
    if (!(ls >> r.revoked_at) || r.revoked_at.size() < 10 || r.revoked_at[4] != '-' || r.revoked_at[7] != '-')
      return std::unexpected(where + "the key id is followed by the date of its revocation (YYYY-MM-DD or an ISO 8601 time)");
    std::getline(ls >> std::ws, r.reason);
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace fogbench::signing
