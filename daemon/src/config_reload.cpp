// The configuration's reload (config_reload.hpp): the table of what a changed key needs, the
// comparison of two files, and the errors placed on their line.
#include "fogbench/daemon/config_reload.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <cctype>
#include <map>

namespace fogbench::daemon {

using nlohmann::json;

namespace {

// Every key of the configuration file and what a change of it needs. A key is `applies` when
// nothing but the daemon's own state reads it later (new connections, runs started after the
// reload); it needs a restart when a device, a socket, the store or a thread was opened with it,
// or when the active run reads it second by second (its chamber checks).
constexpr ReloadRule kRules[] = {
    // The connection limits: new connections are admitted by them (the open ones stay).
    {"socket.max_clients", ReloadClass::applies, "new connections"},
    {"socket.unix_max_clients", ReloadClass::applies, "new connections"},
    {"socket.max_clients_per_address", ReloadClass::applies, "new connections"},
    {"socket.max_analyses_per_address", ReloadClass::applies, "new analysis requests"},
    {"socket.refusal_log_interval_s", ReloadClass::applies, "the next refusal"},
    // Timeouts are armed on a connection when it opens, by the web listener as well (restart).
    {"socket.first_request_timeout_s", ReloadClass::restart, "restart (armed by the listeners at start)"},
    {"socket.idle_timeout_s", ReloadClass::restart, "restart (armed by the listeners at start)"},
    {"socket.path", ReloadClass::restart, "restart (the socket is bound at start)"},
    {"socket.group", ReloadClass::restart, "restart (the socket is bound at start)"},
    {"socket.tcp_port", ReloadClass::restart, "restart (the socket is bound at start)"},
    {"socket.tcp", ReloadClass::restart, "restart (the port is bound at start, its token read then)"},
    // The analysis settings: the automatic fit or verification of runs started after the reload.
    // A run keeps the settings it started with (its verdict by one rule).
    {"analysis.terms", ReloadClass::applies, "runs started after the reload"},
    {"analysis.method", ReloadClass::applies, "runs started after the reload"},
    {"analysis.verify_threshold", ReloadClass::applies, "runs started after the reload"},
    {"analysis.verify_max_noise_factor", ReloadClass::applies, "runs started after the reload"},
    {"analysis.verify_max_fail_s", ReloadClass::applies, "runs started after the reload"},
    {"analysis.max_iterations", ReloadClass::applies, "runs started after the reload"},
    {"analysis.causal_lags", ReloadClass::applies, "runs started after the reload"},
    // The bench slots: default serials and position names for runs started after the reload; a
    // slot's gyro node id and thermistor channels are the devices' (restart).
    {"drivers.units[].serial", ReloadClass::applies, "runs started after the reload"},
    {"drivers.units[].slot", ReloadClass::applies, "runs started after the reload"},
    {"drivers", ReloadClass::restart, "restart (the devices are opened at start)"},
    {"map_dir", ReloadClass::restart, "restart (the chamber's register map is read at start)"},
    // Read by the active run each second, or by its end (the safe setpoint): a restart, so that a
    // run is judged by the checks it started with.
    {"chamber_limits", ReloadClass::restart, "restart (the active run's profile was checked against them)"},
    {"safe_setpoint_c", ReloadClass::restart, "restart (the acquisition holds it)"},
    {"link_loss", ReloadClass::restart, "restart (the active run's chamber checks)"},
    {"tracking", ReloadClass::restart, "restart (the active run's chamber checks)"},
    {"profile_dir", ReloadClass::restart, "restart (plans and queued runs name profiles in it)"},
    {"simulated", ReloadClass::restart, "restart"},
    {"sim_clock", ReloadClass::restart, "restart (the paced clock is opened at start)"},
    {"storage", ReloadClass::restart, "restart (the store is opened at start)"},
    {"signing", ReloadClass::restart, "restart (the key is loaded at start)"},
    {"station", ReloadClass::restart, "restart (the station's identity)"},
    {"web", ReloadClass::restart, "restart (the web listener is bound at start)"},
    {"plant", ReloadClass::restart, "restart (the plant connection is opened at start)"},
    {"rate_table", ReloadClass::restart, "restart (the rate table is opened at start)"},
};

// "drivers.units[2].serial" -> "drivers.units[].serial".
std::string without_indices(std::string_view path) {
  std::string out;
  for (std::size_t i = 0; i < path.size(); ++i) {
    out += path[i];
    if (path[i] == '[') {
      while (i + 1 < path.size() && path[i + 1] != ']') ++i;
    }
  }
  return out;
}

// Leaf values by path; an array also by its own path, as its length. An empty object has no
// leaves: `"analysis": {}` says what leaving the section out says.
void flatten(const json& j, const std::string& path, std::map<std::string, json>& out) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) flatten(v, path.empty() ? k : path + "." + k, out);
  } else if (j.is_array()) {
    out[path + "#length"] = j.size();
    for (std::size_t i = 0; i < j.size(); ++i) flatten(j[i], path + "[" + std::to_string(i) + "]", out);
  } else {
    out[path] = j;
  }
}

