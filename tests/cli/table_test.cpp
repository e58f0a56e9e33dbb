// fogctl's human tables: what a cell may carry to the terminal.
#include <algorithm>
#include <catch2/catch.hpp>

#include <sstream>
#include <string>
#include <vector>

#include "table.hpp"

using namespace fogbench::cli;

TEST_CASE("fogctl tables: a cell never carries a control character or a 100,000-byte name to the terminal") {
  Table t({"plan", "units"});
  t.add({"night\x1b]0;owned\x07", std::string(100000, 'n')});
  const std::string s = t.str(0);
  CHECK(s.find('\x1b') == std::string::npos);
  CHECK(s.find('\x07') == std::string::npos);
  CHECK(s.find("night\\x1B]0;owned\\x07") != std::string::npos);
  CHECK(s.find("... (100000 bytes)") != std::string::npos);
  CHECK(s.size() < 2000);
  // Cut at a character's start: "é" is two bytes and is not split.
  CHECK(printable(std::string(499, 'a') + "é", 500) == std::string(499, 'a') + "... (501 bytes)");
  CHECK(printable("Zoë", 500) == "Zoë");
}

namespace {
std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}
}  // namespace

TEST_CASE("fogctl tables: wider than the terminal, the text columns wrap and the numbers stay whole") {
  Table t({"#", "terms", "exp1.csv", "note"});
  const std::string note =
      "added d(T2)@13 to d(T1)@0 + grad@0, refitted on exp1.csv (paper method); the shared lag of d(T1), grad is 599 s, "
      "at the edge of its scan (0..600 s): a bound, not an estimate";
  t.add({"0", "d(T1)@0 + grad@0", "0.254", ""});
  t.add({"1", "d(T1) + grad + d(T2)@13", "0.149", note});
  const std::string whole = t.str(0);
  CHECK(whole.find(note) != std::string::npos);  // no limit: one line per row, as before
  CHECK(lines_of(whole).size() == 4);

  const std::string narrow = t.str(60);
  const auto lines = lines_of(narrow);
  CHECK(lines.size() > 4);
  for (const auto& l : lines) {
    INFO(l);
    CHECK(display_width(l) <= 60);
  }
  // Every word of the note is there, in order, and the numbers are whole on their row's first line.
  CHECK(lines[2].find("0.254") != std::string::npos);
  CHECK(lines[3].find("0.149") != std::string::npos);
  CHECK(lines[3].rfind("1", 0) == 0);
  std::string joined;
  const auto note_at = lines[0].find("note");
  REQUIRE(note_at != std::string::npos);
  for (std::size_t i = 3; i < lines.size(); ++i)
    if (lines[i].size() > note_at) joined += (joined.empty() ? "" : " ") + lines[i].substr(note_at);
  CHECK(joined == note);
  // The separator is as wide as the table.
  CHECK(lines[1] == std::string(display_width(lines[1]), '-'));
  CHECK(display_width(lines[1]) <= 60);
}

TEST_CASE("fogctl tables: a 20-column limit narrows every text column to its floor and says nothing false") {
  Table t({"serial", "verdict", "value"});
  t.add({"FOG-000000000042", "pass (plan strict, limits of plan 7)", "0.1875"});
  const std::string s = t.str(20);
  // Narrower than the header's words allow: the table stays as narrow as it can, nothing lost.
  CHECK(s.find("0.1875") != std::string::npos);
  CHECK(s.find("FOG-00000") != std::string::npos);
  std::string all;
  for (const auto& l : lines_of(s)) all += l + "\n";
  for (const char* word : {"pass", "(plan", "strict,", "limits", "of", "plan", "7)"}) CHECK(all.find(word) != std::string::npos);
  // And it says the table is wider than the terminal, in lines that fit it.
  const auto ls = lines_of(s);
  REQUIRE(ls.size() >= 2);
  std::string flat = all;  // the note's wrapped lines joined again
  std::replace(flat.begin(), flat.end(), '\n', ' ');
  CHECK(flat.find("(this table is ") != std::string::npos);
  CHECK(flat.find("columns wide, the terminal 20: its numbers are kept whole") != std::string::npos);
  CHECK(display_width(ls.back()) <= 20);
  // A table that fits says nothing of the kind.
  CHECK(t.str(200).find("columns wide") == std::string::npos);
  CHECK(t.str(0).find("columns wide") == std::string::npos);
}

TEST_CASE("fogctl tables: wrap_text and display_width") {
  CHECK(wrap_text("", 10) == std::vector<std::string>{""});
  CHECK(wrap_text("a bb ccc", 4) == std::vector<std::string>{"a bb", "ccc"});
  CHECK(wrap_text("abcdefghij", 4) == std::vector<std::string>{"abcd", "efgh", "ij"});
  CHECK(wrap_text("one  two", 20) == std::vector<std::string>{"one two"});
  // Counted in code points, cut between them: "é" is two bytes, one column.
  CHECK(display_width("Zoë") == 3);
  CHECK(wrap_text("ééééé", 2) == std::vector<std::string>{"éé", "éé", "é"});
}

TEST_CASE("fogctl text output: fit_lines wraps each line wider than the terminal at spaces, indented, and leaves the others") {
  const std::string title(
      "Table 1 (deg/h): model run 2 SIM-0001 (d(T1)@0 + grad@0), pass when comp/raw < 20%, comp std within 1.25 x the "
      "gyro's noise std and no failing interval of 60 s or more (else MARGINAL)");
  const std::string text = "short line\n" + title + "\n  - " + title + "\n";
  for (std::size_t width : {100u, 60u}) {
    INFO("width " << width);
    const std::string fitted = fit_lines(text, width);
    std::istringstream in(fitted);
    std::string line, words;
    std::size_t n = 0;
    while (std::getline(in, line)) {
      ++n;
      CHECK(display_width(line) <= width);
      words += line + " ";
    }
    CHECK(n > 3);
    CHECK(fitted.rfind("short line\nTable 1 (deg/h): model", 0) == 0);
    CHECK(fitted.find("\n  - Table 1") != std::string::npos);  // an indented line keeps its indent
    CHECK(fitted.find("\n    ") != std::string::npos);         // and its continuation two further
    // Nothing lost: the same words in the same order.
    std::istringstream a(text), b(words);
    std::vector<std::string> wa, wb;
    for (std::string w; a >> w;) wa.push_back(w);
    for (std::string w; b >> w;) wb.push_back(w);
    CHECK(wa == wb);
  }
  CHECK(fit_lines(text, 0) == text);
}
