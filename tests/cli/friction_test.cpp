// fogctl without friction (issue 15): progress lines that suit a log file, exit codes and
// messages of bad options as the user typed them, CSV from other locales, a truncated model
// file, a term the model already has, profile list|validate. Exit codes and messages through
// the built fogctl, as a user meets them.
#include <catch2/catch.hpp>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

#include "fogbench/model/json.hpp"
#include "offline.hpp"
#include "plan.hpp"
#include "progress.hpp"
#include "fogctl_process.hpp"

using namespace fogbench::cli;
using namespace fogbench::cli::testing;
namespace fs = std::filesystem;
using Catch::Contains;

namespace {

void write(const std::string& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

void simulate(const std::string& profile, std::uint64_t seed, const std::string& path, std::vector<std::string> effects = {}) {
  SimulateOptions o;
  o.profile = profile;
  o.seed = seed;
  o.output = path;
  o.effects = std::move(effects);
  o.quiet = true;
  std::ostringstream out, err;
  REQUIRE(run_simulate(o, out, err) == kExitOk);
}

void fit_paper(const std::string& run, const std::string& model) {
  FitCommandOptions f;
  f.run = run;
  f.output = model;
  std::ostringstream out, err;
  REQUIRE(run_fit(f, out, err) == kExitOk);
}

std::size_t count(const std::string& s, char c) { return static_cast<std::size_t>(std::count(s.begin(), s.end(), c)); }

}  // namespace

TEST_CASE("progress: in a file, a line per phase change and one a minute, never a carriage return") {
  using namespace std::chrono;
  auto now = steady_clock::time_point{};
  std::ostringstream err;
  {
    Progress p(err, /*redraw=*/false, 60.0, [&] { return now; });
    p.update("hold 0", "a");       // the first status: a line
    now += seconds(10);
    p.update("hold 0", "b");       // same phase, 10 s later: nothing
    now += seconds(10);
    p.update("heating 1", "c");    // a new phase: a line at once
    for (int i = 0; i < 59; ++i) {  // 59 s in the same phase: nothing
      now += seconds(1);
      p.update("heating 1", "d");
    }
    now += seconds(1);
    p.update("heating 1", "e");    // a minute since the last line: a line
    p.line("run 1: completed (done)");
  }
  CHECK(err.str() == "a\nc\ne\nrun 1: completed (done)\n");
}

TEST_CASE("progress: on a terminal, one line redrawn in place and ended by a message") {
  using namespace std::chrono;
  auto now = steady_clock::time_point{};
  std::ostringstream err;
  {
    Progress p(err, /*redraw=*/true, 60.0, [&] { return now; });
    p.update("hold 0", "long status");
    now += milliseconds(300);
    p.update("hold 0", "short");  // padded over the longer line before it
    p.line("done");
  }
  CHECK(err.str() == "\rlong status\rshort      \ndone\n");
}

TEST_CASE("progress: on a terminal of 100 columns a longer line is cut to 99 and ends with ..., a file keeps it whole") {
  using namespace std::chrono;
  auto now = steady_clock::time_point{};
  const std::string wide(184, 'x');
  std::ostringstream tty, file;
  {
    Progress p(tty, /*redraw=*/true, 60.0, [&] { return now; });
    p.set_width(100);
    CHECK(p.width() == 100);
    p.update("hold 0", wide);
  }
  CHECK(tty.str() == "\r" + std::string(96, 'x') + "...\n");
  {
    Progress p(file, /*redraw=*/false, 60.0, [&] { return now; });
    p.set_width(100);
    CHECK(p.width() == 0);  // lines in a file or a pipe are never cut
    p.update("hold 0", wide);
  }
  CHECK(file.str() == wide + "\n");
}

TEST_CASE("fogctl simulate: progress written to a file has no carriage return") {
  Dir d;
  // The redraw an operator sees on a terminal (forced, as a pty would be) ...
  const Ran tty = fogctl(d, "simulate --profile exp1 --seed 2 -o " + d.file("a.csv"), "FOGCTL_PROGRESS=redraw");
  REQUIRE(tty.code == 0);
  CHECK(count(tty.err, '\r') >= 1);
  CHECK(count(tty.err, '\n') == 1);  // the redrawn line, ended once
  // ... and the same command with stderr a file, as under nohup or systemd.
  const Ran log = fogctl(d, "simulate --profile exp1 --seed 2 -o " + d.file("b.csv"));
  INFO(log.err);
  REQUIRE(log.code == 0);
  CHECK(count(log.err, '\r') == 0);
  CHECK_THAT(log.err, Contains("simulating exp1"));
  CHECK(count(log.err, '\n') <= 3);  // exp1 simulates in seconds: its first line, at most a minute's
}

TEST_CASE("fogctl: --run and --seed out of their range exit 2 naming the option as typed, never abort") {
  Dir d;
  struct Case {
    std::string args, names;
  };
  for (const Case& c : {Case{"verify --run exp1.csv", "'exp1.csv'"}, Case{"fit --run abc", "'abc'"},
                        Case{"fit --run 99999999999999999999", "out of the range"}, Case{"fit --run 0", "'0'"},
                        Case{"compare --run x", "'x'"}, Case{"diagnose --run -3", "-3"},
                        Case{"report --run 1.5 -o r.html", "'1.5'"}}) {
    INFO(c.args);
    const Ran r = fogctl(d, c.args);
    INFO(r.err);
    CHECK(r.code == kExitError);
    CHECK_THAT(r.err, Contains("--run"));
    CHECK_THAT(r.err, Contains(c.names));
  }
  const Ran csv = fogctl(d, "verify --run exp1.csv");
  CHECK_THAT(csv.err, Contains("a CSV file is given without --run"));
  const Ran seed = fogctl(d, "simulate --profile exp1 --seed -1 -o " + d.file("s.csv"));
  INFO(seed.err);
  CHECK(seed.code == kExitError);
  CHECK_THAT(seed.err, Contains("--seed"));
  CHECK_FALSE(fs::exists(d.file("s.csv")));
}

TEST_CASE("fogctl report: exits as verify does, 1 when the qualification fails") {
  Dir d;
  simulate("exp1", 3, d.file("e1.csv"));
  // A strong absolute-temperature sensitivity the paper's model lacks: held out, it fails.
  simulate("exp3", 4, d.file("e3.csv"), {"0.5*T1"});
  fit_paper(d.file("e1.csv"), d.file("m.json"));
  const Ran v = fogctl(d, "verify --model " + d.file("m.json") + " " + d.file("e3.csv"));
  REQUIRE(v.code == kExitFailed);
  const Ran r = fogctl(d, "report --model " + d.file("m.json") + " " + d.file("e1.csv") + " " + d.file("e3.csv") + " -o " + d.file("r.html"));
  INFO(r.out << r.err);
  CHECK_THAT(r.out, Contains("qualification FAIL"));
  CHECK(r.code == kExitFailed);
  CHECK(fs::exists(d.file("r.html")));  // the report is written either way
  // Its progress, piped: a line per stage, never a carriage return (issue 28: long work is not silent).
  CHECK_THAT(r.err, Contains("report: reading " + d.file("e1.csv") + " (1 of 2)\n") && Contains("report: diagnose, ") &&
                        Contains("report: Table 1, the lineage and the plots\n") && Contains("report: writing "));
  CHECK(r.err.find('\r') == std::string::npos);
}

namespace {

std::size_t widest_line(const std::string& text) {
  std::size_t widest = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) widest = std::max(widest, line.size());
  return widest;
}

// A text without its spaces and line breaks: a line wrapped at spaces reads the same.
std::string without_spaces(const std::string& text) {
  std::string out;
  for (char c : text)
    if (c != ' ' && c != '\n') out += c;
  return out;
}

}  // namespace

