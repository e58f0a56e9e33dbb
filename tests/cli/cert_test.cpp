// fogctl cert --check without a daemon (issue 24, point 2): a certificate (JSON or the printable
// HTML that embeds it) signed by the station's key is valid with --key station.pub (exit 0); a
// field changed (its SHA-256 recomputed or not), a signature changed or taken from another key,
// the HTML's visible table edited: exit 1; no key, an unknown key, an unsigned certificate, a
// file without a certificate: exit 2. Keyrings (a file of several keys, a folder, --key given
// twice) and revocation lists. The HTML's print stylesheet fits A4 and Letter.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "cert.hpp"
#include "cert_fixture.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/signing/signing.hpp"
#include "temp_dir.hpp"

using namespace fogbench;
using namespace fogbench::cli;
using namespace fogbench::cli::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

using fogbench::cli::testing::Dir;

const signing::SigningKey& other_key() {
  static const signing::SigningKey k = *signing::SigningKey::generate();
  return k;
}

json signed_cert(const signing::SigningKey& key = station_key()) {
  json c = unsigned_cert();
  REQUIRE(signing::sign_certificate(c, key, c["station_id"]).has_value());
  return c;
}

struct Result {
  int code;
  std::string out, err;
};
Result check(const std::string& file, std::vector<std::string> keys = {}, const std::string& revoked = "", bool as_json = false) {
  CertOptions o;
  o.check = file;
  o.keys = std::move(keys);
  o.revoked = revoked;
  o.daemon.json_out = as_json;
  o.daemon.socket = "/nonexistent/fogbench-test.sock";  // no daemon: offline
  std::ostringstream out, err;
  const int code = run_cert(o, out, err);
  return {code, out.str(), err.str()};
}
bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

}  // namespace

TEST_CASE("fogctl cert --check --key: valid offline, every alteration exit 1, no key or an unknown one exit 2", "[cli][cert]") {
  Dir d;
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const std::string other_pub = d.write("other.pub", other_key().public_key().pem());
  const json c = signed_cert();
  const std::string file = d.write("c.json", c.dump());

  auto ok = check(file, {pub});
  CHECK(ok.code == 0);
  CHECK(has(ok.out, "VALID"));
  CHECK(has(ok.out, station_key().key_id().substr(0, 16)));
  CHECK(has(ok.out, "not asked"));
  // Whitespace does not matter (the signature is over the canonical form), content does.
  CHECK(check(d.write("pretty.json", c.dump(2)), {pub}).code == 0);
  auto j = json::parse(check(file, {pub}, "", true).out);
  CHECK(j["valid"] == true);
  CHECK(j["status"] == "valid");
  CHECK(j["key_id"] == station_key().key_id());

  // A digit of a coefficient changed in the file: altered.
  std::string text = c.dump();
  const auto at = text.find("-8.0123");
  REQUIRE(at != std::string::npos);
  text[at + 6] = '4';  // -8.0124
  auto bad = check(d.write("altered.json", text), {pub});
  CHECK(bad.code == 1);
  CHECK(has(bad.out, "ALTERED"));

  // A forgery: the verdict changed and the SHA-256 recomputed (what passed before issue 24).
  json forged = c;
  forged["verdict"] = "fail";
  forged["sha256"] = signing::content_sha256(forged);
  auto f = check(d.write("forged.json", forged.dump()), {pub});
  CHECK(f.code == 1);
  CHECK(has(f.out, "BAD SIGNATURE"));

  // Signature bytes changed.
  json flipped = c;
  std::string sig = flipped["signature"];
  sig[20] = sig[20] == 'x' ? 'y' : 'x';
  flipped["signature"] = sig;
  CHECK(check(d.write("flipped.json", flipped.dump()), {pub}).code == 1);
  json cut = c;
  cut["signature"] = "AAAA";
  CHECK(check(d.write("cut.json", cut.dump()), {pub}).code == 1);

  // The signature of another key over the same content: bad signature with the key id left,
  // an unknown key when the forger names his own.
  json other = c;
  other["signature"] = signed_cert(other_key())["signature"];
  CHECK(check(d.write("other-sig.json", other.dump()), {pub}).code == 1);
  auto theirs = check(d.write("theirs.json", signed_cert(other_key()).dump()), {pub});
  CHECK(theirs.code == 2);
  CHECK(has(theirs.out, "none of the keys given"));

  // A wrong key: cannot tell; no key and no daemon: cannot tell, saying to give --key.
  CHECK(check(file, {other_pub}).code == 2);
  auto none = check(file);
  CHECK(none.code == 2);
  CHECK(has(none.out, "--key"));
  // A missing key file, a private key for a public one: exit 2 naming the file.
  auto missing = check(file, {(d.path / "nope.pub").string()});
  CHECK(missing.code == 2);
  CHECK(has(missing.err, "nope.pub"));
  auto priv = check(file, {d.write("station.key", station_key().private_pem())});
  CHECK(priv.code == 2);
  CHECK(has(priv.err, "a private key"));

  // An unsigned certificate of before issue 24 (only a SHA-256): cannot tell, never valid.
  json old = unsigned_cert();
  old["sha256"] = signing::content_sha256(old);
  auto o = check(d.write("old.json", old.dump()), {pub});
  CHECK(o.code == 2);
  CHECK(has(o.out, "unsigned"));

  CHECK(check(d.write("empty.json", ""), {pub}).code == 2);
  CHECK(check(d.write("other.json", R"({"a":1})"), {pub}).code == 2);
  CHECK(check(d.write("nohash.json", R"({"format":"fogbench.certificate"})"), {pub}).code == 2);
  CHECK(check((d.path / "missing.json").string(), {pub}).code == 2);
}

