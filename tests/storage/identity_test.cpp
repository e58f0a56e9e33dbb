// A run's identity and the certificates in the store (schema 4), the operator-name check, and
// the identity's `# key: value` comments atop a CSV read back as they were written.
#include <catch2/catch.hpp>

#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/identity.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::storage;

namespace {
Store mem() {
  auto s = Store::open(":memory:");
  REQUIRE(s.has_value());
  return std::move(*s);
}

RunIdentity sample_identity() {
  RunIdentity id;
  id.station_id = "bench-3";
  id.operator_name = "Ada Lovelace";
  id.operator_source = "client";
  id.software_version = "0.1.0";
  id.git_hash = "58b9f8ad20ce2bfcb4bae6985d95cf60120ac562";
  id.config_sha256 = std::string(64, 'a');
  id.profile_sha256 = std::string(64, 'b');
  id.units = {{0, "FOG-1", "2026-11-25T08:00:00Z", 120.0}, {1, "FOG-2", std::nullopt, std::nullopt}};
  return id;
}

model::RunData small_run() {
  model::RunData d;
  d.name = "small";
  for (int i = 0; i < 5; ++i) {
    d.time_s.push_back(i);
    d.gyro_dph.push_back(0.1 * i);
    d.t1_c.push_back(20.0);
    d.t2_c.push_back(20.5);
  }
  return d;
}
}  // namespace

TEST_CASE("identity: a run's identity is stored with the run and read back, units by index") {
  Store s = mem();
  NewRun nr;
  nr.profile_name = "exp1";
  nr.profile_text = "hold 20 for 60 s\n";
  nr.unit_serials = {"FOG-1", "FOG-2"};
  nr.identity = sample_identity();
  auto id = s.create_run(nr);
  REQUIRE(id.has_value());
  auto got = s.get_run_identity(*id);
  REQUIRE(got.has_value());
  REQUIRE(got->has_value());
  const RunIdentity& r = **got;
  CHECK(r.station_id == "bench-3");
  CHECK(r.operator_name == "Ada Lovelace");
  CHECK(r.operator_source == "client");
  CHECK(r.git_hash == nr.identity->git_hash);
  CHECK(r.config_sha256 == std::string(64, 'a'));
  REQUIRE(r.units.size() == 2);
  CHECK(r.units[0].serial == "FOG-1");
  CHECK(r.units[0].powered_on_at == "2026-11-25T08:00:00Z");
  CHECK(r.units[0].since_power_on_s == 120.0);
  CHECK(r.units[1].serial == "FOG-2");
  CHECK_FALSE(r.units[1].powered_on_at.has_value());
  CHECK_FALSE(r.units[1].since_power_on_s.has_value());

  // A run without one says so; a missing run is not_found.
  nr.identity.reset();
  auto bare = s.create_run(nr);
  REQUIRE(bare.has_value());
  CHECK_FALSE(s.get_run_identity(*bare)->has_value());
  CHECK(s.get_run_identity(999).error().code == StoreErrc::not_found);
}

TEST_CASE("identity: a bad operator name or source refuses the whole run, nothing stored") {
  Store s = mem();
  NewRun nr;
  nr.profile_name = "exp1";
  nr.unit_serials = {"FOG-1"};
  nr.identity = sample_identity();
  nr.identity->units.resize(1);
  nr.identity->operator_name = "Ada\x1b[2J";
  auto id = s.create_run(nr);
  REQUIRE_FALSE(id.has_value());
  CHECK(id.error().code == StoreErrc::invalid_argument);
  CHECK(id.error().message.find("operator") != std::string::npos);
  nr.identity->operator_name = "Ada";
  nr.identity->operator_source = "guess";
  CHECK_FALSE(s.create_run(nr).has_value());
  CHECK(s.list_runs()->empty());
}

