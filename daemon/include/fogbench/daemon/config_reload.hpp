// Reloading fogbenchd's configuration (SIGHUP, `systemctl reload`, config.reload): the file the
// daemon was started with is read again and parsed by the same parser as at start; what may
// change without touching an active run is applied, every other changed key is named as needing
// a restart and keeps its old value. A file that does not parse changes nothing, and the error
// names the key and its line. Pure (no I/O but reading the file): the server applies the result
// (docs/daemon.md, "Reloading the configuration").
#pragma once

#include <cstddef>
#include <expected>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/daemon/config.hpp"

namespace fogbench::daemon {

// Where a byte of a text is, as an editor counts: line and column from 1.
struct TextPosition {
  std::size_t line = 1;
  std::size_t column = 1;
};
// The position of the byte at `offset` (clamped to the text's end).
TextPosition position_of_offset(std::string_view text, std::size_t offset);

// The line (from 1) on which the key `path` of a JSON text is written: "socket.max_clients",
// "drivers.units[1].serial" (an array element's line is that of its first byte). nullopt when the
// text does not hold it; a text that is not whole JSON is scanned as far as it goes.
std::optional<std::size_t> line_of_key(std::string_view text, std::string_view path);

// The configuration file's text parsed as at start (parse_daemon_config), its errors with the
// place: "line 12, column 3: not valid JSON: ..." for a syntax error, "socket.max_clients (line
// 9): expected an integer 1..100000" for a bad key (the line of the key, or of the nearest
// enclosing key the text has, for a missing one).
std::expected<DaemonConfig, std::string> parse_daemon_config_text(std::string_view text,
                                                                  const std::filesystem::path& base_dir);

// The paths of a parsed configuration checked on this machine, as `fogbenchd --check-config`
// does (issue 28): storage.path's folder and signing.key_path's folder must be directories that
// exist (the daemon does not create them: a typo would start an empty store elsewhere), and
// profile_dir a directory. A folder the shipped units' StateDirectory= makes at start
// (/var/lib/fogbench and below) is not required yet. Each problem names the key, its line in
// `text` and the path: "storage.path (line 4): /srv/x: no such directory". Empty: all good.
std::vector<std::string> config_path_problems(const DaemonConfig& config, std::string_view text);

// What a changed key needs: applied at once, or a restart of the daemon.
enum class ReloadClass { applies, restart };
std::string_view to_string(ReloadClass c);

// One row of the table of every configuration key: a key path (arrays' elements as "[]"), its
// class, and when it takes effect (docs). A row covers the keys under it too unless a longer row
// says otherwise ("drivers" restart, "drivers.units[].serial" applies).
struct ReloadRule {
  std::string_view key;
  ReloadClass cls;
  std::string_view when;
};
// The one table (config_reload.cpp), in the order of docs/daemon.md.
std::span<const ReloadRule> reload_rules();
// The rule of a key path ("drivers.units[2].serial" -> "drivers.units[].serial"); nullptr when
// no row covers it (a key nobody classified: treated as needing a restart).
const ReloadRule* reload_rule_of(std::string_view path);

// The keys whose value differs between two configuration files (as read: before any
// redaction), as paths with indices: "socket.max_clients", "drivers.units[0].serial"; an array
// whose length changed is named itself ("drivers.units"). Sorted, each once.
std::vector<std::string> changed_keys(const nlohmann::json& before, const nlohmann::json& after);

struct ReloadOutcome {
  DaemonConfig config;                 // what is in force after the reload
  std::vector<std::string> applied;    // changed keys now in force
  std::vector<std::string> restart;    // changed keys that keep their old value until a restart
  nlohmann::json report() const;       // {"applied": [...], "needs_restart": [...], "changed": bool}
  std::string log_line() const;        // one line for the log
};

// The reload of `current` from the configuration file's new text: the new file parsed whole
// (an error keeps everything, as parse_daemon_config_text says it), then the changed keys split
// by the table, and the configuration in force rebuilt from the old file with the applied keys
// taken from the new one and parsed again. `current.file_json` is what the daemon read last.
std::expected<ReloadOutcome, std::string> plan_reload(const DaemonConfig& current, std::string_view new_text,
                                                      const std::filesystem::path& base_dir);

}  // namespace fogbench::daemon
