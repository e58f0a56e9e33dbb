// The station key (issue 24, point 2), in-process: created at the first start with mode 0600
// and its public key beside it, the same key at the next start, refused (naming the path) when
// group or others may read it, when another user owns it, when it is not a key; a certificate
// signed with it checks valid with its public key and not with another's, every kind of
// tampering caught; keyrings and revocation lists read.
#include "fixture.hpp"

#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

#include "fogbench/daemon/config.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/signing/signing.hpp"

using namespace fogbench;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {
struct KeyDir {
  fs::path path = fs::temp_directory_path() / ("fogbench-signing-" + std::to_string(::getpid()));
  KeyDir() { fs::remove_all(path); }
  ~KeyDir() { fs::remove_all(path); }
};
unsigned mode_of(const fs::path& p) {
  struct stat st{};
  REQUIRE(::stat(p.c_str(), &st) == 0);
  return st.st_mode & 07777;
}
bool mentions(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

json body() {
  return {{"format", "fogbench.certificate"}, {"serial", "FOG-9"}, {"station_id", "line-2"}, {"verdict", "pass"},
          {"model", {{"id", 1}, {"version", 1}, {"coefficients", {{{"term", "mu0"}, {"value", -8.0123}}}}}}};
}
}  // namespace

TEST_CASE("station key: created 0600 in a new folder with its public key beside it, the same key at the next start") {
  KeyDir d;
  const fs::path key = d.path / "state" / "station.key";
  auto first = signing::load_or_create(key);
  REQUIRE(first.has_value());
  CHECK(first->created);
  CHECK(mode_of(key) == 0600);
  CHECK(mode_of(key.parent_path()) == 0700);
  const fs::path pub = d.path / "state" / "station.pub";
  REQUIRE(fs::exists(pub));
  CHECK(mode_of(pub) == 0644);
  CHECK(first->key.key_id().size() == 64);

  auto again = signing::load_or_create(key);
  REQUIRE(again.has_value());
  CHECK_FALSE(again->created);
  CHECK(again->key.key_id() == first->key.key_id());
  auto from_pub = signing::load_public_keys(pub);
  REQUIRE(from_pub.has_value());
  REQUIRE(from_pub->size() == 1);
  CHECK(from_pub->front().key_id() == first->key.key_id());

  // The public key, lost, is written again at the next start.
  fs::remove(pub);
  REQUIRE(signing::load_or_create(key).has_value());
  CHECK(fs::exists(pub));
}

TEST_CASE("station key: loose permissions, another owner, not a key, a folder: refused naming the path") {
  KeyDir d;
  const fs::path key = d.path / "station.key";
  REQUIRE(signing::load_or_create(key).has_value());

  fs::permissions(key, fs::perms(0644));
  auto loose = signing::load_or_create(key);
  REQUIRE_FALSE(loose.has_value());
  CHECK(mentions(loose.error(), key.string()));
  CHECK(mentions(loose.error(), "0644"));
  CHECK(mentions(loose.error(), "chmod 600"));
  fs::permissions(key, fs::perms(0640));
  CHECK_FALSE(signing::load_or_create(key).has_value());
  fs::permissions(key, fs::perms(0600));
  CHECK(signing::load_or_create(key).has_value());

  if (::geteuid() == 0) {  // as root the test can hand the file to another user
    REQUIRE(::chown(key.c_str(), 1, static_cast<gid_t>(-1)) == 0);
    auto other = signing::load_or_create(key);
    REQUIRE_FALSE(other.has_value());
    CHECK(mentions(other.error(), "owned by uid 1"));
    REQUIRE(::chown(key.c_str(), 0, static_cast<gid_t>(-1)) == 0);
  }

  const fs::path junk = d.path / "junk.key";
  {
    std::ofstream(junk) << "not a key\n";
  }
  fs::permissions(junk, fs::perms(0600));
  auto bad = signing::load_or_create(junk);
  REQUIRE_FALSE(bad.has_value());
  CHECK(mentions(bad.error(), junk.string()));
  CHECK(mentions(bad.error(), "not a PEM private key"));

  fs::create_directories(d.path / "dir.key");
  auto dir = signing::load_or_create(d.path / "dir.key");
  REQUIRE_FALSE(dir.has_value());
  CHECK(mentions(dir.error(), "dir.key"));

  // A public key is not a private one, and the checker refuses a private key as --key.
  auto as_pub = signing::load_public_keys(key);
  REQUIRE_FALSE(as_pub.has_value());
  CHECK(mentions(as_pub.error(), "a private key"));
}

TEST_CASE("station key: the configuration puts it beside the store unless signing.key_path says where") {
  json j = daemon::test::golden_config_json();
  j["storage"]["path"] = "/var/lib/fogbench/runs.sqlite";
  auto c = daemon::parse_daemon_config(j, daemon::test::golden_dir());
  INFO((c ? std::string() : c.error()));
  REQUIRE(c.has_value());
  CHECK(c->signing_key_path == fs::path("/var/lib/fogbench/station.key"));
  j["signing"] = {{"key_path", "keys/line2.key"}};
  auto c2 = daemon::parse_daemon_config(j, daemon::test::golden_dir());
  REQUIRE(c2.has_value());
  CHECK(c2->signing_key_path == daemon::test::golden_dir() / "keys/line2.key");
  j["signing"] = {{"key_path", "station.pub"}};
  auto c3 = daemon::parse_daemon_config(j, daemon::test::golden_dir());
  REQUIRE_FALSE(c3.has_value());
  CHECK(mentions(c3.error(), "signing.key_path"));
  j["signing"] = {{"path", "x.key"}};
  REQUIRE_FALSE(daemon::parse_daemon_config(j, daemon::test::golden_dir()).has_value());
  // A store in memory: no key file (a key for the process alone).
  j.erase("signing");
  j["storage"]["path"] = ":memory:";
  auto c4 = daemon::parse_daemon_config(j, daemon::test::golden_dir());
  REQUIRE(c4.has_value());
  CHECK(c4->signing_key_path.empty());
}

TEST_CASE("signed certificate: valid with its key, not with another's, and every kind of tampering caught") {
  auto a = signing::SigningKey::generate();
  auto b = signing::SigningKey::generate();
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  json cert = body();
  cert["issued_at"] = "2026-11-27T09:00:00Z";
  REQUIRE(signing::sign_certificate(cert, *a, "line-2").has_value());
  const std::vector<signing::PublicKey> ka{a->public_key()}, kb{b->public_key()};
  CHECK(signing::check_certificate(cert, ka).exit_code == 0);
  // The key of another station: cannot tell (2), never valid.
  CHECK(signing::check_certificate(cert, kb).exit_code == 2);
  CHECK(signing::check_certificate(cert, kb).status == "unknown key");
  CHECK(signing::check_certificate(cert, {}).exit_code == 2);

  // A field changed, its SHA-256 recomputed: a bad signature.
  json forged = cert;
  forged["verdict"] = "fail";
  forged["sha256"] = signing::content_sha256(forged);
  CHECK(signing::check_certificate(forged, ka).exit_code == 1);
  // One character of the signature changed.
  json flipped = cert;
  std::string sig = flipped["signature"];
  sig[10] = sig[10] == 'A' ? 'B' : 'A';
  flipped["signature"] = sig;
  CHECK(signing::check_certificate(flipped, ka).exit_code == 1);
  // The signature of another key over the same content, the key id left: bad signature.
  json other = cert;
  json resigned = cert;
  REQUIRE(signing::sign_certificate(resigned, *b, "line-2").has_value());
  other["signature"] = resigned["signature"];
  CHECK(signing::check_certificate(other, ka).exit_code == 1);
  // The whole certificate re-signed by another key: unknown to whoever holds the station's key.
  CHECK(signing::check_certificate(resigned, ka).exit_code == 2);
  // The station named in signed_by changed: bad signature (signed_by is signed too).
  json moved = cert;
  moved["signed_by"]["station_id"] = "line-3";
  moved["station_id"] = "line-3";
  moved["sha256"] = signing::content_sha256(moved);
  CHECK(signing::check_certificate(moved, ka).exit_code == 1);
  // Not signed at all (format_version 1).
  json old = body();
  old["sha256"] = signing::content_sha256(old);
  CHECK(signing::check_certificate(old, ka).exit_code == 2);
  CHECK(signing::check_certificate(old, ka).status == "unsigned");

  // Revocation: a key revoked after the certificate's date keeps it valid, one revoked before not.
  const std::vector<signing::Revocation> later{{a->key_id(), "2026-12-01", "retired"}};
  const std::vector<signing::Revocation> before{{a->key_id(), "2026-11-27", "stolen"}};
  CHECK(signing::check_certificate(cert, ka, later).exit_code == 0);
  CHECK(signing::check_certificate(cert, ka, before).exit_code == 1);
  CHECK(signing::check_certificate(cert, ka, before).status == "revoked");
}

TEST_CASE("keyrings and revocation lists: several keys in a file or a folder, a bad line named") {
  KeyDir d;
  fs::create_directories(d.path / "ring");
  auto a = signing::SigningKey::generate();
  auto b = signing::SigningKey::generate();
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  std::ofstream(d.path / "ring" / "2025.pub") << a->public_key().pem();
  std::ofstream(d.path / "ring" / "2026.pub") << b->public_key().pem();
  std::ofstream(d.path / "keyring.pem") << a->public_key().pem() << b->public_key().pem();
  std::ofstream(d.path / "ring" / "notes.txt") << "not a key";
  auto dir = signing::load_public_keys(d.path / "ring");
  REQUIRE(dir.has_value());
  REQUIRE(dir->size() == 2);
  CHECK(dir->at(0).key_id() == a->key_id());
  auto file = signing::load_public_keys(d.path / "keyring.pem");
  REQUIRE(file.has_value());
  CHECK(file->size() == 2);
  auto missing = signing::load_public_keys(d.path / "nope.pub");
  REQUIRE_FALSE(missing.has_value());
  CHECK(mentions(missing.error(), "nope.pub"));

  std::ofstream(d.path / "revoked.txt") << "# revoked station keys\n" << a->key_id() << " 2026-11-01 retired at the rotation\n\n";
  auto rv = signing::load_revocations(d.path / "revoked.txt");
  REQUIRE(rv.has_value());
  REQUIRE(rv->size() == 1);
  CHECK(rv->front().revoked_at == "2026-11-01");
  CHECK(rv->front().reason == "retired at the rotation");
  std::ofstream(d.path / "bad.txt") << a->key_id() << "\nXYZ 2026-01-01\n";
  auto bad = signing::load_revocations(d.path / "bad.txt");
  REQUIRE_FALSE(bad.has_value());
  CHECK(mentions(bad.error(), "bad.txt:1"));
}