TEST_CASE("fogctl cert --check: keyrings (several --key, a file of keys, a folder) and revoked keys", "[cli][cert]") {
  Dir d;
  const json c = signed_cert();
  const std::string file = d.write("c.json", c.dump());
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const std::string other_pub = d.write("other.pub", other_key().public_key().pem());
  CHECK(check(file, {other_pub, pub}).code == 0);
  CHECK(check(file, {d.write("ring.pem", other_key().public_key().pem() + station_key().public_key().pem())}).code == 0);
  fs::create_directories(d.path / "keys");
  std::ofstream(d.path / "keys" / "2026-11.pub") << station_key().public_key().pem();
  std::ofstream(d.path / "keys" / "2025-01.pub") << other_key().public_key().pem();
  CHECK(check(file, {(d.path / "keys").string()}).code == 0);

  // Revoked after the certificate's date: still valid, said; revoked before: not valid.
  auto later = check(file, {pub}, d.write("later.txt", station_key().key_id() + " 2026-12-01 rotated\n"));
  CHECK(later.code == 0);
  CHECK(has(later.out, "revoked on 2026-12-01"));
  auto before = check(file, {pub}, d.write("before.txt", "# stolen\n" + station_key().key_id() + " 2026-11-20T00:00:00Z stolen laptop\n"));
  CHECK(before.code == 1);
  CHECK(has(before.out, "stolen laptop"));
  auto broken = check(file, {pub}, d.write("broken.txt", "deadbeef 2026-01-01\n"));
  CHECK(broken.code == 2);
  CHECK(has(broken.err, "broken.txt:1"));
}

