// fogctl store prune (issue 28, retention) through the built fogctl, as an admin meets it: the
// table and JSON, the runs kept and why, a dry run, a bad date and a mistyped store path; and
// fogctl store vacuum, refused while the store's lock is held.
#include <unistd.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "fogbench/storage/lock.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "fogctl_process.hpp"

namespace fs = std::filesystem;
using Catch::Contains;
using namespace fogbench::storage;
using namespace fogbench::cli::testing;

namespace {

// Two runs ended on 2026-01-01: run 1 sent to the plant store, run 2 never sent; 50 samples each.
void make_store(const std::string& path) {
  OpenOptions o;
  o.clock = [] { return std::chrono::system_clock::time_point(std::chrono::seconds(1767225600)); };
  auto s = Store::open(path, o);
  REQUIRE(s);
  for (int r = 0; r < 2; ++r) {
    NewRun nr;
    nr.profile_name = "exp1";
    nr.unit_serials = {"FOG-00" + std::to_string(r + 1)};
    const auto id = s->create_run(nr).value();
    REQUIRE(s->set_run_state(id, RunState::running, "start"));
    std::vector<SampleRow> rows(50);
    for (int i = 0; i < 50; ++i) {
      rows[static_cast<std::size_t>(i)].unit_index = 0;
      rows[static_cast<std::size_t>(i)].t_s = i;
      rows[static_cast<std::size_t>(i)].gyro_dph = 0.1;
    }
    REQUIRE(s->append_samples(id, rows));
    REQUIRE(s->set_run_state(id, RunState::completed, "done"));
    if (r == 0) REQUIRE(s->mark_replicated(s->enqueue_replication(id).value()));
  }
}

std::int64_t samples_of(const std::string& path, std::int64_t run) {
  auto s = Store::open(path);
  REQUIRE(s);
  return s->count_samples(run).value();
}

}  // namespace

TEST_CASE("fogctl store prune: the plant's runs lose their samples, the others are listed with why",
          "[cli][store]") {
  Dir d("fogctl-prune");
  const auto db = d.file("fogbench.db");
  make_store(db);

  auto dry = fogctl(d, "store prune --store '" + db + "' --before 2026-02-01 --dry-run");
  INFO(dry.err);
  REQUIRE(dry.code == 0);
  CHECK_THAT(dry.out, Contains("dry run: nothing changed; 1 run, 50 samples would delete"));
  CHECK(samples_of(db, 1) == 50);
  // On a 60-column terminal every line fits, the summary's sentence wrapped at spaces, the run
  // kept and why still said.
  auto narrow = fogctl(d, "store prune --store '" + db + "' --before 2026-02-01 --dry-run", "COLUMNS=60");
  INFO(narrow.out);
  REQUIRE(narrow.code == 0);
  std::istringstream lines(narrow.out);
  std::string joined;
  for (std::string line; std::getline(lines, line);) {
    CHECK(line.size() <= 60);
    joined += line + " ";
  }
  CHECK_THAT(joined, Contains("50 samples would delete;") && Contains("certificates kept") && Contains("never sent"));
  CHECK(samples_of(db, 1) == 50);

  auto r = fogctl(d, "store prune --store '" + db + "' --before 2026-02-01");
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK_THAT(r.out, Contains("FOG-001"));
  CHECK_THAT(r.out, Contains("never sent to the plant store"));
  CHECK_THAT(r.out, Contains("1 run, 50 samples deleted"));
  CHECK(samples_of(db, 1) == 0);
  CHECK(samples_of(db, 2) == 50);

  auto j = fogctl(d, "store prune --store '" + db + "' --before 2026-02-01 --include-unreplicated --json");
  REQUIRE(j.code == 0);
  const auto doc = nlohmann::json::parse(j.out);
  REQUIRE(doc["pruned"].size() == 1);
  CHECK(doc["pruned"][0]["run_id"] == 2);
  CHECK(doc["pruned"][0]["samples"] == 50);
  CHECK(doc["pruned"][0]["plant_sent_at"].is_null());
  CHECK(doc["before"] == "2026-02-01T00:00:00.000Z");
  CHECK(samples_of(db, 2) == 0);
}

TEST_CASE("fogctl store prune: a bad date or a store path that is not a file is exit 2, nothing made or touched",
          "[cli][store]") {
  Dir d("fogctl-prune");
  const auto db = d.file("fogbench.db");
  make_store(db);
  auto bad = fogctl(d, "store prune --store '" + db + "' --before 2026-13-01");
  CHECK(bad.code == 2);
  CHECK_THAT(bad.err, Contains("month 13 is not 1..12"));
  CHECK(samples_of(db, 1) == 50);

  const auto typo = d.file("fogbnech.db");
  auto missing = fogctl(d, "store prune --store '" + typo + "' --before 2026-02-01");
  CHECK(missing.code == 2);
  CHECK_THAT(missing.err, Contains("no such store file"));
  CHECK_FALSE(fs::exists(typo));

  auto no_date = fogctl(d, "store prune --store '" + db + "'");
  CHECK(no_date.code == 2);
  CHECK_THAT(no_date.err, Contains("--before"));
}

TEST_CASE("fogctl store vacuum: refused while another process holds the store, then gives the pruned space back",
          "[cli][store]") {
  Dir d("fogctl-vacuum");
  const auto db = d.file("fogbench.db");
  make_store(db);
  {
    // More rows than make_store's, so that the space given back is measurable.
    auto s = Store::open(db);
    REQUIRE(s);
    std::vector<SampleRow> rows(20000);
    for (int i = 0; i < 20000; ++i) {
      rows[static_cast<std::size_t>(i)].unit_index = 0;
      rows[static_cast<std::size_t>(i)].t_s = 1000 + i;
      rows[static_cast<std::size_t>(i)].gyro_dph = 0.1;
    }
    REQUIRE(s->append_samples(1, rows));
  }
  REQUIRE(fogctl(d, "store prune --store '" + db + "' --before 2026-02-01").code == 0);
  const auto size_pruned = fs::file_size(db);
  {
    // What a running fogbenchd holds (daemon/instance.hpp uses this lock).
    auto lock = StoreLock::acquire(db);
    REQUIRE(lock);
    auto held = fogctl(d, "store vacuum --store '" + db + "'");
    CHECK(held.code == 2);
    CHECK_THAT(held.err, Contains("the store is in use by"));
    CHECK_THAT(held.err, Contains("pid " + std::to_string(::getpid())));
    CHECK_THAT(held.err, Contains("stop fogbenchd first"));
    CHECK(fs::file_size(db) == size_pruned);
  }
  auto v = fogctl(d, "store vacuum --store '" + db + "' --json");
  INFO(v.err);
  REQUIRE(v.code == 0);
  const auto doc = nlohmann::json::parse(v.out);
  CHECK(doc["bytes_after"].get<std::int64_t>() < doc["bytes_before"].get<std::int64_t>());
  CHECK(fs::file_size(db) < size_pruned);
  CHECK(samples_of(db, 2) == 50);  // the run kept by the prune reads as before

  auto table = fogctl(d, "store vacuum --store '" + db + "'");
  REQUIRE(table.code == 0);
  CHECK_THAT(table.out, Contains("given back to the filesystem"));

  const auto typo = d.file("fogbnech.db");
  auto missing = fogctl(d, "store vacuum --store '" + typo + "'");
  CHECK(missing.code == 2);
  CHECK_THAT(missing.err, Contains("no such store file"));
  CHECK_FALSE(fs::exists(typo));
}
