// A run's identity (issue 13): where, by whom and with what it was recorded, and a
// certificate's stored record. Plain values; the Store keeps them in the tables run_identity,
// run_unit_identity and certificates (docs/storage.md), and the CSV export writes the identity
// as `# key: value` comment lines that the importer reads back (docs/csv.md).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fogbench::storage {

// Where the operator's name came from.
//   client: the request's `operator` field (fogctl run start --operator NAME)
//   peer:   the user of the unix socket's peer credentials (SO_PEERCRED), when the client gave none
//   import: read back from a CSV file's comments
//   none:   nobody known (a TCP client without --operator)
std::string_view operator_source_name(std::string_view s);  // the value itself when valid, else ""

struct UnitIdentity {
  int unit_index = 0;
  std::string serial;
  // When the daemon saw this unit's gyro power on, ISO 8601 UTC (wall clock at the start of
  // the period its first frames came in); empty when it did not see it (the gyro was on before
  // the daemon started). since_power_on_s is the same at the run's creation, daemon seconds.
  std::optional<std::string> powered_on_at;
  std::optional<double> since_power_on_s;
};

struct RunIdentity {
  std::string station_id;          // the daemon's station.id ("" when not configured)
  std::string operator_name;       // "" when nobody is known
  std::string operator_source = "none";
  std::string software_version;    // fogbench's version, e.g. "0.1.0"
  std::string git_hash;            // the commit it was built from, or "unknown"
  std::string config_sha256;       // SHA-256 of the run's config_json (canonical JSON, as stored)
  std::string profile_sha256;      // SHA-256 of the run's profile_text, bytes as stored
  std::vector<UnitIdentity> units; // by unit_index
};

// Operators' names: at most this many bytes, no control characters (U+0000..U+001F, U+007F).
inline constexpr std::size_t kMaxOperatorBytes = 64;
// Why `name` is no valid operator name ("" when it is one): the message names the field.
std::string check_operator_name(std::string_view name);

// The bounds of the other free texts a client hands in and the store keeps (issue 27): a serial,
// a profile's or plan's name, where a plan came from (`source`), an abort's reason.
inline constexpr std::size_t kMaxNameBytes = 64;     // serials, profile and plan names
inline constexpr std::size_t kMaxSourceBytes = 256;  // a plan's `source` (a path as the client gave it)
inline constexpr std::size_t kMaxReasonBytes = 500;  // an abort's reason as the operator typed it
// Why `value` is no storable text for `field` ("" when it is one): at most `max_bytes` bytes,
// valid UTF-8, no control characters (U+0000..U+001F, U+007F: a terminal escape sequence
// printed by `fogctl queue list` would act on the reader's terminal). The message names the
// field, the byte and the code.
std::string check_stored_text(std::string_view field, std::string_view value, std::size_t max_bytes);

// The identity as `key: value` pairs, in the order the CSV export writes them (docs/csv.md):
// run, profile, profile_sha256, station_id, operator, operator_source, software_version,
// git_hash, config_sha256, serial, powered_on_at, since_power_on_s (the unit's, of unit_index).
std::vector<std::pair<std::string, std::string>> identity_fields(const RunIdentity& id, std::int64_t run_id,
                                                                 std::string_view profile_name, int unit_index);
// The CSV's header comment: one `# key: value` line per field.
std::string identity_comment_lines(const std::vector<std::pair<std::string, std::string>>& fields);
// The `# key: value` comment lines before a CSV's header row, in file order (other comments are
// skipped; a key is a word of [a-z0-9_]). What the importer reads back.
std::vector<std::pair<std::string, std::string>> read_comment_fields(std::string_view csv_text);
// An identity from such fields (one unit, index 0): operator_source becomes "import" when an
// operator is named. Empty when the fields hold no software_version (not a fogbench export).
std::optional<RunIdentity> identity_from_fields(const std::vector<std::pair<std::string, std::string>>& fields);
// The unit's lot from such fields (`# lot: L-7`), for ImportOptions::lot: empty when the file
// has no lot line or an empty one (`# lot:`, none was given). Not part of the identity.
std::optional<std::string> lot_from_fields(const std::vector<std::pair<std::string, std::string>>& fields);

// A certificate as the store keeps it (docs/storage.md "certificates").
struct CertificateRecord {
  std::int64_t id = 0;
  std::string serial;
  std::int64_t model_id = 0;
  int model_version = 0;
  std::string sha256;  // of the canonical JSON without its sha256 field
  std::string json;    // the canonical JSON, hash field included
  std::string created_at;
};

struct NewCertificate {
  std::string serial;
  std::int64_t model_id = 0;
  int model_version = 0;
  std::string sha256;
  std::string json;
};

}  // namespace fogbench::storage
