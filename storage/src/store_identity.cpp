// A run's identity and the certificates (issue 13): the Store's reads and writes of the tables
// run_identity, run_unit_identity and certificates, the operator-name check, and the identity's
// `# key: value` form at the top of a run's CSV. The other rooms: store.cpp (runs),
// store_samples.cpp (samples, import), store_models.cpp (models, verifications).
#include <charconv>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/store.hpp"
#include "store_identity.hpp"
#include "store_rows.hpp"

namespace fogbench::storage {

std::string_view operator_source_name(std::string_view s) {
  for (std::string_view v : {"client", "peer", "import", "none"})
    if (s == v) return v;
  return {};
}

namespace {
// The offset of the first byte that does not start a well-formed UTF-8 sequence (RFC 3629: no
// overlong forms, no surrogates, nothing above U+10FFFF), npos when all of `s` is well formed.
std::size_t first_invalid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto b = static_cast<unsigned char>(s[i]);
    std::size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the allowed range of the second byte
    if (b < 0x80) len = 1;
    else if (b >= 0xC2 && b <= 0xDF) len = 2;
    else if (b == 0xE0) len = 3, lo = 0xA0;
    else if (b == 0xED) len = 3, hi = 0x9F;
    else if (b >= 0xE1 && b <= 0xEF) len = 3;
    else if (b == 0xF0) len = 4, lo = 0x90;
    else if (b == 0xF4) len = 4, hi = 0x8F;
    else if (b >= 0xF1 && b <= 0xF3) len = 4;
    else return i;
    if (i + len > s.size()) return i;
    for (std::size_t k = 1; k < len; ++k) {
      const auto c = static_cast<unsigned char>(s[i + k]);
      if (c < (k == 1 ? lo : 0x80u) || c > (k == 1 ? hi : 0xBFu)) return i;
    }
    i += len;
  }
  return std::string_view::npos;
}
}  // namespace

std::string check_stored_text(std::string_view field, std::string_view value, std::size_t max_bytes) {
  const std::string f(field);
  if (value.size() > max_bytes)
    return f + ": longer than " + std::to_string(max_bytes) + " bytes (" + std::to_string(value.size()) + ")";
  for (std::size_t i = 0; i < value.size(); ++i) {
    const auto c = static_cast<unsigned char>(value[i]);
    if (c < 0x20 || c == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof code, "0x%02X", c);
      return f + ": control character " + std::string(code) + " at byte " + std::to_string(i + 1);
    }
  }
  if (const auto bad = first_invalid_utf8(value); bad != std::string_view::npos)
    return f + ": not valid UTF-8 at byte " + std::to_string(bad + 1);
  return {};
}

std::string check_operator_name(std::string_view name) {
  return check_stored_text("operator", name, kMaxOperatorBytes);
}

namespace {
std::string number_text(double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}
}  // namespace

std::vector<std::pair<std::string, std::string>> identity_fields(const RunIdentity& id, std::int64_t run_id,
                                                                 std::string_view profile_name, int unit_index) {
  std::vector<std::pair<std::string, std::string>> f = {
      {"run", std::to_string(run_id)},
      {"profile", std::string(profile_name)},
      {"profile_sha256", id.profile_sha256},
      {"station_id", id.station_id},
      {"operator", id.operator_name},
      {"operator_source", id.operator_source},
      {"software_version", id.software_version},
      {"git_hash", id.git_hash},
      {"config_sha256", id.config_sha256},
  };
  for (const auto& u : id.units) {
    if (u.unit_index != unit_index) continue;
    f.emplace_back("serial", u.serial);
    f.emplace_back("powered_on_at", u.powered_on_at.value_or(""));
    f.emplace_back("since_power_on_s", u.since_power_on_s ? number_text(*u.since_power_on_s) : "");
  }
  return f;
}

