// fogbenchd's PlantLink thread (daemon/src/plant_link.hpp) against a real PostgreSQL started by
// the test: completed runs recorded before the plant was configured are queued at start and
// sent; with the server down they wait in the outbox with the error; once it is back they are
// sent, each once. Exits 77 (SKIPPED) where the server's binaries are missing.
#include "fixture.hpp"

#include <chrono>
#include <thread>

#include "../../daemon/src/plant_link.hpp"
#include "../plant/pg_server.hpp"
#include "fogbench/storage/outbox.hpp"

using namespace fogbench;
using namespace fogbench::daemon;

namespace {
std::int64_t completed_run(storage::Store& s, int samples) {
  storage::NewRun nr;
  nr.profile_name = "p";
  nr.unit_serials = {"FOG-0001"};
  nr.unit_lots = {std::string("L-1")};
  auto id = s.create_run(nr);
  REQUIRE(id);
  REQUIRE(s.set_run_state(*id, storage::RunState::running, "go"));
  std::vector<storage::SampleRow> rows;
  for (int i = 0; i < samples; ++i) {
    storage::SampleRow r;
    r.t_s = i;
    r.gyro_dph = 0.1 * i;
    rows.push_back(r);
  }
  REQUIRE(s.append_samples(*id, rows));
  REQUIRE(s.set_run_state(*id, storage::RunState::completed, "done"));
  return *id;
}
// Polls the store's outbox until `pred` holds or 120 s pass (generous: a loaded CI host).
template <class Pred>
bool wait_for(storage::Store& s, Pred pred) {
  for (int i = 0; i < 1200; ++i) {
    auto st = s.outbox_status();
    REQUIRE(st);
    if (pred(*st)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}
}  // namespace

TEST_CASE("plant link: the history is queued and sent, an outage keeps the runs waiting, and they catch up once") {
  fogbench::test::PgServer pg;
  const auto path = std::filesystem::temp_directory_path() / ("fogbench-plant-link-" + std::to_string(::getpid()) + ".db");
  std::filesystem::remove(path);
  auto opened = storage::Store::open(path);
  REQUIRE(opened);
  storage::Store& store = *opened;
  const auto a = completed_run(store, 500);
  PlantConfig cfg;
  cfg.conninfo = pg.conninfo();
  cfg.bench_id = "bench-link";
  cfg.poll_s = 0.05;
  cfg.retry_max_s = 0.2;
  {
    PlantLink link(cfg, path);
    REQUIRE(wait_for(store, [](const storage::OutboxStatus& s) { return s.sent == 1 && s.depth == 0; }));
    pg.kill_immediate();
    const auto b = completed_run(store, 700);
    REQUIRE(store.enqueue_replication(b));
    REQUIRE(wait_for(store, [](const storage::OutboxStatus& s) { return s.attempts >= 2 && !s.last_error.empty(); }));
    CHECK(store.outbox_status()->depth == 1);
    pg.start();
    REQUIRE(wait_for(store, [](const storage::OutboxStatus& s) { return s.depth == 0 && s.sent == 2; }));
    link.stop();
  }
  CHECK(pg.psql("SELECT count(*) FROM fogbench.samples WHERE bench_id = 'bench-link'") == "1200");
  CHECK(pg.psql("SELECT string_agg(run_id::text, ',' ORDER BY run_id) FROM fogbench.runs") == std::to_string(a) + "," + std::to_string(a + 1));
  CHECK(pg.psql("SELECT count(DISTINCT lot) FROM fogbench.units WHERE lot = 'L-1'") == "1");
  std::filesystem::remove(path);
  std::filesystem::remove(path.string() + "-wal");
  std::filesystem::remove(path.string() + "-shm");
}
