// Tests of the store when things go wrong: runs a crash left behind, a broken reference, a
// read-only file, a full disk, the size limit, and a reader beside the writer (WAL). Every
// failure is an error value and loses nothing already stored.
#include <catch2/catch.hpp>

#include <sqlite3.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fogbench/storage/csv.hpp"
#include "fogbench/storage/errors.hpp"
#include "fogbench/storage/models.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "store_fixture.hpp"

using namespace fogbench;
using namespace fogbench::storage;
using Catch::Matchers::Contains;

using namespace fogbench::storage::testing;

TEST_CASE("store: runs left settling or running by a crash are marked interrupted",
          "[store][runs]") {
  TempDir tmp;
  const auto path = tmp / "crash.db";
  std::int64_t pending, settling, running, completed;
  {
    Store s = open_ok(path);
    pending = s.create_run(two_unit_run()).value();
    settling = s.create_run(two_unit_run()).value();
    running = s.create_run(two_unit_run()).value();
    completed = s.create_run(two_unit_run()).value();
    REQUIRE(s.set_run_state(settling, RunState::settling, "start").has_value());
    REQUIRE(s.set_run_state(running, RunState::running, "start").has_value());
    REQUIRE(s.set_run_state(completed, RunState::completed, "done").has_value());
    const SampleRow rows[] = {sample(0, 10), sample(0, 11), sample(1, 12)};
    REQUIRE(s.append_samples(running, rows).has_value());
    // The Store goes away without any state change, as in a crash.
  }
  Store s = open_ok(path);
  auto marked = s.mark_interrupted_runs("daemon restarted after a crash");
  REQUIRE(marked.has_value());
  CHECK(*marked == std::vector<std::int64_t>{settling, running});

  auto r = s.get_run(running).value();
  CHECK(r.run.state == RunState::interrupted);
  CHECK(r.run.state_reason == "daemon restarted after a crash");
  CHECK(r.run.ended_at.has_value());
  CHECK(r.events.back().kind == EventKind::state);
  CHECK(r.events.back().t_s == 12.0);  // the last sample stored
  CHECK(s.get_run(settling)->events.back().t_s.has_value() == false);
  CHECK(s.get_run(pending)->run.state == RunState::pending);
  CHECK(s.get_run(completed)->run.state == RunState::completed);
  CHECK(s.mark_interrupted_runs("again")->empty());
  CHECK(s.integrity_check().value().empty());
}

TEST_CASE("store: integrity_check reports a broken reference", "[store][schema]") {
  TempDir tmp;
  const auto path = tmp / "fk.db";
  { Store s = open_ok(path); REQUIRE(s.create_run(two_unit_run()).has_value()); }
  {
    Raw raw(path);  // foreign keys are off in a raw connection: break one behind the store's back
    raw.exec("INSERT INTO run_events (run_id, at, kind) VALUES (77, 'x', 'note')");
  }
  Store s = open_ok(path);
  auto problems = s.integrity_check();
  REQUIRE(problems.has_value());
  REQUIRE(problems->size() == 1);
  CHECK_THAT(problems->front(), Contains("run_events"));
  CHECK_THAT(problems->front(), Contains("runs"));
}

TEST_CASE("store: writes to a read-only database are errors and lose nothing",
          "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "ro.db";
  std::int64_t run;
  {
    Store s = open_ok(path);
    run = s.create_run(two_unit_run()).value();
    const SampleRow rows[] = {sample(0, 0), sample(0, 1)};
    REQUIRE(s.append_samples(run, rows).has_value());
  }
  // What a write-refusing store must do, as a list of what it did not (empty: all of it). Plain
  // code rather than CHECKs, so that a child process without privileges can run it too.
  auto refusal_failures = [&](Store& s) {
    std::vector<std::string> failed;
    auto expect = [&](bool ok, const char* what) {
      if (!ok) failed.emplace_back(what);
    };
    const SampleRow rows[] = {sample(0, 2)};
    auto w = s.append_samples(run, rows);
    expect(!w.has_value(), "append_samples refused");
    if (!w) {
      expect(w.error().code == StoreErrc::read_only, "append error code read_only");
      expect((w.error().sqlite_code & 0xff) == SQLITE_READONLY, "sqlite code SQLITE_READONLY");
      expect(w.error().message.find("append 1 samples to run 1") != std::string::npos,
             "message names the append");
      expect(w.error().message.find("readonly") != std::string::npos, "message says readonly");
    }
    auto c = s.create_run(two_unit_run());
    expect(!c && c.error().code == StoreErrc::read_only, "create_run refused as read_only");
    auto st = s.set_run_state(run, RunState::failed, "x");
    expect(!st && st.error().code == StoreErrc::read_only, "set_run_state refused as read_only");
    auto m = s.put_model({"FOG-001", run, std::nullopt, "{}", "", ""});
    expect(!m && m.error().code == StoreErrc::read_only, "put_model refused as read_only");
    // Reads still work and show everything stored before.
    auto n = s.count_samples(run);
    expect(n && *n == 2, "the 2 stored samples still read");
    auto r = s.get_run(run);
    expect(r && r->run.state == RunState::pending, "the run still reads as pending");
    return failed;
  };
  auto check_refused = [&](Store& s) {
    const auto failed = refusal_failures(s);
    for (const auto& f : failed) FAIL_CHECK("not done: " << f);
    CHECK(failed.empty());
  };

  SECTION("opened read-only") {
    OpenOptions ro;
    ro.read_only = true;
    Store s = open_ok(path, ro);
    check_refused(s);
  }
  SECTION("a file without write permission") {
    namespace fs = std::filesystem;
    fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
    if (::geteuid() != 0) {
      Store s = open_ok(path);
      check_refused(s);
    } else {
      // Root ignores file modes: the case runs in a child that gives up root for `nobody`
      // (uid/gid 65534), owner of the folder and the read-only file as a user would be of theirs.
      constexpr uid_t kNobody = 65534;
      for (const auto& e : fs::directory_iterator(tmp.dir))
        REQUIRE(::chown(e.path().c_str(), kNobody, kNobody) == 0);
      REQUIRE(::chown(tmp.dir.c_str(), kNobody, kNobody) == 0);
      int out[2];
      REQUIRE(::pipe(out) == 0);
      const pid_t child = ::fork();
      REQUIRE(child >= 0);
      if (child == 0) {
        ::close(out[0]);
        std::string report;
        if (::setgid(kNobody) != 0 || ::setuid(kNobody) != 0) {
          report = "could not become nobody";
        } else if (auto s = Store::open(path, {}); !s) {
          report = "open: " + s.error().message;
        } else {
          for (const auto& f : refusal_failures(*s)) report += f + "\n";
        }
        const auto written = ::write(out[1], report.data(), report.size());
        ::_exit(written == static_cast<ssize_t>(report.size()) ? 0 : 1);
      }
      ::close(out[1]);
      std::string report;
      char buf[512];
      for (ssize_t k; (k = ::read(out[0], buf, sizeof buf)) > 0;) report.append(buf, k);
      ::close(out[0]);
      int status = 0;
      REQUIRE(::waitpid(child, &status, 0) == child);
      REQUIRE(WIFEXITED(status));
      CHECK(WEXITSTATUS(status) == 0);
      INFO("the child without privileges reported:\n" << report);
      CHECK(report.empty());
      REQUIRE(::chown(tmp.dir.c_str(), 0, 0) == 0);
      for (const auto& e : fs::directory_iterator(tmp.dir))
        REQUIRE(::chown(e.path().c_str(), 0, 0) == 0);
    }
    fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  }
  Store s = open_ok(path);
  CHECK(s.count_samples(run).value() == 2);
  CHECK(s.integrity_check().value().empty());
}