TEST_CASE("fogctl cert: the HTML is drawn from the signed JSON, --check compares its visible tables, it survives </script> and prints on A4 and Letter", "[cli][cert]") {
  Dir d;
  const json c = signed_cert();
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const std::string html = certificate_html(c);
  CHECK(html.find("@page") != std::string::npos);
  CHECK(html.find("max-width:170mm") != std::string::npos);
  CHECK(html.find("@media print") != std::string::npos);
  CHECK(has(html, station_key().key_id()));
  CHECK(has(html, "--key station.pub"));
  // The value's "</script>" is kept out of the page's markup.
  CHECK(html.find("line </script> 2") == std::string::npos);
  auto back = certificate_from_text(html);
  REQUIRE(back.has_value());
  CHECK(*back == c);
  auto ok = check(d.write("c.html", html), {pub});
  CHECK(ok.code == 0);
  CHECK(has(ok.out, "visible page matches"));

  // The visible table edited, the embedded JSON left: what a reader sees is not what was signed.
  std::string visible = html;
  const auto shown = visible.find("<td>-8.0123</td>");
  REQUIRE(shown != std::string::npos);
  REQUIRE(shown < visible.find("application/json"));
  visible.replace(shown, 16, "<td>-1.0123</td>");
  auto v = check(d.write("visible.html", visible), {pub});
  CHECK(v.code == 1);
  CHECK(has(v.out, "EDITED"));
  CHECK(has(v.out, "-1.0123"));
  // A verdict changed in the visible text only.
  std::string verdict = html;
  const auto pass = verdict.find("class=\"pass\">pass<");
  REQUIRE(pass != std::string::npos);
  verdict.replace(pass, 18, "class=\"pass\">PASS<");
  CHECK(check(d.write("verdict.html", verdict), {pub}).code == 1);
  // Something added after the embedded JSON is visible too.
  std::string tail = html;
  tail.insert(tail.rfind("</body>"), "<p>Approved by QA</p>");
  CHECK(check(d.write("tail.html", tail), {pub}).code == 1);

  // The embedded JSON edited: a bad signature, whatever the page shows.
  std::string edited = html;
  const auto at = edited.find("-8.0123", edited.find("application/json"));
  REQUIRE(at != std::string::npos);
  edited[at + 3] = '9';
  CHECK(check(d.write("edited.html", edited), {pub}).code == 1);

  // A page of another renderer: its tables cannot be compared, so cannot tell (2), saying why.
  std::string foreign = html;
  const auto meta = foreign.find("fogbench-certificate-page 2");
  REQUIRE(meta != std::string::npos);
  foreign.replace(meta, 27, "fogbench-certificate-page 1");
  auto fo = check(d.write("foreign.html", foreign), {pub});
  CHECK(fo.code == 2);
  CHECK(has(fo.out, "NOT checked"));

  CHECK(check(d.write("plain.html", "<html><body>no certificate</body></html>"), {pub}).code == 2);
  CHECK(check(d.write("cut.html", html.substr(0, html.find("</script>"))), {pub}).code == 2);
}

TEST_CASE("fogctl cert: a one-verdict certificate (page 4) shows the rule that decided it, a plan's failure is no certificate of qualification, and its visible verdict is checked", "[cli][cert]") {
  Dir d;
  json c = unsigned_cert();
  c.erase("verdicts");
  c["verdict"] = "fail";
  c["verifications"] = json::array({{{"run_id", 2}, {"verification_id", 1},
                                     {"checks", {{{"check", "compensated std / raw std"}, {"value", 0.12}, {"limit", 0.2},
                                                  {"rule", "value < limit"}, {"met", true}}}}}});
  c["qualification"] = {{"verdict_id", 4}, {"serial", "FOG-1"}, {"verdict", "fail"}, {"rule", "plan"},
                        {"plan", {{"id", 7}, {"name", "strict"}, {"sha256", std::string(64, 'a')}}},
                        {"run_id", 2}, {"unit", 0}, {"model_id", 1}, {"decided_at", "2026-11-27 10:00:00"},
                        {"limits", {{{"limit", "comp_raw < 0.05"}, {"line", 3}, {"value", 0.12}, {"met", false},
                                     {"on_fail", "stop"}, {"run_id", 2}}}},
                        {"reasons", {"step 2 (verify, run 2): comp_raw = 0.12, limit comp_raw < 0.05 (line 3)"}}};
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const std::string html = certificate_html(c);
  CHECK(has(html, "fogbench-certificate-page 6"));
  CHECK_FALSE(has(html, "Certificate of qualification"));
  CHECK(has(html, "<title>Qualification record FOG-1: NOT QUALIFIED (fail)</title>"));
  CHECK(has(html, "NOT QUALIFIED"));
  CHECK(has(html, "plan strict (plan 7"));
  CHECK(has(html, "<td>comp_raw &lt; 0.05</td><td>3</td><td>0.12</td><td>no</td>"));
  CHECK(has(html, "limit comp_raw &lt; 0.05 (line 3)"));
  auto ok = check(d.write("c.html", html), {pub});
  CHECK(ok.code == 0);
  // The visible verdict turned into a pass, the signed JSON left as it was: edited, exit 1.
  std::string v = html;
  const auto at = v.find(">fail<");
  REQUIRE(at != std::string::npos);
  v.replace(at, 6, ">pass<");
  CHECK(check(d.write("v.html", v), {pub}).code == 1);
  // The plan's limit line edited in the page only: edited too.
  std::string l = html;
  const auto lim = l.find("<td>comp_raw &lt; 0.05</td>");
  REQUIRE(lim != std::string::npos);
  l.replace(lim, 27, "<td>comp_raw &lt; 0.50</td>");
  CHECK(check(d.write("l.html", l), {pub}).code == 1);

  // The same facts with a pass: a certificate of qualification.
  c["verdict"] = "pass";
  c["qualification"]["verdict"] = "pass";
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  CHECK(has(certificate_html(c), "Certificate of qualification: FOG-1"));
}

