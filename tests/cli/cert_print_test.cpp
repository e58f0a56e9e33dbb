// A certificate printed as an incoming inspection prints it (issue 28, point 3): headless
// Chromium prints page 4 to PDF and every sheet's text (pdftotext, page by page) carries the
// serial, the verdict and "page x of y"; a table continued on the next sheet repeats its header;
// no sheet holds a section's heading without what follows it. Fails when Chromium or pdftotext
// is missing (Debian packages chromium, poppler-utils: scripts/deps installs both).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <vector>
#include <unistd.h>

#include "cert.hpp"
#include "cert_fixture.hpp"
#include "temp_dir.hpp"

using namespace fogbench::cli;
using namespace fogbench::cli::test;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;
using fogbench::cli::testing::slurp;

bool has_program(const std::string& name) { return std::system(("command -v " + name + " >/dev/null 2>&1").c_str()) == 0; }

// The text of one printed page, its whitespace runs as one space.
std::string page_text(const std::string& pdf, int page, const std::string& out) {
  const std::string cmd = "pdftotext -f " + std::to_string(page) + " -l " + std::to_string(page) + " " + pdf + " " + out;
  REQUIRE(std::system(cmd.c_str()) == 0);
  return std::regex_replace(slurp(out), std::regex("\\s+"), " ");
}

int page_count(const std::string& pdf, const std::string& out) {
  REQUIRE(std::system(("pdfinfo " + pdf + " >" + out).c_str()) == 0);
  std::smatch m;
  const std::string info = slurp(out);
  REQUIRE(std::regex_search(info, m, std::regex("Pages:\\s+(\\d+)")));
  return std::stoi(m[1]);
}

}  // namespace

TEST_CASE("fogctl cert: page 4 printed by Chromium carries serial, verdict and page x of y on every sheet, headers repeated, no heading alone", "[cli][cert][print]") {
  if (!has_program("chromium")) FAIL("chromium not found (Debian package: chromium): the printed certificate cannot be checked");
  if (!has_program("pdftotext") || !has_program("pdfinfo"))
    FAIL("pdftotext/pdfinfo not found (Debian package: poppler-utils): the printed certificate cannot be checked");
  Dir dir;
  // 70 verifications: their table runs over more than one A4 sheet.
  const auto c = one_verdict_cert("FOG-4242", "pass", 70);
  const std::string html = dir.file("c.html"), pdf = dir.file("c.pdf");
  std::ofstream(html, std::ios::binary) << certificate_html(c);
  const std::string cmd = "timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-background-networking "
                          "--disable-component-update --disable-sync --no-first-run --user-data-dir=" + dir.file("profile") +
                          " --no-pdf-header-footer --print-to-pdf=" + pdf + " file://" + html + " >" + dir.file("o") + " 2>" +
                          dir.file("e");
  REQUIRE(std::system(cmd.c_str()) == 0);
  REQUIRE(fs::exists(pdf));
  const int pages = page_count(pdf, dir.file("info"));
  REQUIRE(pages >= 2);
  int continued_tables = 0;
  for (int p = 1; p <= pages; ++p) {
    const std::string text = page_text(pdf, p, dir.file("p" + std::to_string(p) + ".txt"));
    INFO("page " << p << " of " << pages << ": " << text.substr(0, 3000));
    CHECK(text.find("FOG-4242") != std::string::npos);
    CHECK(text.find("QUALIFIED (pass)") != std::string::npos);
    CHECK(text.find("page " + std::to_string(p) + " of " + std::to_string(pages)) != std::string::npos);
    CHECK(text.find("SHA-256 " + c["sha256"].get<std::string>().substr(0, 16)) != std::string::npos);
    // A sheet that continues the verifications' table starts it with its header again.
    if (p > 1 && text.find("compensated std / raw std") != std::string::npos &&
        text.find("Verifications of this model") == std::string::npos) {
      ++continued_tables;
      CHECK(text.find("run check value limit rule met") != std::string::npos);
    }
    // No section heading is the last thing on its sheet (before the margins' text).
    for (const std::string heading : {"How the verdict was decided", "Verifications of this model (evidence)",
                                      "Allan deviation of the compensated output (IEEE Std 952 Annex C)", "Runs", "Integrity"}) {
      const auto at = text.find(heading);
      if (at == std::string::npos) continue;
      std::string after = text.substr(at + heading.size());
      for (const std::string& margin : std::vector<std::string>{"page " + std::to_string(p) + " of " + std::to_string(pages), "Certificate of qualification FOG-4242: QUALIFIED (pass)",
                                       "SHA-256 " + c["sha256"].get<std::string>().substr(0, 16) + "..."})
        if (const auto m = after.find(margin); m != std::string::npos) after.erase(m, margin.size());
      CHECK(std::regex_replace(after, std::regex(" "), "").size() > 10);
    }
  }
  CHECK(continued_tables >= 1);
}

TEST_CASE("fogctl cert: page 7 printed by Chromium keeps the run's 12-digit git hash on one line and shows each axis", "[cli][cert][print]") {
  if (!has_program("chromium")) FAIL("chromium not found (Debian package: chromium): the printed certificate cannot be checked");
  if (!has_program("pdftotext") || !has_program("pdfinfo"))
    FAIL("pdftotext/pdfinfo not found (Debian package: poppler-utils): the printed certificate cannot be checked");
  Dir dir;
  const auto c = three_axis_cert("FOG-3X");
  const std::string html = dir.file("c.html"), pdf = dir.file("c.pdf");
  std::ofstream(html, std::ios::binary) << certificate_html(c);
  const std::string cmd = "timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-background-networking "
                          "--disable-component-update --disable-sync --no-first-run --user-data-dir=" + dir.file("profile") +
                          " --no-pdf-header-footer --print-to-pdf=" + pdf + " file://" + html + " >" + dir.file("o") + " 2>" +
                          dir.file("e");
  REQUIRE(std::system(cmd.c_str()) == 0);
  REQUIRE(fs::exists(pdf));
  std::string all;
  for (int p = 1, pages = page_count(pdf, dir.file("info")); p <= pages; ++p)
    all += page_text(pdf, p, dir.file("p" + std::to_string(p) + ".txt")) + " ";
  INFO(all);
  // The hash whole: a hash broken over two lines reads "62756e98 5c7e" (page 6 broke it so).
  CHECK(all.find("62756e985c7e") != std::string::npos);
  CHECK(all.find("Axes (three-axis unit") != std::string::npos);
  CHECK(all.find("NOT QUALIFIED (fail)") != std::string::npos);
}
