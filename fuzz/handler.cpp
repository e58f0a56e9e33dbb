// Fuzzes the daemon's command protocol without a socket (protocol/include/fogbench/protocol/
// framing.hpp, daemon/include/fogbench/daemon/handler.hpp; docs/protocol.md): the input is what a client sends, split into
// lines by LineSplitter and answered by a Handler over a Station with the golden transcripts'
// configuration (tests/golden/config.json: two simulated units, the golden profiles) and an
// in-memory store. As in the golden transcripts, a line `! tick N` lets N seconds of a small
// synthetic bench pass instead (at most kMaxTicks per input), so runs start, record, end and
// fit; a line `! readonly` makes the rest a read-only (TCP) connection whose token is kToken.
// Each input starts from a fresh station and store, so every finding replays alone.
//
// Lines reach the handler as the server gives them: handle_line, with the protocol's depth and
// duplicate-key checks (framing.hpp's parse_line), the same function for both. Inputs go up
// to 1 MiB (scripts/fuzz -max_len) and the dictionary has brackets and nesting, so lines nested
// past kMaxDepth are reached; fuzz/regressions/handler/ keeps issue 11's 100,000-level line.
//
// Properties: framing does not depend on how the bytes are cut into reads; every reply is a
// "reply" object carrying the request's id and either a result or an error with a documented
// code; on a read-only connection a command that changes something succeeds only with the
// token; an `internal` error is storage or analysis failing, never an exception caught from a
// bug; every reply, sample and event serialises (the server sends reply.dump(), which throws
// on invalid UTF-8).
#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <cmath>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/daemon/config.hpp"
#include "fogbench/protocol/framing.hpp"
#include "fogbench/daemon/handler.hpp"
#include "fogbench/daemon/station.hpp"
#include "fogbench/storage/store.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::protocol;
using nlohmann::json;