TEST_CASE("fogctl cert: page 4 prints serial, verdict and page x of y in every page's margins, repeats table headers, keeps sections whole, and a page 3 issued before it still checks", "[cli][cert]") {
  Dir d;
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const json c = one_verdict_cert("FOG-7", "pass", 3);
  const std::string html = certificate_html(c);
  CHECK(has(html, "fogbench-certificate-page 6"));  // page 4's print furniture, kept by page 6
  CHECK(has(html, "<title>Certificate of qualification FOG-7: QUALIFIED (pass)</title>"));
  CHECK(has(html, "@top-left{content:\"Certificate of qualification FOG-7: QUALIFIED (pass)\""));
  CHECK(has(html, "counter(page) \" of \" counter(pages)"));
  CHECK(has(html, "SHA-256 " + c["sha256"].get<std::string>().substr(0, 16)));
  CHECK(has(html, "<table><thead><tr><th>term</th>"));
  CHECK_FALSE(has(html, "<table><tr>"));  // every table's header repeats on a continued page
  CHECK(has(html, "section{break-inside:avoid}"));
  CHECK(check(d.write("p4.html", html), {pub}).code == 0);

  // The page as layout 3 drew it (issued before page 4): no print furniture, and it still checks.
  const std::string p3 = certificate_html(c, 3);
  CHECK(has(p3, "fogbench-certificate-page 3"));
  CHECK_FALSE(has(p3, "counter(pages)"));
  CHECK(has(p3, "<title>Certificate FOG-7</title>"));
  auto ok3 = check(d.write("p3.html", p3), {pub});
  CHECK(ok3.code == 0);
  CHECK(has(ok3.out, "visible page matches"));
  // ... and an edit of it is still seen, compared with page 3 (not with page 4).
  std::string e3 = p3;
  e3.replace(e3.find("<title>Certificate FOG-7"), 24, "<title>Certificate FOG-8");
  CHECK(check(d.write("e3.html", e3), {pub}).code == 1);
  // A page claiming a layout this fogctl never drew: cannot tell.
  std::string p9 = html;
  p9.replace(p9.find("fogbench-certificate-page 6"), 27, "fogbench-certificate-page 9");
  CHECK(check(d.write("p9.html", p9), {pub}).code == 2);

  // A serial that would close the <style> element or the CSS string: escaped in the margins.
  const json evil = one_verdict_cert("X\"}</style><b>", "fail", 1);
  const std::string eh = certificate_html(evil);
  CHECK(has(eh, "content:\"Qualification record X\\22 }\\3c /style\\3e \\3c b\\3e : NOT QUALIFIED (fail)\""));
  CHECK(eh.find("</style>") == eh.rfind("</style>"));  // the one that closes the stylesheet
  CHECK(check(d.write("evil.html", eh), {pub}).code == 0);
}