std::string identity_comment_lines(const std::vector<std::pair<std::string, std::string>>& fields) {
  std::string out;
  for (const auto& [k, v] : fields) {
    out += "# " + k + ":";
    // A value is one line: a line break (never in what the daemon checks) would end the comment.
    std::string one;
    for (char c : v) one += (c == '\n' || c == '\r') ? ' ' : c;
    if (!one.empty()) out += " " + one;
    out += "\n";
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> read_comment_fields(std::string_view text) {
  std::vector<std::pair<std::string, std::string>> out;
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    if (line.ends_with('\r')) line.remove_suffix(1);
    const std::size_t first = line.find_first_not_of(" \t");
    if (first == std::string_view::npos) continue;  // blank
    if (line[first] != '#') break;                  // the header row: the comments above it end here
    std::string_view body = line.substr(first + 1);
    while (!body.empty() && (body.front() == ' ' || body.front() == '\t')) body.remove_prefix(1);
    const std::size_t colon = body.find(':');
    if (colon == std::string_view::npos || colon == 0) continue;
    const std::string_view key = body.substr(0, colon);
    if (key.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_") != std::string_view::npos) continue;
    std::string_view value = body.substr(colon + 1);
    while (!value.empty() && (value.front() == ' ' || value.front() == '\t')) value.remove_prefix(1);
    while (!value.empty() && (value.back() == ' ' || value.back() == '\t')) value.remove_suffix(1);
    out.emplace_back(std::string(key), std::string(value));
  }
  return out;
}

std::optional<std::string> lot_from_fields(const std::vector<std::pair<std::string, std::string>>& fields) {
  for (const auto& [key, value] : fields)
    if (key == "lot") return value.empty() ? std::nullopt : std::optional<std::string>(value);
  return std::nullopt;
}

std::optional<RunIdentity> identity_from_fields(const std::vector<std::pair<std::string, std::string>>& fields) {
  RunIdentity id;
  UnitIdentity u;
  bool has_version = false;
  for (const auto& [k, v] : fields) {
    if (k == "station_id") id.station_id = v;
    else if (k == "operator") id.operator_name = v;
    else if (k == "software_version") {
      id.software_version = v;
      has_version = !v.empty();
    } else if (k == "git_hash") id.git_hash = v;
    else if (k == "config_sha256") id.config_sha256 = v;
    else if (k == "profile_sha256") id.profile_sha256 = v;
    else if (k == "serial") u.serial = v;
    else if (k == "powered_on_at" && !v.empty()) u.powered_on_at = v;
    else if (k == "since_power_on_s" && !v.empty()) {
      double x = 0;
      auto r = std::from_chars(v.data(), v.data() + v.size(), x);
      if (r.ec == std::errc{} && r.ptr == v.data() + v.size() && std::isfinite(x) && x >= 0) u.since_power_on_s = x;
    }
  }
  if (!has_version) return std::nullopt;
  id.operator_source = id.operator_name.empty() ? "none" : "import";
  id.units.push_back(std::move(u));
  return id;
}

namespace detail {

StoreResult<void> insert_identity(Database& db, std::int64_t run_id, const RunIdentity& id, std::string_view what) {
  if (operator_source_name(id.operator_source).empty())
    return std::unexpected(db.error(StoreErrc::invalid_argument,
                                    std::string(what) + ": operator_source '" + id.operator_source +
                                        "' is not client, peer, import or none"));
  if (auto why = check_operator_name(id.operator_name); !why.empty())
    return std::unexpected(db.error(StoreErrc::invalid_argument, std::string(what) + ": " + why));
  {
    auto stmt = db.statement(
        "INSERT INTO run_identity (run_id, station_id, operator, operator_source, software_version, git_hash, "
        "config_sha256, profile_sha256) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    if (!stmt) return fail(std::move(stmt));
    Query q(db, *stmt);
    q.bind(1, run_id)
        .bind(2, id.station_id)
        .bind(3, id.operator_name)
        .bind(4, id.operator_source)
        .bind(5, id.software_version)
        .bind(6, id.git_hash)
        .bind(7, id.config_sha256)
        .bind(8, id.profile_sha256);
    if (auto ok = run(db, q, what); !ok) return ok;
  }
  auto stmt = db.statement(
      "INSERT INTO run_unit_identity (run_id, unit_index, powered_on_at, since_power_on_s) VALUES (?1, ?2, ?3, ?4)");
  if (!stmt) return fail(std::move(stmt));
  for (const auto& u : id.units) {
    Query q(db, *stmt);
    q.bind(1, run_id).bind(2, u.unit_index).bind(3, u.powered_on_at).bind(4, u.since_power_on_s);
    if (auto ok = run(db, q, std::string(what) + ": unit " + std::to_string(u.unit_index)); !ok) return ok;
  }
  return {};
}

}  // namespace detail

StoreResult<std::optional<RunIdentity>> Store::get_run_identity(std::int64_t run_id) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "read the identity of " + run_label(run_id);
  auto run = get_run(run_id);
  if (!run) return std::unexpected(run.error());
  auto stmt = db.statement(
      "SELECT station_id, operator, operator_source, software_version, git_hash, config_sha256, profile_sha256 "
      "FROM run_identity WHERE run_id = ?1");
  if (!stmt) return fail(std::move(stmt));
  RunIdentity id;
  {
    Query q(db, *stmt);
    q.bind(1, run_id);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    if (!*got) return std::optional<RunIdentity>{};
    id.station_id = q.text(0);
    id.operator_name = q.text(1);
    id.operator_source = q.text(2);
    id.software_version = q.text(3);
    id.git_hash = q.text(4);
    id.config_sha256 = q.text(5);
    id.profile_sha256 = q.text(6);
  }
  auto units = db.statement(
      "SELECT unit_index, powered_on_at, since_power_on_s FROM run_unit_identity WHERE run_id = ?1 AND unit_index = ?2");
  if (!units) return fail(std::move(units));
  for (const auto& ru : run->run.units) {
    UnitIdentity u;
    u.unit_index = ru.unit_index;
    u.serial = ru.serial;
    Query q(db, *units);
    q.bind(1, run_id).bind(2, ru.unit_index);
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    if (*got) {
      u.powered_on_at = q.opt_text(1);
      u.since_power_on_s = q.opt_real(2);
    }
    id.units.push_back(std::move(u));
  }
  return std::optional<RunIdentity>(std::move(id));
}

namespace {

constexpr std::string_view kCertColumns = "id, serial, model_id, model_version, sha256, json, created_at";

CertificateRecord read_certificate(const Query& q) {
  CertificateRecord c;
  c.id = q.int64(0);
  c.serial = q.text(1);
  c.model_id = q.int64(2);
  c.model_version = static_cast<int>(q.int64(3));
  c.sha256 = q.text(4);
  c.json = q.text(5);
  c.created_at = q.text(6);
  return c;
}

StoreResult<std::vector<CertificateRecord>> read_certificates(Database& db, sqlite3_stmt* stmt, std::string_view key,
                                                              std::string_view what) {
  std::vector<CertificateRecord> out;
  Query q(db, stmt);
  q.bind(1, key);
  for (;;) {
    auto got = row(db, q, what);
    if (!got) return fail(std::move(got));
    if (!*got) break;
    out.push_back(read_certificate(q));
  }
  return out;
}

}  // namespace

StoreResult<std::int64_t> Store::put_certificate(const NewCertificate& c) {
  assert(db_);
  Database& db = *db_;
  const std::string what = "store a certificate for serial '" + c.serial + "'";
  if (!is_json(c.json)) return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": not valid JSON"));
  if (c.sha256.size() != 64 || c.sha256.find_first_not_of("0123456789abcdef") != std::string::npos)
    return std::unexpected(db.error(StoreErrc::invalid_argument, what + ": sha256 is not 64 hex digits"));
  auto m = get_model(c.model_id);
  if (!m) return std::unexpected(m.error());
  if (m->serial != c.serial || m->version != c.model_version)
    return std::unexpected(db.error(StoreErrc::invalid_argument,
                                    what + ": model " + std::to_string(c.model_id) + " is version " +
                                        std::to_string(m->version) + " of " + m->serial));
  return with_reserve(db, [&]() -> StoreResult<std::int64_t> {
    Transaction tx(db);
    if (auto ok = tx.begin(what); !ok) return fail(std::move(ok));
    auto stmt = db.statement(
        "INSERT INTO certificates (serial, model_id, model_version, sha256, json, created_at) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    if (!stmt) return fail(std::move(stmt));
    {
      Query q(db, *stmt);
      q.bind(1, c.serial).bind(2, c.model_id).bind(3, c.model_version).bind(4, c.sha256).bind(5, c.json).bind(6, db.now_iso());
      if (auto ok = run(db, q, what); !ok) return fail(std::move(ok));
    }
    const std::int64_t id = sqlite3_last_insert_rowid(db.handle());
    if (auto ok = tx.commit(what); !ok) return fail(std::move(ok));
    return id;
  });
}

StoreResult<std::vector<CertificateRecord>> Store::find_certificates(std::string_view sha256) {
  assert(db_);
  static const std::string sql = "SELECT " + std::string(kCertColumns) + " FROM certificates WHERE sha256 = ?1 ORDER BY id";
  auto stmt = db_->statement(sql);
  if (!stmt) return fail(std::move(stmt));
  return read_certificates(*db_, *stmt, sha256, "find certificates by hash");
}

StoreResult<std::vector<CertificateRecord>> Store::list_certificates(std::string_view serial) {
  assert(db_);
  static const std::string sql = "SELECT " + std::string(kCertColumns) + " FROM certificates WHERE serial = ?1 ORDER BY id";
  auto stmt = db_->statement(sql);
  if (!stmt) return fail(std::move(stmt));
  return read_certificates(*db_, *stmt, serial, "list the certificates of serial '" + std::string(serial) + "'");
}

}  // namespace fogbench::storage