TEST_CASE("fogctl fit and allan at COLUMNS=60: every line within 60 and every word kept while piped lines stay whole") {
  Dir d;
  simulate("exp1", 2, d.file("e1.csv"));
  for (const std::string& args : {"fit " + d.file("e1.csv"), "allan " + d.file("e1.csv")}) {
    INFO(args);
    const Ran piped = fogctl(d, args, "-u COLUMNS");
    const Ran narrow = fogctl(d, args, "COLUMNS=60");
    INFO(piped.out << "\n--- at 60:\n" << narrow.out);
    REQUIRE(piped.code == 0);
    REQUIRE(narrow.code == 0);
    // The run's notes (fit's whiteness and collinearity, allan's bias instability per hold) are
    // sentences of 166 and more columns (the tables are at most 107), left whole in a pipe ...
    CHECK(widest_line(piped.out) > 150);
    // ... and wrapped at spaces on a 60-column terminal (tables narrowed), each note's words kept.
    CHECK(widest_line(narrow.out) <= 60);
    std::istringstream lines(piped.out);
    int notes = 0;
    for (std::string line; std::getline(lines, line);) {
      if (line.size() <= 150) continue;  // a table's row: table_test.cpp covers their wrapping
      ++notes;
      CHECK_THAT(without_spaces(narrow.out), Contains(without_spaces(line)));
    }
    CHECK(notes >= 1);
  }
}

