// The fleet queries (fleet.hpp).
#include "fogbench/plant/fleet.hpp"

#include <nlohmann/json.hpp>

#include "fleet_query.hpp"

namespace fogbench::plant {
namespace {

using Params = std::vector<std::optional<std::string>>;

// The filter on units u joined with runs r, parameters $1..$5.
constexpr const char* kWhere =
    "($1::text IS NULL OR u.lot = $1) AND ($2::text IS NULL OR r.bench_id = $2) "
    "AND ($3::text IS NULL OR u.serial = $3) AND ($4::timestamptz IS NULL OR r.ended_at >= $4::timestamptz) "
    "AND ($5::timestamptz IS NULL OR r.ended_at < $5::timestamptz)";

Params params(const FleetFilter& f) { return {f.lot, f.bench, f.serial, f.since, f.until}; }

std::int64_t to_i64(const std::optional<std::string>& s) { return s ? std::stoll(*s) : 0; }
double to_d(const std::optional<std::string>& s) { return s ? std::stod(*s) : 0.0; }

// ISO 8601 UTC text of a timestamptz column (the session's time zone is set to UTC).
constexpr const char* kIso = "to_char(r.ended_at AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"')";

}  // namespace

PlantResult<std::vector<SerialSummary>> serials(Connection& c, const FleetFilter& f) {
  const std::string sql = std::string(
                              "SELECT u.serial, count(*), string_agg(DISTINCT u.lot, ','), "
                              "string_agg(DISTINCT r.bench_id, ','), min(") + kIso + "), max(" + kIso +
                          "), (SELECT v.verdict FROM fogbench.verdicts v "
                          "WHERE v.serial = u.serial ORDER BY v.decided_at DESC, v.verdict_id DESC "
                          "LIMIT 1) FROM fogbench.units u JOIN fogbench.runs r USING (bench_id, run_id) WHERE " +
                          kWhere + " GROUP BY u.serial ORDER BY u.serial";
  auto rows = c.query(sql, params(f), "list the serials");
  if (!rows) return std::unexpected(rows.error());
  std::vector<SerialSummary> out;
  for (auto& r : rows->rows)
    out.push_back({r[0].value_or(""), to_i64(r[1]), r[2].value_or(""), r[3].value_or(""), r[4], r[5], r[6]});
  return out;
}

PlantResult<std::vector<HistoryEntry>> serial_history(Connection& c, const std::string& serial, const FleetFilter& f) {
  FleetFilter g = f;
  g.serial = serial;
  const std::string sql =
      std::string("SELECT r.bench_id, r.run_id, u.unit_index, u.lot, ") + kIso +
      ", r.purpose, r.state, (SELECT v.verdict FROM fogbench.verdicts v WHERE v.bench_id = u.bench_id AND "
      "v.run_id = u.run_id AND v.unit_index = u.unit_index ORDER BY v.verdict_id DESC LIMIT 1), "
      "(SELECT string_agg(fg.source || ':' || fg.name || '=' || fg.value::text, E'\\t' ORDER BY fg.source, fg.name) "
      "FROM fogbench.figures fg WHERE fg.bench_id = u.bench_id AND fg.run_id = u.run_id AND fg.unit_index = "
      "u.unit_index), ri.station_id, ri.operator, ri.operator_source, ri.software_version, ri.git_hash, "
      "ri.config_sha256, ri.profile_sha256, "
      "to_char(ui.powered_on_at AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'), ui.since_power_on_s "
      "FROM fogbench.units u JOIN fogbench.runs r USING (bench_id, run_id) "
      "LEFT JOIN fogbench.run_identity ri ON ri.bench_id = u.bench_id AND ri.run_id = u.run_id "
      "LEFT JOIN fogbench.unit_identity ui ON ui.bench_id = u.bench_id AND ui.run_id = u.run_id AND "
      "ui.unit_index = u.unit_index WHERE " +
      kWhere + " ORDER BY r.ended_at NULLS LAST, r.bench_id, r.run_id";
  auto rows = c.query(sql, params(g), "read the history of serial '" + serial + "'");
  if (!rows) return std::unexpected(rows.error());
  std::vector<HistoryEntry> out;
  for (auto& r : rows->rows) {
    HistoryEntry e;
    e.bench = r[0].value_or("");
    e.run_id = to_i64(r[1]);
    e.unit_index = static_cast<int>(to_i64(r[2]));
    e.lot = r[3];
    e.ended_at = r[4];
    e.purpose = r[5].value_or("");
    e.state = r[6].value_or("");
    e.verdict = r[7];
    if (r[8]) {
      std::size_t start = 0;
      const std::string& s = *r[8];
      while (start <= s.size()) {
        const std::size_t end = std::min(s.find('\t', start), s.size());
        const std::string item = s.substr(start, end - start);
        const std::size_t eq = item.rfind('=');
        if (eq != std::string::npos) e.figures.emplace_back(item.substr(0, eq), std::stod(item.substr(eq + 1)));
        start = end + 1;
      }
    }
    if (r[9])  // station_id is NOT NULL in run_identity: present exactly when the run has one
      e.identity = RunIdentityInfo{r[9].value_or(""),  r[10].value_or(""), r[11].value_or(""), r[12].value_or(""),
                                   r[13].value_or(""), r[14].value_or(""), r[15].value_or("")};
    e.powered_on_at = r[16];
    if (r[17]) e.since_power_on_s = to_d(r[17]);
    out.push_back(std::move(e));
  }
  return out;
}

PlantResult<std::vector<SerialCertificate>> serial_certificates(Connection& c, const std::string& serial,
                                                                const FleetFilter& f) {
  const std::string sql =
      "SELECT ce.bench_id, ce.certificate_id, ce.model_id, ce.model_version, ce.sha256, "
      "to_char(ce.created_at AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'), ce.json, m.run_id "
      "FROM fogbench.certificates ce LEFT JOIN fogbench.models m ON m.bench_id = ce.bench_id AND m.model_id = "
      "ce.model_id WHERE ce.serial = $1 AND ($2::text IS NULL OR ce.bench_id = $2) "
      "ORDER BY ce.created_at, ce.bench_id, ce.certificate_id";
  auto rows = c.query(sql, {serial, f.bench}, "read the certificates of serial '" + serial + "'");
  if (!rows) return std::unexpected(rows.error());
  std::vector<SerialCertificate> out;
  for (auto& r : rows->rows) {
    SerialCertificate ce;
    ce.bench = r[0].value_or("");
    ce.certificate_id = to_i64(r[1]);
    ce.model_id = to_i64(r[2]);
    ce.model_version = static_cast<int>(to_i64(r[3]));
    ce.sha256 = r[4].value_or("");
    ce.issued_at = r[5];
    // The verdict from the certificate's canonical JSON (kept as text: its hash is of those bytes).
    const auto j = nlohmann::json::parse(r[6].value_or(""), nullptr, false);
    if (j.is_object() && j.contains("verdict") && j["verdict"].is_string()) ce.verdict = j["verdict"].get<std::string>();
    if (r[7]) ce.run_id = to_i64(r[7]);
    out.push_back(std::move(ce));
  }
  return out;
}

PlantResult<std::vector<FigureValue>> figure_values(Connection& c, const std::string& name, const FleetFilter& f) {
  auto p = params(f);
  p.push_back(name);
  const std::string sql =
      std::string("SELECT r.bench_id, r.run_id, u.unit_index, u.serial, u.lot, ") + kIso +
      ", fg.source, fg.value FROM fogbench.figures fg JOIN fogbench.units u USING (bench_id, run_id, unit_index) "
      "JOIN fogbench.runs r USING (bench_id, run_id) WHERE fg.name = $6 AND " +
      kWhere + " ORDER BY r.ended_at NULLS LAST, r.bench_id, r.run_id, u.unit_index, fg.source_id";
  auto rows = detail::query_scan(c, sql, p, "read the values of '" + name + "'");
  if (!rows) return std::unexpected(rows.error());
  std::vector<FigureValue> out;
  out.reserve(rows->rows.size());
  for (auto& r : rows->rows)
    out.push_back({r[0].value_or(""), to_i64(r[1]), static_cast<int>(to_i64(r[2])), r[3].value_or(""), r[4], r[5],
                   r[6].value_or(""), to_d(r[7])});
  return out;
}

PlantResult<std::vector<FigureName>> figure_names(Connection& c, const FleetFilter& f) {
  const std::string sql = std::string(
                              "SELECT fg.name, fg.source, count(*) FROM fogbench.figures fg JOIN fogbench.units u "
                              "USING (bench_id, run_id, unit_index) JOIN fogbench.runs r USING (bench_id, run_id) "
                              "WHERE ") +
                          kWhere + " GROUP BY fg.name, fg.source ORDER BY fg.source, fg.name";
  auto rows = c.query(sql, params(f), "list the figures");
  if (!rows) return std::unexpected(rows.error());
  std::vector<FigureName> out;
  for (auto& r : rows->rows) out.push_back({r[0].value_or(""), r[1].value_or(""), to_i64(r[2])});
  return out;
}

}  // namespace fogbench::plant