TEST_CASE("identity: operator names: printable, at most 64 bytes, the field named in the error") {
  CHECK(check_operator_name("Ada Lovelace").empty());
  CHECK(check_operator_name("Zoë Ødegård").empty());  // UTF-8 is fine
  CHECK(check_operator_name(std::string(64, 'x')).empty());
  CHECK(check_operator_name(std::string(65, 'x')).starts_with("operator: longer than 64 bytes"));
  CHECK(check_operator_name("a\tb") == "operator: control character 0x09 at byte 2");
  CHECK(check_operator_name("ab\n") == "operator: control character 0x0A at byte 3");
  CHECK(check_operator_name("a\x7f").starts_with("operator: control character 0x7F"));
  CHECK(check_operator_name("a\xff").starts_with("operator: not valid UTF-8"));
}

TEST_CASE("identity: stored texts: quotes and backslashes are text, escapes and malformed UTF-8 are refused by byte") {
  CHECK(check_stored_text("source", "plans/\"odd\" name\\x.plan", kMaxSourceBytes).empty());
  CHECK(check_stored_text("source", "a\\q", kMaxSourceBytes).empty());  // not a JSON escape: just a backslash
  CHECK(check_stored_text("reason", "Zoë: 3 °C", kMaxReasonBytes).empty());
  CHECK(check_stored_text("source", "x\x1b]0;owned\x07", kMaxSourceBytes) == "source: control character 0x1B at byte 2");
  CHECK(check_stored_text("units[1]", std::string(65, 'F'), kMaxNameBytes) == "units[1]: longer than 64 bytes (65)");
  CHECK(check_stored_text("reason", "ab\xc0\xaf", kMaxReasonBytes) == "reason: not valid UTF-8 at byte 3");  // overlong '/'
  CHECK(check_stored_text("reason", "\xed\xa0\x80", kMaxReasonBytes) == "reason: not valid UTF-8 at byte 1");  // a surrogate
  CHECK(check_stored_text("reason", "\xe2\x82", kMaxReasonBytes) == "reason: not valid UTF-8 at byte 1");  // cut short
  CHECK(check_stored_text("reason", "\xf0\x9f\x94\xa5", kMaxReasonBytes).empty());  // four bytes, fine
}

