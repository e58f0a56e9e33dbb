// A run's identity on fogctl's side: see run_identity.hpp.
#include "run_identity.hpp"

#include <fstream>
#include <sstream>

#include "table.hpp"

namespace fogbench::cli {

using nlohmann::json;

namespace {
std::string string_field(const json& j, const char* key) {
  return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
}
}  // namespace

std::optional<storage::RunIdentity> identity_from_json(const json& j) {
  if (!j.is_object()) return std::nullopt;
  storage::RunIdentity id;
  id.station_id = string_field(j, "station_id");
  id.operator_name = string_field(j, "operator");
  id.operator_source = string_field(j, "operator_source");
  id.software_version = string_field(j, "software_version");
  id.git_hash = string_field(j, "git_hash");
  id.config_sha256 = string_field(j, "config_sha256");
  id.profile_sha256 = string_field(j, "profile_sha256");
  if (j.contains("units") && j["units"].is_array())
    for (const auto& u : j["units"]) {
      storage::UnitIdentity x;
      x.unit_index = u.value("unit", 0);
      x.serial = string_field(u, "serial");
      if (u.contains("powered_on_at") && u["powered_on_at"].is_string()) x.powered_on_at = u["powered_on_at"].get<std::string>();
      if (u.contains("since_power_on_s") && u["since_power_on_s"].is_number())
        x.since_power_on_s = u["since_power_on_s"].get<double>();
      id.units.push_back(std::move(x));
    }
  return id;
}

std::string identity_csv_comments(const json& run_get, int unit) {
  auto id = identity_from_json(run_get.value("identity", json()));
  if (!id) return {};
  const json& run = run_get["run"];
  auto fields = storage::identity_fields(*id, run.value("id", std::int64_t{0}), run.value("profile", std::string()), unit);
  // The unit's production lot (issue 24), empty when none was given.
  std::string lot;
  if (run.contains("lots") && run["lots"].is_array() && unit >= 0 && static_cast<std::size_t>(unit) < run["lots"].size() &&
      run["lots"][static_cast<std::size_t>(unit)].is_string())
    lot = run["lots"][static_cast<std::size_t>(unit)].get<std::string>();
  fields.emplace_back("lot", lot);
  // The serial's one verdict as the station decided it (issue 24), so that a report or a reader
  // of the file sees that verdict, never a second one (docs/csv.md).
  const json verdicts = run_get.value("verdicts", json::array());
  if (verdicts.is_array() && unit >= 0 && static_cast<std::size_t>(unit) < verdicts.size()) {
    const json& v = verdicts[static_cast<std::size_t>(unit)];
    if (v.is_object() && v.value("verdict", json()).is_string()) {
      fields.emplace_back("verdict", v["verdict"].get<std::string>());
      fields.emplace_back("verdict_by", verdict_by_text(v));
      fields.emplace_back("verdict_decided_at", v.value("decided_at", std::string()));
      // A three-axis unit's: each axis' verdict, the unit's above being the worst of them.
      if (v.contains("axes") && v["axes"].is_array()) {
        std::string by_axis;
        for (const auto& a : v["axes"])
          by_axis += (by_axis.empty() ? "" : ", ") + a.value("axis", std::string("?")) + " " + a.value("verdict", std::string("-"));
        fields.emplace_back("verdict_axes", by_axis);
      }
    }
  }
  return storage::identity_comment_lines(fields);
}

void print_identity(const json& identity, std::ostream& out) {
  auto id = identity_from_json(identity);
  if (!id) {
    out << "  identity: not recorded (a run from before schema 4, or imported without it)\n";
    return;
  }
  out << "  station " << (id->station_id.empty() ? "-" : id->station_id) << ", operator "
      << (id->operator_name.empty() ? "-" : id->operator_name) << " (" << id->operator_source << ")\n"
      << "  fogbench " << id->software_version << " (" << id->git_hash << ")\n"
      << "  config sha256 " << id->config_sha256 << "\n  profile sha256 " << id->profile_sha256 << "\n";
  Table t({"unit", "serial", "powered on", "since power-on at creation, s"});
  for (const auto& u : id->units)
    t.add({std::to_string(u.unit_index), u.serial, u.powered_on_at.value_or("not seen"),
           u.since_power_on_s ? fixed(*u.since_power_on_s, 0) : "-"});
  out << t.str();
}

std::string verdict_by_text(const json& v) {
  if (v.value("rule", "") == "plan" && v.contains("plan") && v["plan"].is_object())
    return "plan " + v["plan"].value("name", std::string()) + " (plan " + std::to_string(v["plan"].value("id", std::int64_t{0})) + ")";
  return "analysis settings";
}

std::vector<std::pair<std::string, std::string>> csv_file_identity(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  // The comments stand before the header row: the first 64 KiB hold them.
  std::string head(65536, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  return storage::read_comment_fields(head);
}

}  // namespace fogbench::cli