TEST_CASE("fogctl diagnose: progress lines in a log that asks for them without --progress, never a carriage return") {
  Dir d;
  simulate("exp1", 5, d.file("e1.csv"));
  simulate("exp2", 6, d.file("e2.csv"));
  fit_paper(d.file("e1.csv"), d.file("m.json"));
  const std::string args = "diagnose --model " + d.file("m.json") + " " + d.file("e1.csv") + " " + d.file("e2.csv");
  // A log that wants progress (FOGCTL_PROGRESS=lines, as for run start --wait): a line per stage
  // from the start. Without it, a piped diagnose writes them once it has taken 2 s (a 3-day run
  // takes a minute), so this short one writes none.
  const Ran logged = fogctl(d, args, "FOGCTL_PROGRESS=lines");
  INFO(logged.err);
  REQUIRE((logged.code == kExitOk || logged.code == kExitFailed));
  CHECK_THAT(logged.err, Contains("diagnose: step 1, "));
  CHECK(logged.err.find('\r') == std::string::npos);
  CHECK(logged.out.find("diagnose: step") == std::string::npos);  // never on stdout
}

TEST_CASE("fogctl verify: progress lines per run in a log that asks for them, none on a quick piped verify") {
  Dir d;
  simulate("exp1", 7, d.file("e1.csv"));
  simulate("exp2", 8, d.file("e2.csv"));
  fit_paper(d.file("e1.csv"), d.file("m.json"));
  const std::string args = "verify --model " + d.file("m.json") + " " + d.file("e1.csv") + " " + d.file("e2.csv");
  const Ran logged = fogctl(d, args, "FOGCTL_PROGRESS=lines");
  INFO(logged.err);
  REQUIRE(logged.code != 2);
  CHECK_THAT(logged.err, Contains("verify: reading " + d.file("e1.csv") + " (1 of 2)\n") &&
                             Contains("verify: compensating " + d.file("e2.csv") + " (2 of 2)\n"));
  CHECK(logged.err.find('\r') == std::string::npos);
  CHECK_THAT(logged.out, Contains("Table 1"));
}

