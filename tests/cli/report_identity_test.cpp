// fogctl report's header: each run file's identity (the `# key: value` comments fogctl run
// export writes atop the CSV) printed under the title; a file without them prints none.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "fogbench/storage/identity.hpp"
#include "offline.hpp"
#include "workbench.hpp"

using namespace fogbench;
using namespace fogbench::cli;
namespace fs = std::filesystem;

TEST_CASE("fogctl report: the run's identity from its CSV comments is in the header", "[cli][report]") {
  const fs::path dir = fs::temp_directory_path() / ("fogctl-report-id-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ostringstream o, e;
  SimulateOptions s;
  s.profile = "exp1";
  s.output = (dir / "plain.csv").string();
  s.coil = "lumped";
  s.quiet = true;
  REQUIRE(run_simulate(s, o, e) == kExitOk);
  FitCommandOptions f;
  f.run = s.output;
  f.output = (dir / "model.json").string();
  REQUIRE(run_fit(f, o, e) == kExitOk);

  storage::RunIdentity id;
  id.station_id = "line-2";
  id.operator_name = "Ada Lovelace";
  id.operator_source = "client";
  id.software_version = "0.1.0";
  id.git_hash = "58b9f8ad20ce2bfcb4bae6985d95cf60120ac562";
  id.config_sha256 = std::string(64, 'a');
  id.profile_sha256 = std::string(64, 'b');
  id.units = {{0, "FOG-1", "2026-11-25T08:00:00Z", 12.0}};
  std::ifstream in(s.output);
  std::stringstream csv;
  csv << in.rdbuf();
  std::ofstream(dir / "run.csv") << storage::identity_comment_lines(storage::identity_fields(id, 12, "exp1", 0)) << csv.str();

  ReportOptions r;
  r.model = f.output;
  r.runs = {(dir / "run.csv").string()};
  r.output = (dir / "report.html").string();
  REQUIRE(run_report(r, o, e) == kExitOk);
  std::ifstream h(r.output);
  std::stringstream html;
  html << h.rdbuf();
  CHECK(html.str().find("run 12 of FOG-1, station line-2, operator Ada Lovelace, fogbench 0.1.0 (58b9f8ad20ce)") != std::string::npos);
  CHECK(html.str().find("powered on 2026-11-25T08:00:00Z") != std::string::npos);

  r.runs = {s.output};  // no comments: no identity line
  REQUIRE(run_report(r, o, e) == kExitOk);
  std::ifstream h2(r.output);
  std::stringstream html2;
  html2 << h2.rdbuf();
  CHECK(html2.str().find("operator Ada") == std::string::npos);
  fs::remove_all(dir);
}