TEST_CASE("fogctl cert: a certificate with the scale factor over temperature draws page 5 with its tables, checks, and an edit of its figures is seen, one without stays page 4", "[cli][cert]") {
  Dir d;
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  const json plain = one_verdict_cert("FOG-7", "pass", 1);
  CHECK(has(certificate_html(plain), "fogbench-certificate-page 6"));  // no rate steps: no section
  CHECK_FALSE(has(certificate_html(plain), "Scale factor"));

  json c = one_verdict_cert("FOG-7", "pass", 1);
  c["scale_factor"] = json::array(
      {{{"run_id", 10}, {"role", "fit"}, {"settle_s", 5.0}, {"t0_c", 20.0}, {"sf0", 1.000012},
        {"tc_ppm_per_c", {{"value", -12.34}, {"sigma", 0.41}}},
        {"temp_rate_ppm_per_c_per_min", {{"value", nullptr}, {"note", "needs at least 4 plateaus"}}},
        {"model_form", {{"sf0", 1.000012}, {"k1_ppm_per_c", {{"value", -12.34}, {"sigma", 0.41}}},
                        {"k2_ppm_per_c2", {{"value", 0.021}, {"sigma", 0.003}}}, {"rms_ppm", 0.8}}},
        {"plateaus", {{{"plateau", 1}, {"coil_c", -20.0}, {"scale_factor", 1.0004}, {"sigma", 1e-6}, {"bias_dph", -8.1},
                       {"nonlinearity_ppm", 31.0}, {"asymmetry_ppm", 19.5}}}}},
       {{"run_id", 11}, {"role", "verify"}, {"error", "plateau 2: no negative input rate"}}});
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  const std::string html = certificate_html(c);
  CHECK(has(html, "fogbench-certificate-page 6"));
  CHECK(has(html, "Scale factor over temperature (IEEE Std 952)"));
  CHECK(has(html, "<td>10</td><td>fit</td><td>1.000012</td><td>-12.34 +- 0.41</td><td>not identified (needs at least 4 plateaus)</td>"));
  CHECK(has(html, "k2 0.021 +- 0.003 ppm/degC^2, T0 20 degC"));
  CHECK(has(html, "<td>10</td><td>1</td><td>-20</td><td>1.0004</td><td>1e-06</td><td>-8.1</td><td>31</td><td>19.5</td>"));
  CHECK(has(html, "no fit: plateau 2: no negative input rate"));
  auto ok = check(d.write("sf.html", html), {pub});
  CHECK(ok.code == 0);
  CHECK(has(ok.out, "visible page matches"));
  // The sensitivity edited in the page only: edited, exit 1.
  std::string e = html;
  e.replace(e.find("-12.34 +- 0.41"), 14, "-2.34 +- 0.41 ");
  CHECK(check(d.write("e.html", e), {pub}).code == 1);
  // As page 4 drew it (a fogctl before page 5): without the section, and it still checks.
  const std::string p4 = certificate_html(c, 4);
  CHECK_FALSE(has(p4, "Scale factor"));
  CHECK(check(d.write("p4.html", p4), {pub}).code == 0);
  // As page 5 drew it (a fogctl before page 6): with the section, and it still checks.
  const std::string p5 = certificate_html(c, 5);
  CHECK(has(p5, "fogbench-certificate-page 5"));
  CHECK(has(p5, "Scale factor over temperature (IEEE Std 952)"));
  CHECK(check(d.write("p5.html", p5), {pub}).code == 0);
  // The JSON: its signature covers the figures.
  json altered = c;
  altered["scale_factor"][0]["tc_ppm_per_c"]["value"] = -2.34;
  std::ofstream(d.file("a.json")) << altered.dump();
  CHECK(check(d.file("a.json"), {pub}).code == 1);
}

TEST_CASE("fogctl cert: page 6 draws a run's end as date and time to the second and names an empty station or operator, and a page 4 issued before it still checks", "[cli][cert]") {
  Dir d;
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  json c = one_verdict_cert("FOG-7", "marginal", 1);
  // A station without a station.id and a run whose operator was not recorded, as the demo's.
  c["station_id"] = "";
  c["runs"] = json::array({{{"id", 10}, {"role", "fit"}, {"profile", "exp1"}, {"ended_at", "2026-11-29T13:44:50.889Z"},
                            {"identity", {{"station_id", ""}, {"operator", ""}, {"software_version", "0.1.0"},
                                          {"git_hash", "62756e985c7e4dfb"}}}}});
  REQUIRE(signing::sign_certificate(c, station_key(), c["station_id"]).has_value());
  const std::string html = certificate_html(c);
  CHECK(has(html, "fogbench-certificate-page 6"));
  // The end as date and time (one break between them in a narrow column, never inside either),
  // the station and the operator named: no empty cell.
  CHECK(has(html, "<td>exp1</td><td>2026-11-29 13:44:50Z</td><td>not configured</td><td>not recorded</td>"));
  CHECK_FALSE(has(html, "<td></td>"));
  CHECK(has(html, "by a station without a station.id with fogbench 0.1.0"));
  CHECK(has(html, "Signed (Ed25519) by a station without a station.id with key "));
  CHECK_FALSE(has(html, "by station  with"));
  auto ok = check(d.write("p6.html", html), {pub});
  CHECK(ok.code == 0);
  CHECK(has(ok.out, "visible page matches"));
  // An operator written into the page only: edited, exit 1.
  std::string e = html;
  e.replace(e.find("<td>not recorded</td>"), 21, "<td>A. N. Other</td>");
  CHECK(check(d.write("e.html", e), {pub}).code == 1);
  // The same certificate as page 4 drew it, byte for byte as issued: its empty cells and its
  // full timestamp, and it still checks.
  const std::string p4 = certificate_html(c, 4);
  CHECK(has(p4, "<td>exp1</td><td>2026-11-29T13:44:50.889Z</td><td></td><td></td>"));
  CHECK(has(p4, "by station  with fogbench"));
  CHECK(check(d.write("p4.html", p4), {pub}).code == 0);
}

