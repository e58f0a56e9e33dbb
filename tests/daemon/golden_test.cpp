// Replays the golden transcripts in tests/golden/*.jsonl through the handler. A transcript is
// lines of
//   > request          sent to the handler
//   < expected reply   compared as JSON, with volatile fields masked as "*"
//   ! tick N           N seconds of the synthetic bench pass
//   # comment
// FOGBENCH_UPDATE_GOLDEN=1 rewrites the expected lines from the actual replies; a change to a
// transcript is explained in its commit.
#include "fixture.hpp"

#include <cstdlib>
#include <set>

#include "fogbench/daemon/handler.hpp"

using namespace fogbench;
using namespace fogbench::daemon;
using namespace fogbench::daemon::test;
using nlohmann::json;

namespace {

// Times of day, the daemon version and the commit it was built from (run identity) change from
// one replay to the next.
void mask(json& j) {
  static const std::set<std::string> volatile_keys = {"created_at", "at", "started_at", "ended_at",
                                                      "wall_time", "version", "software_version", "git_hash"};
  if (j.is_object()) {
    for (auto& [k, v] : j.items()) {
      if (volatile_keys.contains(k) && !v.is_null()) v = "*";
      else mask(v);
    }
  } else if (j.is_array()) {
    for (auto& v : j) mask(v);
  }
}

void replay(const std::filesystem::path& file) {
  std::ifstream in(file);
  REQUIRE(in);
  const bool update = std::getenv("FOGBENCH_UPDATE_GOLDEN") != nullptr;
  auto store = memory_store();
  Station station(golden_config(), store, 1.0, [] { return std::string("2026-01-01T00:00:00Z"); });
  Handler handler(station);
  SessionState session;
  SyntheticBench bench(2);
  double clock_s = 0.0, sp = 20.0;

  std::vector<std::string> out;
  std::optional<json> last_reply;
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    INFO(file.filename().string() << ":" << lineno << ": " << line);
    if (line.starts_with("> ")) {
      json r = handler.handle_line(line.substr(2), session);
      mask(r);
      last_reply = r;
      out.push_back(line);
      if (update) out.push_back("< " + r.dump());
    } else if (line.starts_with("< ")) {
      REQUIRE(last_reply.has_value());
      if (!update) CHECK(last_reply->dump() == json::parse(line.substr(2)).dump());
      last_reply.reset();
    } else if (line.starts_with("! tick ")) {
      const int n = std::stoi(line.substr(7));
      for (int i = 0; i < n; ++i) sp = station.tick(clock_s++, bench.step(sp)).setpoint_c;
      out.push_back(line);
    } else {
      out.push_back(line);
    }
  }
  if (update) {
    std::ofstream o(file);
    for (const auto& l : out) o << l << "\n";
  }
}

}  // namespace

TEST_CASE("golden: protocol transcripts replay through the handler") {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(golden_dir()))
    if (e.path().extension() == ".jsonl") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  REQUIRE(!files.empty());
  for (const auto& f : files) {
    SECTION(f.filename().string()) { replay(f); }
  }
}
