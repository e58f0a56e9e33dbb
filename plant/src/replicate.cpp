// Replication of one completed run from a bench's SQLite store to the plant, in one
// transaction: delete what the plant held for (bench_id, run_id), then insert the run, its
// identity, its units, events, models, verifications, verdicts and figures, and COPY its samples; the
// certificates of its units' serials are inserted when the plant does not hold them yet, and
// the public key each was signed with goes into station_keys.
#include <charconv>
#include <cmath>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "sample_stream.hpp"
#include "fogbench/plant/plant.hpp"
#include "fogbench/signing/signing.hpp"
#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/outbox.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/store.hpp"
#include "fogbench/storage/verdict.hpp"

namespace fogbench::plant {
namespace {

using Params = std::vector<std::optional<std::string>>;

void put_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "\\N";
    return;
  }
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

void put_int(std::string& out, std::int64_t v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

std::optional<std::string> num_text(double v) {
  if (!std::isfinite(v)) return std::nullopt;
  std::string s;
  put_number(s, v);
  return s;
}

PlantError from_store(const storage::StoreError& e) { return {PlantErrc::bench_store, "the bench's store: " + e.message}; }

// One figure row of COPY fogbench.figures.
void figure(std::string& out, std::string_view bench, std::int64_t run, int unit, std::string_view source,
            std::int64_t source_id, std::string_view name, const nlohmann::json* v) {
  if (!v || !v->is_number()) return;
  const double x = v->get<double>();
  if (!std::isfinite(x)) return;
  copy_escape(out, bench);
  out += '\t';
  put_int(out, run);
  out += '\t';
  put_int(out, unit);
  out += '\t';
  out += source;
  out += '\t';
  put_int(out, source_id);
  out += '\t';
  copy_escape(out, name);
  out += '\t';
  put_number(out, x);
  out += '\n';
}

// A transaction's failure: rolled back (unless the connection is gone, which rolls it back), the
// error named by what was being done.
std::unexpected<PlantError> rolled_back(Connection& plant, const std::string& what, PlantError e) {
  if (e.code != PlantErrc::connection_lost) (void)plant.exec("ROLLBACK", what);
  e.message = what + ": " + e.message;
  return std::unexpected(std::move(e));
}

// One verdict row; `if_absent`: a row the plant holds already is left as it is.
PlantResult<Rows> insert_verdict(Connection& plant, const std::string& bench, const storage::VerdictRecord& v,
                                 bool if_absent) {
  return plant.query(
      std::string("INSERT INTO fogbench.verdicts (bench_id, verdict_id, serial, run_id, unit_index, model_id, verdict, "
                  "rule, plan_id, plan_name, plan_sha256, limits_json, reasons_json, decided_at, axes_json) "
                  "VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15)") +
          (if_absent ? " ON CONFLICT DO NOTHING" : ""),
      {bench, std::to_string(v.id), v.serial, std::to_string(v.run_id), std::to_string(v.unit_index),
       v.model_id ? std::optional(std::to_string(*v.model_id)) : std::nullopt, v.verdict, v.rule,
       v.plan_id ? std::optional(std::to_string(*v.plan_id)) : std::nullopt, v.plan_name, v.plan_sha256,
       v.limits_json, v.reasons_json, v.decided_at, v.axes_json.empty() ? std::nullopt : std::optional(v.axes_json)},
      "insert verdict " + std::to_string(v.id));
}

const nlohmann::json* at(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return nullptr;
  auto it = j.find(key);
  return it == j.end() ? nullptr : &*it;
}

}  // namespace

PlantResult<ReplicateStats> replicate_run(Connection& plant, storage::Store& bench, std::string_view bench_id,
                                          std::int64_t run_id) {
  const std::string what = "replicate run " + std::to_string(run_id) + " of bench '" + std::string(bench_id) + "'";
  if (auto why = check_id(bench_id, "bench id"); !why.empty())
    return std::unexpected(PlantError{PlantErrc::invalid_argument, what + ": " + why});

  // Everything is read from the bench first: the plant's transaction stays short.
  auto detail = bench.get_run(run_id);
  if (!detail) return std::unexpected(from_store(detail.error()));
  const storage::RunRecord& run = detail->run;
  for (const auto& u : run.units) {
    if (u.lot) {
      if (auto why = check_id(*u.lot, "lot id of unit " + std::to_string(u.unit_index)); !why.empty())
        return std::unexpected(PlantError{PlantErrc::invalid_argument, what + ": " + why});
    }
  }
  std::vector<storage::ModelRecord> models;
  for (const auto& u : run.units) {
    auto ms = bench.list_models(u.serial);
    if (!ms) return std::unexpected(from_store(ms.error()));
    for (auto& m : *ms)
      if (m.run_id == run_id) models.push_back(std::move(m));
  }
  auto verifications = bench.list_verifications(run_id);
  if (!verifications) return std::unexpected(from_store(verifications.error()));
  auto identity = bench.get_run_identity(run_id);
  if (!identity) return std::unexpected(from_store(identity.error()));
  auto verdicts = bench.run_verdicts(run_id);
  if (!verdicts) return std::unexpected(from_store(verdicts.error()));
  std::vector<storage::CertificateRecord> certificates;
  for (const auto& u : run.units) {
    auto cs = bench.list_certificates(u.serial);
    if (!cs) return std::unexpected(from_store(cs.error()));
    for (auto& cert : *cs) certificates.push_back(std::move(cert));
  }

  ReplicateStats stats;
  const std::string b(bench_id);
  const std::string rid = std::to_string(run_id);
  auto fail = [&](PlantError e) { return rolled_back(plant, what, std::move(e)); };
  if (auto ok = plant.exec("BEGIN", what); !ok) return fail(ok.error());
  // The bench marks the run sent once COMMIT returns: the commit must then be on the plant's
  // disk, whatever the server's default (synchronous_commit = off would lose it in a crash).
  if (auto ok = plant.exec("SET LOCAL synchronous_commit = on", what); !ok) return fail(ok.error());
  if (auto ok = plant.query("DELETE FROM fogbench.samples WHERE bench_id = $1 AND run_id = $2", {b, rid},
                            "delete the samples held before");
      !ok)
    return fail(ok.error());
  if (auto ok = plant.query("DELETE FROM fogbench.runs WHERE bench_id = $1 AND run_id = $2", {b, rid},
                            "delete the run held before");
      !ok)
    return fail(ok.error());
  if (auto ok = plant.query(
          "INSERT INTO fogbench.runs (bench_id, run_id, created_at, profile_name, purpose, state, state_reason, "
          "config_json, started_at, ended_at, time_scale) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11)",
          {b, rid, run.created_at, run.profile_name, std::string(storage::to_string(run.purpose)),
           std::string(storage::to_string(run.state)), run.state_reason, run.config_json, run.started_at,
           run.ended_at, num_text(run.time_scale)},
          "insert the run");
      !ok)
    return fail(ok.error());
  for (const auto& u : run.units) {
    if (auto ok = plant.query("INSERT INTO fogbench.units (bench_id, run_id, unit_index, serial, lot, axes) "
                              "VALUES ($1, $2, $3, $4, $5, $6)",
                              {b, rid, std::to_string(u.unit_index), u.serial, u.lot, std::to_string(u.axes)},
                              "insert a unit");
        !ok)
      return fail(ok.error());
    ++stats.units;
  }
  // The identity (none for a run recorded before the bench kept one).
  if (*identity) {
    const storage::RunIdentity& ri = **identity;
    if (auto ok = plant.query(
            "INSERT INTO fogbench.run_identity (bench_id, run_id, station_id, operator, operator_source, "
            "software_version, git_hash, config_sha256, profile_sha256) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
            {b, rid, ri.station_id, ri.operator_name, ri.operator_source, ri.software_version, ri.git_hash,
             ri.config_sha256, ri.profile_sha256},
            "insert the run's identity");
        !ok)
      return fail(ok.error());
    ++stats.identity_rows;
    for (const auto& ui : ri.units) {
      if (auto ok = plant.query("INSERT INTO fogbench.unit_identity (bench_id, run_id, unit_index, powered_on_at, "
                                "since_power_on_s) VALUES ($1, $2, $3, $4, $5)",
                                {b, rid, std::to_string(ui.unit_index), ui.powered_on_at,
                                 ui.since_power_on_s ? num_text(*ui.since_power_on_s) : std::nullopt},
                                "insert the identity of unit " + std::to_string(ui.unit_index));
          !ok)
        return fail(ok.error());
      ++stats.identity_rows;
    }
  }
  // Certificates are immutable and belong to a serial: one sent before stays as it is.
  for (const auto& cert : certificates) {
    if (auto ok = plant.query(
            "INSERT INTO fogbench.certificates (bench_id, certificate_id, serial, model_id, model_version, sha256, "
            "json, created_at) VALUES ($1, $2, $3, $4, $5, $6, $7, $8) ON CONFLICT DO NOTHING RETURNING 1",
            {b, std::to_string(cert.id), cert.serial, std::to_string(cert.model_id),
             std::to_string(cert.model_version), cert.sha256, cert.json, cert.created_at},
            "insert certificate " + std::to_string(cert.id));
        !ok)
      return fail(ok.error());
    else if (ok->rows.empty())
      ++stats.certificates_held;
    else
      ++stats.certificates;
  }
  // The key each certificate was signed with, into the plant's keyring (issue 24): only a public
  // key whose id is the one the certificate names (a certificate of before issue 24 has none).
  for (const auto& cert : certificates) {
    const auto j = nlohmann::json::parse(cert.json, nullptr, false);
    if (!j.is_object() || !j.contains("signed_by") || !j["signed_by"].is_object()) continue;
    const auto& sb = j["signed_by"];
    const std::string pem = sb.value("public_key_pem", ""), key_id = sb.value("key_id", "");
    auto key = signing::PublicKey::from_pem(pem);
    if (!key || key->key_id() != key_id) {
      ++stats.station_keys_refused;
      continue;
    }
    auto ok = plant.query(
        "INSERT INTO fogbench.station_keys (station_id, key_id, public_key_pem, first_seen) VALUES ($1, $2, $3, $4) "
        "ON CONFLICT (station_id, key_id) DO UPDATE SET first_seen = least(fogbench.station_keys.first_seen, "
        "EXCLUDED.first_seen) RETURNING (xmax = 0)",
        {sb.value("station_id", ""), key_id, pem, cert.created_at}, "record the public key of certificate " + std::to_string(cert.id));
    if (!ok) return fail(ok.error());
    if (!ok->rows.empty() && !ok->rows.front().empty() && ok->rows.front().front() == std::optional<std::string>("t"))
      ++stats.station_keys;
  }

  // Events by COPY.
  {
    std::string data;
    for (const auto& e : detail->events) {
      copy_escape(data, b);
      data += '\t';
      put_int(data, run_id);
      data += '\t';
      put_int(data, e.id);
      data += '\t';
      if (e.t_s) put_number(data, *e.t_s);
      else data += "\\N";
      data += '\t';
      copy_escape(data, e.at);
      data += '\t';
      copy_escape(data, storage::to_string(e.kind));
      data += '\t';
      copy_escape(data, e.detail_json.empty() ? "{}" : e.detail_json);
      data += '\n';
    }
    auto n = plant.copy_in("COPY fogbench.events (bench_id, run_id, event_id, t_s, at, kind, detail) FROM STDIN",
                           data, "copy the events");
    if (!n) return fail(n.error());
    stats.events = *n;
  }

  // Samples by one COPY in binary format (copy_binary.hpp: no number is printed here nor parsed
  // by the server), read and encoded a page of each unit at a time on a thread of their own
  // (sample_stream.hpp: a few MB in memory, never the whole run) while the server takes the
  // page before.
  {
    if (auto ok = plant.copy_begin(
            "COPY fogbench.samples (bench_id, run_id, unit_index, t_s, wall_time, setpoint_c, chamber_c, gyro_dph, "
            "frames, t1_c, t2_c, phase, step, flags, since_power_on_s, compensated_dph, rate_in_dps, gyro_y_dph, "
            "gyro_z_dph, t1_y_c, t2_y_c, t1_z_c, t2_z_c) FROM STDIN (FORMAT binary)",
            "copy the samples");
        !ok)
      return fail(ok.error());
    std::vector<int> units;
    for (const auto& u : run.units) units.push_back(u.unit_index);
    detail::SampleStream stream(bench, b, run_id, units);
    while (auto chunk = stream.next()) {
      if (!chunk->error.empty()) {
        // Ends the COPY so the transaction can be rolled back: nothing of the run is committed.
        (void)plant.copy_end("abandon the samples' COPY");
        return fail(PlantError{PlantErrc::bench_store, "the bench's store: " + chunk->error});
      }
      if (auto ok = plant.copy_put(chunk->data, "copy the samples"); !ok) return fail(ok.error());
    }
    auto n = plant.copy_end("copy the samples");
    if (!n) return fail(n.error());
    stats.samples = *n;
  }

  // Models fitted on the run, verifications of it, and the figures the fleet statistics read.
  std::string figures;
  for (const auto& m : models) {
    std::optional<std::string> unit;
    int unit_index = 0;
    for (const auto& u : run.units)
      if (u.serial == m.serial) {
        unit = std::to_string(u.unit_index);
        unit_index = u.unit_index;
        break;
      }
    if (auto ok = plant.query(
            "INSERT INTO fogbench.models (bench_id, model_id, run_id, unit_index, serial, version, parent_id, "
            "created_at, method, terms, model_json, axis) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)",
            {b, std::to_string(m.id), rid, unit, m.serial, std::to_string(m.version),
             m.parent_id ? std::optional(std::to_string(*m.parent_id)) : std::nullopt, m.created_at, m.method, m.terms,
             m.model_json, m.axis.empty() ? std::nullopt : std::optional(m.axis)},
            "insert model " + std::to_string(m.id));
        !ok)
      return fail(ok.error());
    ++stats.models;
    const auto j = nlohmann::json::parse(m.model_json, nullptr, false);
    figure(figures, b, run_id, unit_index, "model", m.id, "mu0", at(j, "mu0"));
    figure(figures, b, run_id, unit_index, "model", m.id, "sigma_a", at(j, "sigma_a"));
    if (const auto* terms = at(j, "terms"); terms && terms->is_array()) {
      for (const auto& t : *terms) {
        const auto* name = at(t, "term");
        if (name && name->is_string()) figure(figures, b, run_id, unit_index, "model", m.id, name->get<std::string>(), at(t, "coef"));
      }
    }
  }
  for (const auto& v : *verifications) {
    const auto j = nlohmann::json::parse(v.result_json, nullptr, false);
    const auto* verdict = at(j, "verdict");
    if (auto ok = plant.query(
            "INSERT INTO fogbench.verifications (bench_id, verification_id, run_id, unit_index, model_id, created_at, "
            "pass, verdict, result_json) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
            {b, std::to_string(v.id), rid, std::to_string(v.unit_index), std::to_string(v.model_id), v.created_at,
             v.pass ? "true" : "false",
             verdict && verdict->is_string() ? std::optional(verdict->get<std::string>()) : std::nullopt,
             v.result_json},
            "insert verification " + std::to_string(v.id));
        !ok)
      return fail(ok.error());
    ++stats.verifications;
    for (const char* name : {"ratio", "comp_std", "meas_std", "noise_std", "noise_factor", "longest_fail_s"})
      figure(figures, b, run_id, v.unit_index, "verification", v.id, name, at(j, name));
  }
  // The verdicts this run decided (the bench's one verdict per serial, issue 24).
  for (const auto& v : *verdicts) {
    if (auto ok = insert_verdict(plant, b, v, false); !ok) return fail(ok.error());
    ++stats.verdicts;
  }
  if (!figures.empty()) {
    auto n = plant.copy_in(
        "COPY fogbench.figures (bench_id, run_id, unit_index, source, source_id, name, value) FROM STDIN", figures,
        "copy the figures");
    if (!n) return fail(n.error());
    stats.figures = *n;
  }
  if (auto ok = plant.exec("COMMIT", what); !ok) return fail(ok.error());
  return stats;
}

PlantResult<std::int64_t> send_outbox(Connection& plant, storage::Store& bench, std::string_view bench_id,
                                      std::int64_t limit) {
  std::int64_t sent = 0;
  while (sent < limit) {
    auto head = bench.pending_replications(1);
    if (!head) return std::unexpected(from_store(head.error()));
    if (head->empty()) break;
    const storage::OutboxEntry entry = head->front();
    auto r = replicate_run(plant, bench, bench_id, entry.run_id);
    if (!r) {
      (void)bench.mark_replication_failed(entry.id, r.error().message);
      return std::unexpected(r.error());
    }
    if (auto ok = bench.mark_replicated(entry.id); !ok) return std::unexpected(from_store(ok.error()));
    ++sent;
  }
  return sent;
}

PlantResult<std::int64_t> send_missing_verdicts(Connection& plant, storage::Store& bench, std::string_view bench_id) {
  const std::string b(bench_id);
  const std::string what = "send the verdicts the plant lacks";
  auto mine = bench.list_verdicts();
  if (!mine) return std::unexpected(from_store(mine.error()));
  if (mine->empty()) return 0;
  auto held = plant.query("SELECT verdict_id FROM fogbench.verdicts WHERE bench_id = $1", {b}, what);
  if (!held) return std::unexpected(held.error());
  auto runs = plant.query("SELECT run_id FROM fogbench.runs WHERE bench_id = $1", {b}, what);
  if (!runs) return std::unexpected(runs.error());
  std::set<std::int64_t> held_ids, run_ids;
  for (const auto& r : held->rows) held_ids.insert(std::stoll(r.at(0).value_or("0")));
  for (const auto& r : runs->rows) run_ids.insert(std::stoll(r.at(0).value_or("0")));
  std::vector<const storage::VerdictRecord*> missing;
  for (const auto& v : *mine)
    if (!held_ids.contains(v.id) && run_ids.contains(v.run_id)) missing.push_back(&v);
  if (missing.empty()) return 0;
  auto fail = [&](PlantError e) { return rolled_back(plant, what, std::move(e)); };
  if (auto ok = plant.exec("BEGIN", what); !ok) return fail(ok.error());
  if (auto ok = plant.exec("SET LOCAL synchronous_commit = on", what); !ok) return fail(ok.error());
  for (const auto* v : missing)
    if (auto ok = insert_verdict(plant, b, *v, true); !ok) return fail(ok.error());
  if (auto ok = plant.exec("COMMIT", what); !ok) return std::unexpected(ok.error());
  return static_cast<std::int64_t>(missing.size());
}

}  // namespace fogbench::plant