TEST_CASE("fogctl: a CSV from a German spreadsheet, a tab-separated one, upper-case headers") {
  Dir d;
  simulate("exp1", 5, d.file("e1.csv"));
  const std::string plain = slurp(d.file("e1.csv"));
  // ';' between fields and decimal commas, headers capitalised: the same numbers.
  std::string semi, tab;
  bool header = true;
  std::istringstream in(plain);
  for (std::string line; std::getline(in, line);) {
    std::string s = line, t = line;
    if (header) {
      for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      t = s;
    }
    for (auto& c : s) c = c == ',' ? ';' : c == '.' ? ',' : c;
    for (auto& c : t) c = c == ',' ? '\t' : c;
    semi += s + "\n";
    tab += t + "\n";
    header = false;
  }
  write(d.file("de.csv"), semi);
  write(d.file("tab.csv"), tab);
  const Ran base = fogctl(d, "fit " + d.file("e1.csv") + " --json");
  REQUIRE(base.code == 0);
  const auto mu0 = nlohmann::json::parse(base.out)["mu0"].get<double>();

  const Ran de = fogctl(d, "fit " + d.file("de.csv") + " --decimal-comma --json");
  INFO(de.err);
  REQUIRE(de.code == 0);
  CHECK(nlohmann::json::parse(de.out)["mu0"].get<double>() == mu0);  // the same digits, the same doubles
  const Ran tb = fogctl(d, "fit " + d.file("tab.csv") + " --json");     // tab detected
  INFO(tb.err);
  REQUIRE(tb.code == 0);
  CHECK(nlohmann::json::parse(tb.out)["mu0"].get<double>() == mu0);
  const Ran tb2 = fogctl(d, "fit " + d.file("tab.csv") + " --delimiter '\\t' --json");
  CHECK(tb2.code == 0);

  // Decimal commas without --decimal-comma: refused, with the hint; never a wrong number.
  const Ran no_dc = fogctl(d, "fit " + d.file("de.csv"));
  INFO(no_dc.err);
  CHECK(no_dc.code == kExitError);
  CHECK_THAT(no_dc.err, Contains("--decimal-comma"));
  // --decimal-comma with ',' between fields cannot be told apart: refused, named.
  const Ran comma = fogctl(d, "fit " + d.file("e1.csv") + " --decimal-comma");
  CHECK(comma.code == kExitError);
  CHECK_THAT(comma.err, Contains("--decimal-comma needs ';' or tab"));
  const Ran bad = fogctl(d, "fit " + d.file("e1.csv") + " --delimiter '|'");
  CHECK(bad.code == kExitError);
  CHECK_THAT(bad.err, Contains("--delimiter |"));
}

TEST_CASE("fogctl: every missing column named at once, and a one-column header is said to be one") {
  Dir d;
  write(d.file("m.csv"), "Zeit_s;Drehrate;T1_c;t2_c\n0;1;2;3\n1;1;2;3\n");
  const Ran r = fogctl(d, "fit " + d.file("m.csv"));
  INFO(r.err);
  CHECK(r.code == kExitError);
  // ';' detected: the header is four names, two of them (in any case) fogbench's.
  CHECK_THAT(r.err, Contains("columns 'time_s', 'gyro_dph' not found"));
  CHECK_THAT(r.err, Contains("Zeit_s,Drehrate,T1_c,t2_c"));
  CHECK_THAT(r.err, Contains("--map time_s=<name in the file> --map gyro_dph=<name in the file>"));
  // Forced to ',' the header is one column: said so, not "'Zeit_s' not found; the header has: Zeit_s;...".
  const Ran one = fogctl(d, "fit " + d.file("m.csv") + " --delimiter , --map time_s=Zeit_s --map gyro_dph=Drehrate");
  INFO(one.err);
  CHECK(one.code == kExitError);
  CHECK_THAT(one.err, Contains("the header is one column: give its separator with --delimiter"));
  CHECK_THAT(one.err, Contains("'Zeit_s' (named by --map time_s=Zeit_s)") && Contains("'Drehrate' (named by --map gyro_dph=Drehrate)"));
}

TEST_CASE("fogctl: messages name the options as typed, a truncated model its line and column, a term the model has") {
  Dir d;
  simulate("exp1", 6, d.file("e1.csv"));
  fit_paper(d.file("e1.csv"), d.file("m.json"));
  const Ran ar = fogctl(d, "fit " + d.file("e1.csv") + " --ar-order 0");
  CHECK(ar.code == kExitError);
  CHECK_THAT(ar.err, Contains("--ar-order must be 1..10"));
  CHECK(ar.err.find("ar_order") == std::string::npos);
  const Ran sm = fogctl(d, "compare --model " + d.file("m.json") + " " + d.file("e1.csv") + " --smooth 4");
  CHECK(sm.code == kExitError);
  CHECK_THAT(sm.err, Contains("--smooth must be"));
  CHECK(sm.err.find("smooth_s") == std::string::npos);
  // Uneven time: the hint names --resample.
  write(d.file("u.csv"), "time_s,gyro_dph,t1_c,t2_c\n0,1,2,3\n1,1,2,3\n2,1,2,3\n4,1,2,3\n");
  const Ran un = fogctl(d, "fit " + d.file("u.csv"));
  CHECK_THAT(un.err, Contains("--resample S"));
  CHECK(un.err.find("resample_s") == std::string::npos);

  // A model file cut short: where the JSON ends.
  const std::string full = slurp(d.file("m.json"));
  write(d.file("cut.json"), full.substr(0, full.size() / 2));
  std::size_t lines = 1 + static_cast<std::size_t>(std::count(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(full.size() / 2), '\n'));
  const Ran cut = fogctl(d, "verify --model " + d.file("cut.json") + " " + d.file("e1.csv"));
  INFO(cut.err);
  CHECK(cut.code == kExitError);
  CHECK_THAT(cut.err, Contains("not valid JSON at line " + std::to_string(lines) + ", column "));

  // --add of a term the model has: said as such.
  auto m = fogbench::model::model_from_text(full);
  REQUIRE(m);
  REQUIRE_FALSE(m->terms.empty());
  const std::string term = m->terms.front().name();
  const Ran add = fogctl(d, "fit --model " + d.file("m.json") + " --add '" + term + "' " + d.file("e1.csv") + " -o " + d.file("m2.json"));
  INFO(add.err);
  CHECK(add.code == kExitError);
  CHECK_THAT(add.err, Contains("the model already has the term " + term));
  CHECK(add.err.find("collinear") == std::string::npos);
  CHECK_FALSE(fs::exists(d.file("m2.json")));
}

