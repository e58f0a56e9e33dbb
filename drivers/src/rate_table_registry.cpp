// The rate table's configuration, events and the table of kinds: the one place a configuration's
// "kind" becomes a rate-table driver.
#include "fogbench/drivers/rate_table_registry.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <ctime>

#include "fogbench/drivers/acutrol_dialect.hpp"
#include "fogbench/drivers/acutrol_rate_table.hpp"
#include "json_fields.hpp"

namespace fogbench::drivers {

namespace {

const std::array<RateTableKind, 1> kinds{{
    {"acutrol", "Acutronic ACUTROL (ACS2000 / ACUTROL3000) ASCII command set over TCP", acutrol::default_tcp_port,
     [](const RateTableConfig& c, RateTable::WallClock wall, RateTable::MonotonicClock clock) -> std::unique_ptr<RateTable> {
       return std::make_unique<AcutrolRateTable>(c, std::move(wall), std::move(clock));
     }},
}};

}  // namespace

std::string_view to_string(RateTableMode mode) noexcept {
  switch (mode) {
    case RateTableMode::off: return "off";
    case RateTableMode::rate: return "rate";
    case RateTableMode::position: return "position";
  }
  return "?";
}

std::string_view to_string(RateTableEvent::Kind kind) noexcept {
  switch (kind) {
    case RateTableEvent::Kind::refused: return "refused";
    case RateTableEvent::Kind::link_lost: return "link_lost";
    case RateTableEvent::Kind::link_restored: return "link_restored";
    case RateTableEvent::Kind::fault: return "fault";
    case RateTableEvent::Kind::fault_cleared: return "fault_cleared";
  }
  return "?";
}

std::string RateTableEvent::to_string() const {
  using namespace std::chrono;
  const auto ms = duration_cast<milliseconds>(time.time_since_epoch()).count();
  const std::time_t secs = static_cast<std::time_t>(ms >= 0 ? ms / 1000 : (ms - 999) / 1000);
  std::tm tm{};
  ::gmtime_r(&secs, &tm);
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  char frac[8];
  std::snprintf(frac, sizeof frac, ".%03dZ", static_cast<int>(((ms % 1000) + 1000) % 1000));
  return std::string(buf) + frac + " " + device + ": " + std::string(drivers::to_string(kind)) + ": " + reason;
}

std::span<const RateTableKind> rate_table_kinds() noexcept { return kinds; }

const RateTableKind* find_rate_table_kind(std::string_view name) noexcept {
  for (const auto& k : kinds) {
    if (k.name == name) return &k;
  }
  return nullptr;
}

std::string known_rate_table_kinds() {
  std::string out;
  for (const auto& k : kinds) {
    if (!out.empty()) out += ", ";
    out += k.name;
  }
  return out;
}

Result<RateTableConfig> parse_rate_table_config(const nlohmann::json& value, const std::string& path) {
  namespace d = detail;
  if (auto ok = d::expect_object(value, path); !ok) return std::unexpected(ok.error());
  if (auto ok = d::expect_known_keys(value, path, {"kind", "name", "link", "axis", "max_rate_dps", "max_accel_dps2"});
      !ok) {
    return std::unexpected(ok.error());
  }
  RateTableConfig out;
  auto kind = d::get_string_or(value, path, "kind", out.kind);
  if (!kind) return std::unexpected(kind.error());
  const RateTableKind* k = find_rate_table_kind(*kind);
  if (k == nullptr) {
    return d::config_error(d::join_path(path, "kind"),
                           "unknown rate table kind '" + *kind + "' (known: " + known_rate_table_kinds() + ")");
  }
  out.kind = *kind;
  auto name = d::get_string_or(value, path, "name", out.name);
  if (!name) return std::unexpected(name.error());
  if (name->empty()) return d::config_error(d::join_path(path, "name"), "empty (expected a device name)");
  out.name = *name;
  const auto lp = d::join_path(path, "link");
  if (!value.contains("link")) return d::config_error(lp, "missing (expected an object)");
  auto line = parse_line_endpoint(value["link"], lp, k->default_tcp_port, false);
  if (!line) return std::unexpected(line.error());
  out.line = *line;
  auto axis = d::get_int_or(value, path, "axis", 1, 8, 1);
  if (!axis) return std::unexpected(axis.error());
  out.axis = static_cast<int>(*axis);
  auto positive = [&](std::string_view key, double fallback, double max) -> Result<double> {
    auto v = d::get_number_or(value, path, key, fallback);
    if (!v) return v;
    if (!(*v > 0 && *v <= max)) {
      return d::config_error(d::join_path(path, key), "expected a number above 0 and at most " + format_number(max) +
                                                          " (got " + format_number(*v) + ")");
    }
    return v;
  };
  auto rate = positive("max_rate_dps", out.limits.max_rate_dps, 100000.0);
  if (!rate) return std::unexpected(rate.error());
  out.limits.max_rate_dps = *rate;
  auto accel = positive("max_accel_dps2", out.limits.max_accel_dps2, 100000.0);
  if (!accel) return std::unexpected(accel.error());
  out.limits.max_accel_dps2 = *accel;
  return out;
}

Result<std::unique_ptr<RateTable>> open_rate_table(const RateTableConfig& config, RateTable::WallClock wall,
                                                   RateTable::MonotonicClock clock) {
  const RateTableKind* kind = find_rate_table_kind(config.kind);
  if (kind == nullptr) {
    return fail(ErrorCode::config, "rate_table.kind: unknown rate table kind '" + config.kind + "' (known: " +
                                       known_rate_table_kinds() + ")");
  }
  return kind->open(config, std::move(wall), std::move(clock));
}

}  // namespace fogbench::drivers