TEST_CASE("identity: the CSV comments read back to the same identity, and the run imports with it") {
  const RunIdentity id = sample_identity();
  const auto fields = identity_fields(id, 12, "exp1", 0);
  const std::string csv = identity_comment_lines(fields) + to_csv(small_run());
  CHECK(csv.starts_with("# run: 12\n# profile: exp1\n# profile_sha256: bbbb"));
  // The data still parses: the comments are comments.
  auto data = parse_csv(csv, {});
  REQUIRE(data.has_value());
  CHECK(data->size() == 5);

  const auto back = read_comment_fields(csv);
  CHECK(back == fields);
  auto read = identity_from_fields(back);
  REQUIRE(read.has_value());
  CHECK(read->station_id == id.station_id);
  CHECK(read->operator_name == id.operator_name);
  CHECK(read->operator_source == "import");  // said where it came from now
  CHECK(read->software_version == id.software_version);
  CHECK(read->git_hash == id.git_hash);
  CHECK(read->config_sha256 == id.config_sha256);
  CHECK(read->profile_sha256 == id.profile_sha256);
  REQUIRE(read->units.size() == 1);
  CHECK(read->units[0].serial == "FOG-1");
  CHECK(read->units[0].powered_on_at == "2026-11-25T08:00:00Z");
  CHECK(read->units[0].since_power_on_s == 120.0);

  Store s = mem();
  ImportOptions o;
  o.serial = "FOG-1";
  o.identity = read;
  auto run = s.import_run(*data, o);
  REQUIRE(run.has_value());
  auto stored = s.get_run_identity(*run);
  REQUIRE(stored->has_value());
  CHECK((*stored)->station_id == "bench-3");
  CHECK((*stored)->units.at(0).since_power_on_s == 120.0);
  CHECK(s.get_run(*run)->run.units.at(0).lot == std::nullopt);  // the file had no lot line

  // A `# lot:` line is read back with the data and stored with the imported unit; an empty one
  // (no lot was given) stays no lot; a lot with a control character is refused, naming it.
  auto with_lot = fields;
  with_lot.emplace_back("lot", "L-7");
  const std::string lot_csv = identity_comment_lines(with_lot) + to_csv(small_run());
  CHECK(lot_from_fields(read_comment_fields(lot_csv)) == std::optional<std::string>("L-7"));
  CHECK(lot_from_fields({{"lot", ""}}) == std::nullopt);
  o.lot = lot_from_fields(read_comment_fields(lot_csv));
  auto lot_run = s.import_run(*data, o);
  REQUIRE(lot_run.has_value());
  CHECK(s.get_run(*lot_run)->run.units.at(0).lot == std::optional<std::string>("L-7"));
  o.lot = std::string("L") + char(0x1b) + "[2J";
  auto bad_lot = s.import_run(*data, o);
  REQUIRE_FALSE(bad_lot.has_value());
  CHECK(bad_lot.error().message.find("lot") != std::string::npos);
  // The serial and the profile's name are stored names too: a control character, or longer than
  // 64 bytes, refused naming the field; nothing stored.
  o.lot.reset();
  const auto runs_before = s.list_runs()->size();
  o.serial = std::string("FOG") + char(0x07);
  auto bad_serial = s.import_run(*data, o);
  REQUIRE_FALSE(bad_serial.has_value());
  CHECK(bad_serial.error().message.find("serial: control character 0x07") != std::string::npos);
  o.serial = "FOG-1";
  o.profile_name = std::string(65, 'p');
  auto bad_profile = s.import_run(*data, o);
  REQUIRE_FALSE(bad_profile.has_value());
  CHECK(bad_profile.error().message.find("profile_name: longer than 64 bytes") != std::string::npos);
  CHECK(s.list_runs()->size() == runs_before);

  // Comments after the header are data's business, not the identity's; a file without
  // software_version is no fogbench export.
  CHECK(read_comment_fields("time_s,gyro_dph\n# station_id: x\n").empty());
  CHECK_FALSE(identity_from_fields({{"station_id", "x"}}).has_value());
  // Other comments and CRLF are fine.
  auto crlf = read_comment_fields("# fogbench run 12, unit 0\r\n# operator: Bo\r\n\r\ntime_s\r\n");
  REQUIRE(crlf.size() == 1);
  CHECK(crlf[0] == std::pair<std::string, std::string>{"operator", "Bo"});
}

TEST_CASE("identity: certificates are kept per serial and found by their hash") {
  Store s = mem();
  NewModel m;
  m.serial = "FOG-1";
  m.model_json = "{}";
  auto ref = s.put_model(m);
  REQUIRE(ref.has_value());
  NewCertificate c{"FOG-1", ref->id, ref->version, std::string(64, 'c'), R"({"a":1})"};
  auto id = s.put_certificate(c);
  REQUIRE(id.has_value());
  auto found = s.find_certificates(std::string(64, 'c'));
  REQUIRE(found->size() == 1);
  CHECK(found->at(0).serial == "FOG-1");
  CHECK(found->at(0).json == R"({"a":1})");
  CHECK(s.find_certificates(std::string(64, 'd'))->empty());
  CHECK(s.list_certificates("FOG-1")->size() == 1);
  // Refused: another serial's model, a bad hash, bad JSON; nothing stored.
  c.serial = "FOG-2";
  CHECK(s.put_certificate(c).error().code == StoreErrc::invalid_argument);
  c.serial = "FOG-1";
  c.sha256 = "xyz";
  CHECK(s.put_certificate(c).error().code == StoreErrc::invalid_argument);
  c.sha256 = std::string(64, 'e');
  c.json = "{";
  CHECK(s.put_certificate(c).error().code == StoreErrc::invalid_argument);
  CHECK(s.list_certificates("FOG-1")->size() == 1);
}