TEST_CASE("fogctl cert: a three-axis unit's certificate draws page 7 with a table of its axes, a forged axis entry fails the check, and a one-axis one stays page 6", "[cli][cert]") {
  Dir d;
  const std::string pub = d.write("station.pub", station_key().public_key().pem());
  CHECK(has(certificate_html(one_verdict_cert("FOG-7", "pass", 1)), "fogbench-certificate-page 6"));  // one axis: as before
  const json c = three_axis_cert("FOG-3X");
  const std::string html = certificate_html(c);
  CHECK(has(html, "fogbench-certificate-page 7"));
  CHECK(has(html, "Axes (three-axis unit: the verdict is the worst axis')"));
  CHECK(has(html, "<td>x</td><td>pass</td><td>1</td><td>1 (version 1, paper)</td>"));
  CHECK(has(html, "<td>y</td><td>fail</td><td>2</td><td>2 (version 2, paper)</td><td>d(T1)@600 + grad@600</td>"
                  "<td>step 2 (exp2, run 11): comp_raw = 0.821, limit comp_raw &lt; 0.2 (line 4)</td>"));
  CHECK(has(html, "<td>axis y: comp_raw &lt; 0.2</td>"));  // the decision's limits name their axis
  // The runs' table gives the software its width, the hash breaking only from its version.
  CHECK(has(html, "<table class=\"runs\"><colgroup>"));
  CHECK(has(html, ".runs td:last-child{overflow-wrap:normal}"));
  CHECK(has(html, "<td>0.1.0 62756e985c7e</td>"));
  auto ok = check(d.write("p7.html", html), {pub});
  CHECK(ok.code == 0);
  CHECK(has(ok.out, "visible page matches"));

  // A forged axis entry in the signed JSON: y made a pass (in the table, or in the decision's
  // evidence), its hash recomputed or not: altered, exit 1.
  for (const char* where : {"axes", "qualification"}) {
    json forged = c;
    json& entry = std::string(where) == "axes" ? forged["axes"][1] : forged["qualification"]["axes"][1];
    REQUIRE(entry["axis"] == "y");
    entry["verdict"] = "pass";
    std::ofstream(d.file("forged.json")) << forged.dump();
    INFO(where);
    CHECK(check(d.file("forged.json"), {pub}).code == 1);
    forged["sha256"] = signing::content_sha256(forged);
    std::ofstream(d.file("forged2.json")) << forged.dump();
    CHECK(check(d.file("forged2.json"), {pub}).code == 1);
  }
  // An axis left out of the JSON: altered too.
  json dropped = c;
  dropped["axes"].erase(1);
  std::ofstream(d.file("dropped.json")) << dropped.dump();
  CHECK(check(d.file("dropped.json"), {pub}).code == 1);
  // y's verdict edited in the visible page only: edited, exit 1.
  std::string e = html;
  const auto at = e.find("<td>y</td><td>fail</td>");
  REQUIRE(at != std::string::npos);
  e.replace(at, 23, "<td>y</td><td>pass</td>");
  CHECK(check(d.write("e.html", e), {pub}).code == 1);
  // The same content drawn as page 6 (without its axes table) does not check: cannot tell.
  const std::string p6 = certificate_html(c, 6);
  CHECK_FALSE(has(p6, "Axes (three-axis"));
  CHECK(check(d.write("p6.html", p6), {pub}).code == 2);
}