TEST_CASE("store: a full disk is an error value, earlier data intact", "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "full.db";
  OpenOptions o;
  o.size_limit_bytes = 256 * 1024;  // room for a few thousand samples only
  Store s = open_ok(path, o);
  const auto run = s.create_run(two_unit_run()).value();

  std::int64_t stored = 0;
  std::optional<StoreError> error;
  for (int second = 0; second < 100000 && !error; ++second) {
    std::vector<SampleRow> rows;
    for (int u = 0; u < 2; ++u) rows.push_back(sample(u, second));
    if (auto r = s.append_samples(run, rows); r)
      stored += 2;
    else
      error = r.error();
  }
  REQUIRE(error.has_value());
  CHECK(error->code == StoreErrc::disk_full);
  CHECK_THAT(error->message, Contains("full"));
  CHECK(stored > 100);
  CHECK(s.count_samples(run).value() == stored);
  auto last = s.get_samples(run, 1, stored / 2 - 1, 1).value();
  CHECK(last.at(0).t_s == static_cast<double>(stored / 2 - 1));
  CHECK(s.integrity_check().value().empty());
  // The store is still usable: reads work and a small write that fits is not needed to recover.
  CHECK(s.get_run(run).has_value());
}

TEST_CASE("store: a size limit keeps a reserve for the run's end after samples filled it", "[store][failure]") {
  TempDir tmp;
  const auto path = tmp / "reserve.db";
  OpenOptions o;
  o.size_limit_bytes = 256 * 1024;
  Store s = open_ok(path, o);
  const auto run = s.create_run(two_unit_run()).value();
  REQUIRE(s.set_run_state(run, RunState::running, "started").has_value());
  int second = 0;
  for (; second < 100000; ++second) {
    std::vector<SampleRow> rows;
    for (int u = 0; u < 2; ++u) rows.push_back(sample(u, second));
    if (!s.append_samples(run, rows)) break;
  }
  REQUIRE(second < 100000);
  // Samples are refused, but the end of the run still goes in: a note and the state change.
  // Larger than a page: it needs new pages (overflow), which only the reserve has.
  const std::string note(5000, 'q');
  CHECK(s.add_event(run, EventKind::note, "{\"why\":\"" + note + "\"}").has_value());
  CHECK(s.set_run_state(run, RunState::aborted, "storage full").has_value());
  CHECK(s.get_run(run).value().run.state == RunState::aborted);
  // ... and the reserve is closed again: the second that did not fit still does not.
  const SampleRow next[] = {sample(0, second), sample(1, second)};
  auto r = s.append_samples(run, next);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().code == StoreErrc::disk_full);
  CHECK(s.count_samples(run).value() == 2 * second);
  CHECK(s.integrity_check().value().empty());
  // The file stays within its limit once the WAL is checkpointed into it (at close).
  s = Store::open(":memory:").value();
  CHECK(std::filesystem::file_size(path) <= 256 * 1024);
}

TEST_CASE("store: a second connection reads while the first writes (WAL)", "[store][wal]") {
  TempDir tmp;
  const auto path = tmp / "wal.db";
  Store writer = open_ok(path);
  const auto run = writer.create_run(two_unit_run()).value();
  OpenOptions ro;
  ro.read_only = true;
  Store reader = open_ok(path, ro);
  for (int t = 0; t < 5; ++t) {
    const SampleRow rows[] = {sample(0, t)};
    REQUIRE(writer.append_samples(run, rows).has_value());
    CHECK(reader.count_samples(run).value() == t + 1);  // each call is committed at once
  }
  Store moved = std::move(writer);
  CHECK(moved);
  CHECK_FALSE(writer);
  CHECK(moved.count_samples(run).value() == 5);
}