namespace {

// A complete run of the golden short.profile (1800 s) with time to spare: enough to reach the
// automatic fit, bounded so an input costs at most a few hundred milliseconds.
constexpr int kMaxTicks = 2400;
// A second, small limit for the framing property, so the fuzzer reaches too_long with short
// inputs; the handler gets lines as the server splits them (kMaxLineBytes).
constexpr std::size_t kSmallLineLimit = 16;

const DaemonConfig& golden_config() {
  static const DaemonConfig config = [] {
    const std::filesystem::path dir = std::filesystem::path(FOGBENCH_SOURCE_DIR) / "tests" / "golden";
    std::ifstream in(dir / "config.json");
    std::stringstream ss;
    ss << in.rdbuf();
    auto c = parse_daemon_config(json::parse(ss.str()), dir);
    FUZZ_CHECK(c.has_value(), "tests/golden/config.json: %s", c ? "" : c.error().c_str());
    return *c;
  }();
  return config;
}

// Two coils lagging a chamber that follows its setpoint at 5 degC/min; the gyro reads the
// paper's model plus a deterministic wobble. Enough for samples and fits to be ordinary.
struct Bench {
  double air_c = 20.0;
  std::vector<double> t1_c, t2_c;
  double k = 0.0;
  explicit Bench(std::size_t units) : t1_c(units, 20.0), t2_c(units, 20.0) {}
  TickInput step(double setpoint_c) {
    air_c += std::clamp(setpoint_c - air_c, -5.0 / 60.0, 5.0 / 60.0);
    TickInput in;
    in.wall_time = 1.7e9 + k;
    in.chamber_c = air_c;
    in.chamber_setpoint_c = setpoint_c;
    for (std::size_t i = 0; i < t1_c.size(); ++i) {
      const double t1_old = t1_c[i];
      t2_c[i] += (air_c - t2_c[i]) / 60.0;
      t1_c[i] += (0.5 * (t2_c[i] + air_c) - t1_c[i]) / 240.0;
      UnitReading u;
      u.gyro_dph = -8.0 - 2.7 * (t1_c[i] - t1_old) * 60.0 - 0.4 * (t1_c[i] - t2_c[i]) + 0.05 * std::sin(0.7 * k + static_cast<double>(i));
      u.frames = 100;
      u.t1_c = t1_c[i];
      u.t2_c = t2_c[i];
      in.units.push_back(u);
    }
    k += 1.0;
    return in;
  }
};

// The lines a splitter gives for `bytes` fed in reads of the given sizes (cycled), up to and
// including a too_long, which spends it. A too_long is recorded as an empty optional.
std::vector<std::optional<std::string>> split(std::string_view bytes, std::size_t limit,
                                              std::initializer_list<std::size_t> reads) {
  LineSplitter s(limit);
  std::vector<std::optional<std::string>> out;
  auto r = reads.begin();
  std::string line;
  while (true) {
    const std::size_t n = std::min(*r, bytes.size());
    s.feed(bytes.substr(0, n));
    bytes.remove_prefix(n);
    if (++r == reads.end()) r = reads.begin();
    for (;;) {
      const auto st = s.next(line);
      if (st == LineSplitter::Status::line) {
        out.emplace_back(line);
      } else if (st == LineSplitter::Status::too_long) {
        out.emplace_back();
        return out;
      } else {
        break;
      }
    }
    if (bytes.empty()) return out;
  }
}

void check_framing(std::string_view bytes, std::size_t limit) {
  const auto whole = split(bytes, limit, {bytes.size() + 1});
  const auto pieces = split(bytes, limit, {1, 3, 7, 64, 2, 501});
  FUZZ_CHECK(whole == pieces, "framing depends on the reads: %zu lines whole, %zu in pieces (limit %zu)",
             whole.size(), pieces.size(), limit);
  for (const auto& l : whole) {
    if (!l) continue;
    FUZZ_CHECK(l->size() <= limit, "a line of %zu bytes over the limit %zu", l->size(), limit);
    FUZZ_CHECK(l->find('\n') == std::string::npos, "a line holds a newline");
  }
}

std::string serialise(const json& message, const char* what) {
  try {
    return message.dump();
  } catch (const json::exception& e) {
    FUZZ_CHECK(false, "a %s does not serialise: %s", what, e.what());
  }
  return {};
}

bool documented_code(const std::string& code) {
  static const std::set<std::string> codes = {"bad_json",        "bad_request", "unknown_command",
                                              "not_found",       "busy",        "invalid_profile",
                                              "limits",          "unknown_serial", "forbidden",
                                              "internal",        "unavailable", "invalid_config"};
  return codes.contains(code);
}

// An `internal` error reports storage or analysis failing (station.cpp, handler.cpp); anything
// else is the text of an exception the handler caught, i.e. a bug.
bool expected_internal(const std::string& message) {
  for (const char* prefix : {"fit failed (", "verification failed (", "model "})
    if (message.starts_with(prefix)) return true;
  for (int c = 0; c <= static_cast<int>(storage::StoreErrc::sqlite); ++c)
    if (message.starts_with(std::string(storage::to_string(static_cast<storage::StoreErrc>(c))) + ": ")) return true;
  return false;
}

// The token of the read-only session that a `! readonly` line switches to.
constexpr const char* kToken = "fuzz-token-0123";

void check_reply(std::string_view line, const json& r, const SessionState& session) {
  serialise(r, "reply");
  FUZZ_CHECK(r.is_object() && r.value("type", "") == "reply", "not a reply: %s", r.dump().c_str());
  FUZZ_CHECK(r.contains("id"), "a reply without an id");
  FUZZ_CHECK(r.contains("result") != r.contains("error"), "a reply needs a result or an error: %s",
             r.dump().c_str());
  if (r.contains("error")) {
    const json& e = r["error"];
    FUZZ_CHECK(e.is_object() && e.contains("code") && e["code"].is_string() && e.contains("message") &&
                   e["message"].is_string(),
               "malformed error: %s", r.dump().c_str());
    const std::string code = e["code"].get<std::string>();
    FUZZ_CHECK(documented_code(code), "undocumented error code %s", code.c_str());
    if (code == "internal")
      FUZZ_CHECK(expected_internal(e["message"].get<std::string>()),
                 "an exception reached the handler: %s", e["message"].get<std::string>().c_str());
  }
  // The id of a well-formed request comes back unchanged. Parsed as the daemon parses it
  // (framing.hpp): json::parse would itself overflow the stack on a deeply nested line.
  const auto parsed = parse_line(line);
  const json req = parsed ? *parsed : json(nullptr);
  if (!parsed && !line.empty() && r.contains("error")) {
    FUZZ_CHECK(r["error"]["code"] == "bad_json" && r["id"].is_null(), "a refused parse that is not bad_json: %s",
               r.dump().c_str());
  }
  if (req.is_object() && req.contains("id") && (req["id"].is_number_integer() || req["id"].is_string()))
    FUZZ_CHECK(r["id"] == req["id"], "reply id %s for request id %s", r["id"].dump().c_str(),
               req["id"].dump().c_str());
  // On a connection that may only read, a command that changes something succeeds only with
  // the connection's token.
  if (!session.may_control && r.contains("result") && req.is_object() && req.contains("cmd") &&
      req["cmd"].is_string() && is_control_command(req["cmd"].get<std::string>()))
    FUZZ_CHECK(req.contains("token") && req["token"] == session.control_token,
               "a read-only connection ran %s without its token", req["cmd"].dump().c_str());
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)golden_config();
  serialise(Handler::hello(), "hello");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // FOGBENCH_FUZZ_PRINT=1: print each request and its reply, to see what an input reaches.
  static const bool print = std::getenv("FOGBENCH_FUZZ_PRINT") != nullptr;
  const auto bytes = fogbench::fuzz::as_text(data, size);
  check_framing(bytes, kMaxLineBytes);
  check_framing(bytes, kSmallLineLimit);

  storage::OpenOptions so;
  so.clock = [] { return std::chrono::system_clock::time_point(std::chrono::seconds(1'767'225'600)); };
  auto store = storage::Store::open(":memory:", so);
  FUZZ_CHECK(store.has_value(), "in-memory store: %s", store ? "" : store.error().message.c_str());
  Station station(golden_config(), *store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  station.set_publisher([](const json& m) { serialise(m, "published message"); });
  Handler handler(station);
  SessionState session;
  Bench bench(golden_config().drivers.units.size());
  double clock_s = 0.0, setpoint_c = 20.0;
  int ticks_left = kMaxTicks;
  (void)station.recover();

  for (const auto& line : split(bytes, kMaxLineBytes, {bytes.size() + 1})) {
    if (!line) {  // the server sends this and closes the connection
      check_reply("", Handler::too_long(), session);
      break;
    }
    if (*line == "! readonly") {  // from here on, a TCP connection's session
      session.may_control = false;
      session.control_token = kToken;
      continue;
    }
    if (line->starts_with("! tick ")) {
      int n = 0;
      std::from_chars(line->data() + 7, line->data() + line->size(), n);
      for (n = std::clamp(n, 0, ticks_left); n > 0; --n, --ticks_left)
        setpoint_c = station.tick(clock_s++, bench.step(setpoint_c)).setpoint_c;
      continue;
    }
    const json reply = handler.handle_line(*line, session);
    if (print) std::fprintf(stderr, "> %s\n< %s\n", line->c_str(), reply.dump(-1, ' ', false, json::error_handler_t::replace).c_str());
    check_reply(*line, reply, session);
  }
  station.shutdown("fuzz input ended");
  serialise(station.status(), "status");
  return 0;
}
