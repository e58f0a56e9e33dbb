// What the store tests share: a temporary directory per test case, a store opened or the test
// failed, raw SQL on the file behind the store, and a two-unit run with its samples.
#pragma once

#include <catch2/catch.hpp>

#include <sqlite3.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"

namespace fogbench::storage::testing {

// A fresh directory per test case, removed at the end of it.
struct TempDir {
  std::filesystem::path dir;
  TempDir() {
    static std::atomic<int> counter{0};
    dir = std::filesystem::temp_directory_path() /
          ("fogbench_store_test_" + std::to_string(::getpid()) + "_" +
           std::to_string(counter++));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::permissions(dir, std::filesystem::perms::owner_all, ec);
    std::filesystem::remove_all(dir, ec);
  }
  std::filesystem::path operator/(const std::string& name) const { return dir / name; }
};

inline Store open_ok(const std::filesystem::path& path, const OpenOptions& options = {}) {
  auto s = Store::open(path, options);
  if (!s) FAIL("open " << path << ": " << s.error().message);
  return std::move(*s);
}

// Raw SQLite access, to build old or foreign files and look at what the store wrote.
struct Raw {
  sqlite3* db = nullptr;
  explicit Raw(const std::filesystem::path& path) {
    REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  }
  ~Raw() { sqlite3_close(db); }
  void exec(const std::string& sql) {
    char* err = nullptr;
    const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
    INFO(sql << ": " << (err ? err : ""));
    sqlite3_free(err);
    REQUIRE(rc == SQLITE_OK);
  }
  std::string text(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK);
    std::string out;
    if (sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0))
      out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    sqlite3_finalize(st);
    return out;
  }
  long long integer(const std::string& sql) { return std::stoll(text(sql)); }
};

inline NewRun two_unit_run(std::string profile = "qualification") {
  NewRun r;
  r.profile_name = std::move(profile);
  r.profile_text = "hold 23 C 1 h\nramp 60 C at 1 C/min\n";
  r.config_json = R"({"units":2,"rate_hz":1})";
  r.time_scale = 1.0;
  r.unit_serials = {"FOG-001", "FOG-002"};
  return r;
}

inline SampleRow sample(int unit, double t_s, model::Phase phase = model::Phase::hold) {
  SampleRow s;
  s.unit_index = unit;
  s.t_s = t_s;
  s.wall_time = 1.7e9 + t_s;
  s.setpoint_c = 23;
  s.chamber_c = 23.5 + 0.001 * t_s;
  s.gyro_dph = 0.01 * t_s + unit;
  s.frames = 2000;
  s.t1_c = 23.1 + 0.001 * t_s;
  s.t2_c = 23.2 + 0.001 * t_s;
  s.phase = phase;
  s.step = 1;
  s.flags = 0;
  return s;
}

}  // namespace fogbench::storage::testing