// The JSON pointer of a dotted path with indices.
json::json_pointer pointer_of(std::string_view path) {
  std::string p;
  std::string token;
  auto flush = [&] {
    if (token.empty()) return;
    std::string esc;
    for (char ch : token) esc += ch == '~' ? std::string("~0") : ch == '/' ? std::string("~1") : std::string(1, ch);
    p += "/" + esc;
    token.clear();
  };
  for (char ch : path) {
    if (ch == '.' || ch == '[') flush();
    else if (ch == ']') flush();
    else token += ch;
  }
  flush();
  return json::json_pointer(p);
}

// The key path at the start of a parser's error ("socket.tcp.port: expected ..."), if it is one.
std::optional<std::string> key_of_error(std::string_view message) {
  const auto colon = message.find(": ");
  if (colon == std::string_view::npos || colon == 0) return std::nullopt;
  const std::string_view key = message.substr(0, colon);
  for (char ch : key)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '[' || ch == ']' || ch == '-'))
      return std::nullopt;
  return std::string(key);
}

// The enclosing key of a path: "a.b[2].c" -> "a.b[2]" -> "a.b" -> "a" -> "".
std::string parent_of(std::string_view path) {
  const auto p = path.find_last_of(".[");
  return p == std::string_view::npos ? std::string() : std::string(path.substr(0, p));
}

}  // namespace

std::string_view to_string(ReloadClass c) { return c == ReloadClass::applies ? "applies" : "restart"; }

std::span<const ReloadRule> reload_rules() { return kRules; }

const ReloadRule* reload_rule_of(std::string_view path) {
  std::string key = without_indices(path);
  for (;;) {
    for (const auto& r : kRules)
      if (r.key == key) return &r;
    if (key.empty()) return nullptr;
    key = parent_of(key);
  }
}

TextPosition position_of_offset(std::string_view text, std::size_t offset) {
  TextPosition p;
  const std::size_t stop = std::min(offset, text.size());
  for (std::size_t i = 0; i < stop; ++i) {
    if (text[i] == '\n') {
      ++p.line;
      p.column = 1;
    } else {
      ++p.column;
    }
  }
  return p;
}

std::optional<std::size_t> line_of_key(std::string_view text, std::string_view path) {
  // A scanner of JSON's tokens that keeps the path of the value it is at: each open object or
  // array is a frame with its path; an object's frame knows its current member's path, an
  // array's the index of its current element.
  struct Frame {
    bool array = false;
    std::string path;
    std::size_t index = 0;   // an array: the current element
    bool expect_key = true;  // an object: the next string is a key
    std::string member;      // an object: the current member's path
  };
  std::vector<Frame> stack;
  auto value_path = [&]() -> std::string {
    if (stack.empty()) return "";
    const Frame& f = stack.back();
    return f.array ? f.path + "[" + std::to_string(f.index) + "]" : f.member;
  };
  auto in_array = [&] { return !stack.empty() && stack.back().array; };
  std::size_t line = 1;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (ch == '\n') {
      ++line;
    } else if (ch == '"') {
      const std::size_t at = line;
      std::string s;
      std::size_t j = i + 1;
      for (; j < text.size() && text[j] != '"'; ++j) {
        if (text[j] == '\\' && j + 1 < text.size()) ++j;
        if (text[j] == '\n') ++line;
        s += text[j];
      }
      i = j;
      if (!stack.empty() && !stack.back().array && stack.back().expect_key) {
        Frame& f = stack.back();
        f.member = f.path.empty() ? s : f.path + "." + s;
        f.expect_key = false;
        if (f.member == path) return at;
      } else if (in_array() && value_path() == path) {
        return at;
      }
    } else if (ch == '{' || ch == '[') {
      const std::string p = value_path();
      if (in_array() && p == path) return line;
      stack.push_back({ch == '[', p, 0, true, {}});
    } else if (ch == '}' || ch == ']') {
      if (!stack.empty()) stack.pop_back();
    } else if (ch == ',') {
      if (in_array()) ++stack.back().index;
      else if (!stack.empty()) stack.back().expect_key = true;
    } else if (!std::isspace(static_cast<unsigned char>(ch)) && ch != ':' && in_array() && value_path() == path) {
      return line;  // an array element that is a number or a literal
    }
  }
  return std::nullopt;
}