TEST_CASE("fogctl profile list and validate") {
  Dir d;
  const Ran list = fogctl(d, "profile list --json");
  INFO(list.err);
  REQUIRE(list.code == 0);
  const auto j = nlohmann::json::parse(list.out);
  bool exp1 = false;
  for (const auto& p : j) exp1 = exp1 || (p["name"] == "exp1" && p["nominal_duration_s"].get<double>() > 0);
  CHECK(exp1);
  CHECK(fogctl(d, "profile validate exp1").code == 0);
  write(d.file("bad.profile"), "setpoint 20 C\nhold ten minutes\n");
  const Ran bad = fogctl(d, "profile validate " + d.file("bad.profile"));
  CHECK(bad.code == kExitError);
  CHECK_THAT(bad.err, Contains("bad.profile:2:"));
  // A chamber that cannot reach exp1's temperatures.
  const Ran lim = fogctl(d, "profile validate exp1 --min 0 --max 1 --max-rate 1");
  CHECK(lim.code == kExitError);
  CHECK(fogctl(d, "profile validate exp1 --min 0").code == kExitError);  // limits go together
}

TEST_CASE("fogctl plan report: the page ends with each unit's report command, with its runs and its model") {
  using nlohmann::json;
  auto run = [](int id, const char* purpose, json units) {
    return json{{"step", id}, {"profile", "exp" + std::to_string(id)}, {"purpose", purpose}, {"attempt", 0},
                {"run_id", id}, {"units", std::move(units)}};
  };
  json status = {{"plan_id", 3}, {"name", "paper"}, {"source", "paper.plan"}, {"state", "completed"}, {"reason", ""},
                 {"started_at", "2026-11-27T08:00:00Z"}, {"ended_at", "2026-11-27T09:00:00Z"}, {"plan_text", "plan paper"},
                 {"progress",
                  {{"units", json::array({json{{"serial", "FOG-1"}, {"verdict", "pass"}, {"reasons", json::array()},
                                               {"measurements", json::array()}},
                                          json{{"serial", "FOG-2"}, {"verdict", "fail"}, {"reasons", json::array()},
                                               {"measurements", json::array()}}})},
                   {"runs", json::array({run(1, "fit", {"FOG-1"}), run(2, "verify", {"FOG-1", "FOG-2"}),
                                         run(3, "verify", {"FOG-1"})})}}}};
  const std::string html = plan_report_html(status);
  // FOG-1 was fitted by the plan: its current model is the one to report with; FOG-2 was not.
  CHECK_THAT(html, Contains("<code>fogctl report --unit FOG-1 --run 1 --run 2 --run 3 -o report-FOG-1.html</code>"));
  CHECK_THAT(html, Contains("<code>fogctl report --model MODEL.json --unit FOG-2 --run 2 -o report-FOG-2.html</code>"));
  CHECK_THAT(html, !Contains("fogctl report RUN"));
  status["progress"]["runs"] = json::array();
  CHECK_THAT(plan_report_html(status), Contains("No run of the plan has been stored yet"));
}