std::expected<DaemonConfig, std::string> parse_daemon_config_text(std::string_view text,
                                                                  const std::filesystem::path& base_dir) {
  json j;
  try {
    j = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    // nlohmann counts the byte it stopped at from 1.
    const auto p = position_of_offset(text, e.byte == 0 ? 0 : e.byte - 1);
    std::string what = e.what();
    if (const auto c = what.find(": "); c != std::string::npos) what = what.substr(c + 2);
    // JSON has no trailing comma, the commonest slip in a file edited by hand: a '}' or ']'
    // whose previous non-blank byte is ',' is named as one, at the comma's place.
    std::string hint;
    if (const std::size_t at = e.byte == 0 ? 0 : e.byte - 1; at < text.size() && (text[at] == '}' || text[at] == ']')) {
      std::size_t before = at;
      while (before > 0 && std::isspace(static_cast<unsigned char>(text[before - 1]))) --before;
      if (before > 0 && text[before - 1] == ',') {
        const auto comma = position_of_offset(text, before - 1);
        hint = " (a trailing comma at line " + std::to_string(comma.line) + ", column " + std::to_string(comma.column) +
               ": JSON allows none before '" + std::string(1, text[at]) + "')";
      }
    }
    return std::unexpected("line " + std::to_string(p.line) + ", column " + std::to_string(p.column) +
                           ": not valid JSON: " + what + hint);
  }
  auto c = parse_daemon_config(j, base_dir);
  if (c) return c;
  const std::string& message = c.error();
  auto key = key_of_error(message);
  if (!key) return std::unexpected(message);
  // The line of the key, or of the nearest enclosing key written in the file (a missing key).
  for (std::string k = *key; !k.empty(); k = parent_of(k)) {
    if (auto line = line_of_key(text, k)) {
      return std::unexpected(*key + " (line " + std::to_string(*line) + (k == *key ? "" : ", in " + k) + ")" +
                             message.substr(key->size()));
    }
  }
  return std::unexpected(message);
}

namespace {
// /var/lib/fogbench and the folders under it: the shipped units' StateDirectory= makes them.
bool made_by_shipped_unit(const std::filesystem::path& dir) {
  const std::filesystem::path state = "/var/lib/fogbench";
  auto d = dir.lexically_normal();
  for (; !d.empty() && d != d.root_path(); d = d.parent_path())
    if (d == state) return true;
  return false;
}
}  // namespace

std::vector<std::string> config_path_problems(const DaemonConfig& config, std::string_view text) {
  std::vector<std::string> out;
  auto where = [&](const std::string& key) {
    const auto line = line_of_key(text, key);
    return key + (line ? " (line " + std::to_string(*line) + ")" : std::string()) + ": ";
  };
  // A folder a file is created in: it must exist and be a directory, on a filesystem mounted
  // for writing (the store's journal and WAL files are created beside it: a read-only mount would
  // stop the daemon at its first write, or at an upgrade's migration).
  auto folder = [&](const std::string& key, const std::filesystem::path& file) {
    const auto dir = file.parent_path();
    std::error_code ec;
    const auto st = std::filesystem::status(dir, ec);
    if (std::filesystem::is_directory(st)) {
      struct statvfs fs {};
      if (::statvfs(dir.c_str(), &fs) == 0 && (fs.f_flag & ST_RDONLY) != 0)
        out.push_back(where(key) + dir.string() + " (the folder of " + file.filename().string() +
                      ") is on a read-only filesystem: fogbenchd cannot write there (remount it read-write, or "
                      "name a folder on a writable one)");
      return;
    }
    if (std::filesystem::exists(st)) {
      out.push_back(where(key) + dir.string() + " (the folder of " + file.filename().string() + ") is not a directory");
    } else if (!made_by_shipped_unit(dir)) {
      out.push_back(where(key) + dir.string() + " (the folder of " + file.filename().string() +
                    "): no such directory (fogbenchd does not create it)");
    }
  };
  if (config.storage_path != ":memory:") {
    folder("storage.path", config.storage_path);
    std::error_code ec;
    if (std::filesystem::is_directory(config.storage_path, ec))
      out.push_back(where("storage.path") + config.storage_path.string() + " is a directory, not the store's file");
  }
  // Only a key the file names: the default beside the store is the store's folder, checked above.
  if (!config.signing_key_path.empty() && line_of_key(text, "signing.key_path"))
    folder("signing.key_path", config.signing_key_path);
  if (!config.profile_dir.empty()) {
    std::error_code ec;
    const auto st = std::filesystem::status(config.profile_dir, ec);
    if (!std::filesystem::exists(st))
      out.push_back(where("profile_dir") + config.profile_dir.string() + ": no such directory");
    else if (!std::filesystem::is_directory(st))
      out.push_back(where("profile_dir") + config.profile_dir.string() + " is not a directory");
  }
  return out;
}

std::vector<std::string> changed_keys(const json& before, const json& after) {
  std::map<std::string, json> a, b;
  flatten(before, "", a);
  flatten(after, "", b);
  std::vector<std::string> out;
  auto add = [&](const std::string& k) {
    const auto hash = k.find('#');
    out.push_back(hash == std::string::npos ? k : k.substr(0, hash));
  };
  for (const auto& [k, v] : a) {
    auto it = b.find(k);
    if (it == b.end() || it->second != v) add(k);
  }
  for (const auto& [k, v] : b)
    if (!a.contains(k)) add(k);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

json ReloadOutcome::report() const {
  json needs = json::array();
  for (const auto& k : restart) {
    const auto* r = reload_rule_of(k);
    needs.push_back({{"key", k}, {"why", r ? std::string(r->when) : std::string("restart (not classified)")}});
  }
  json done = json::array();
  for (const auto& k : applied) {
    const auto* r = reload_rule_of(k);
    done.push_back({{"key", k}, {"from", r ? std::string(r->when) : std::string()}});
  }
  return {{"changed", !applied.empty() || !restart.empty()}, {"applied", done}, {"needs_restart", needs}};
}

std::string ReloadOutcome::log_line() const {
  auto list = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& k : v) s += (s.empty() ? "" : " ") + k;
    return s;
  };
  if (applied.empty() && restart.empty()) return "configuration reloaded: nothing changed";
  std::string s = "configuration reloaded: applied: " + (applied.empty() ? std::string("(none)") : list(applied));
  if (!restart.empty()) s += "; needs a restart (old value kept): " + list(restart);
  return s;
}

std::expected<ReloadOutcome, std::string> plan_reload(const DaemonConfig& current, std::string_view new_text,
                                                      const std::filesystem::path& base_dir) {
  auto next = parse_daemon_config_text(new_text, base_dir);
  if (!next) return std::unexpected(next.error());
  ReloadOutcome out;
  // A key whose array element is new or gone (a slot added) is the array's change: restart.
  std::vector<std::string> arrays_changed;
  const auto changed = changed_keys(current.file_json, next->file_json);
  for (const auto& k : changed) {
    const auto* r = reload_rule_of(k);
    if (!r || r->cls == ReloadClass::restart) out.restart.push_back(k);
  }
  for (const auto& k : changed) {
    const auto* r = reload_rule_of(k);
    if (!r || r->cls == ReloadClass::restart) continue;
    // Under an array whose length changed: the elements do not match up, so not applied.
    bool under_restart = false;
    for (const auto& x : out.restart) under_restart = under_restart || (k.starts_with(x) && k.size() > x.size() && k[x.size()] == '[');
    if (under_restart) out.restart.push_back(k);
    else out.applied.push_back(k);
  }
  std::sort(out.restart.begin(), out.restart.end());
  // The configuration in force: the old file with the applied keys of the new one.
  json merged = current.file_json;
  for (const auto& k : out.applied) {
    const auto ptr = pointer_of(k);
    if (next->file_json.contains(ptr)) merged[ptr] = next->file_json[ptr];
    else if (merged.contains(ptr)) {
      const auto parent = ptr.parent_pointer();
      merged[parent].erase(ptr.back());
    }
  }
  auto in_force = parse_daemon_config(merged, base_dir);
  // The keys applied together may not stand with the old ones (a default serial now in two
  // slots): nothing is applied, and the error says so.
  if (!in_force) return std::unexpected("the changes that apply without a restart do not stand with the old values of the others: " +
                                        in_force.error() + " (nothing changed)");
  out.config = std::move(*in_force);
  return out;
}

}  // namespace fogbench::daemon