TEST_CASE("fogctl plan validate --offline: a plan checked without a daemon, a copied fogctl finds what the variables name") {
  Dir d;
  // The shipped plan, by name, from the build tree's share/fogbench: no daemon is running.
  const Ran paper = fogctl(d, "plan validate --offline paper");
  INFO(paper.out << paper.err);
  CHECK(paper.code == kExitOk);
  CHECK_THAT(paper.out, Contains("valid, 3 steps") && Contains("checked offline") && Contains("comp_raw < 0.2"));
  const Ran js = fogctl(d, "plan validate --offline paper --json");
  REQUIRE(js.code == kExitOk);
  const auto j = nlohmann::json::parse(js.out);
  CHECK(j["checked"] == "offline");
  CHECK(j["steps"].size() == 3);
  CHECK(j["nominal_duration_s"].get<double>() > 3600.0);

  // A plan of its own with a profile of its own, found through FOGBENCH_PROFILE_DIR.
  fs::create_directories(d.path / "mine");
  write((d.path / "mine" / "short.profile").string(), "setpoint 20 C\nhold 3 min\n");
  write(d.file("soak.plan"), "plan soak\nstep short soak\nlimit arw < 1 deg/sqrt(h)\n");
  const std::string mine = "FOGBENCH_PROFILE_DIR='" + (d.path / "mine").string() + "'";
  const Ran soak = fogctl(d, "plan validate --offline " + d.file("soak.plan"), mine);
  INFO(soak.out << soak.err);
  CHECK(soak.code == kExitOk);
  CHECK_THAT(soak.out, Contains("plan soak: valid, 1 steps"));
  // Without it, the step's profile is not found: the line and the variable are named.
  const Ran lost = fogctl(d, "plan validate --offline " + d.file("soak.plan"), "-u FOGBENCH_PROFILE_DIR");
  CHECK(lost.code == kExitError);
  CHECK_THAT(lost.err, Contains("soak.plan:2: step 'short'") && Contains("FOGBENCH_PROFILE_DIR"));
  // A language error names its line and column.
  write(d.file("bad.plan"), "plan bad\nstep short soak\nlimit arw < 1 deg/h\n");
  const Ran bad = fogctl(d, "plan validate --offline " + d.file("bad.plan"), mine);
  CHECK(bad.code == kExitError);
  CHECK_THAT(bad.err, Contains("bad.plan:3:15:"));
  // No such plan: every folder searched is named, and the variable that adds one.
  const Ran none = fogctl(d, "plan validate --offline no-such-plan");
  CHECK(none.code == kExitError);
  CHECK_THAT(none.err, Contains("plan 'no-such-plan': no such file") && Contains("FOGBENCH_PLAN_DIR"));

  // A fogctl copied out of the build tree finds the shipped plans and profiles through the variables.
  const fs::path copy = d.path / "bin" / "fogctl";
  fs::create_directories(copy.parent_path());
  fs::copy_file(std::string(FOGBENCH_BIN_DIR) + "/fogctl", copy);
  const std::string src = FOGBENCH_SOURCE_DIR;
  const std::string cmd = "env FOGBENCH_PLAN_DIR='" + src + "/plans' FOGBENCH_PROFILE_DIR='" + src + "/profiles' '" + copy.string() +
                          "' plan validate --offline paper >'" + d.file("copy.out") + "' 2>&1";
  const int st = std::system(cmd.c_str());
  INFO(slurp(d.file("copy.out")));
  CHECK((WIFEXITED(st) && WEXITSTATUS(st) == 0));
  // Without the variables, its profile list says where it looked and which variable adds a folder.
  const std::string list = "env -u FOGBENCH_PROFILE_DIR '" + copy.string() + "' profile list >'" + d.file("list.out") + "' 2>&1";
  const int ls = std::system(list.c_str());
  const std::string listed = slurp(d.file("list.out"));
  INFO(listed);
  CHECK((WIFEXITED(ls) && WEXITSTATUS(ls) == 0));
  CHECK_THAT(listed, Contains("no profiles found in " + (d.path / "share" / "fogbench" / "profiles").string()) &&
                         Contains("FOGBENCH_PROFILE_DIR"));
}
