// fogctl cert: see cert.hpp. The canonical form, its hash and the signature are
// fogbench::signing's (signing/include/fogbench/signing/certificate.hpp), shared with the daemon.
#include "cert.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string_view>

#include "common.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/signing/signing.hpp"
#include "run_identity.hpp"
#include "table.hpp"
#include "html.hpp"

namespace fogbench::cli {

using nlohmann::json;

namespace {

constexpr const char* kScriptOpen = "<script type=\"application/json\" id=\"fogbench-certificate\">";
// The page's layout version: --check compares a page's visible part only with a rendering of
// the same version (bumped whenever certificate_html changes what it draws), and draws a page of
// an earlier version as that version drew it, byte for byte, so an issued page keeps checking.
// Page 2: per-verification verdicts (certificates issued before issue 24, no `qualification`).
// Page 3 (issue 24, one verdict): the serial's verdict with the rule that decided it. Page 4
// (issue 28, point 3): page 3 as an incoming inspection prints it: the verdict in the title,
// serial, verdict and "page x of y" in every page's margins, table headers repeated on a page
// that continues a table, each section kept on one page when it fits (no heading or row alone).
// Page 5 (issue 29, point 2): page 4 with the scale factor over temperature, for a certificate
// that has `scale_factor` (a run with rate steps); one without it is still drawn as page 4, so
// its page is what it was.
// Page 6: page 4 or 5 (the scale factor's section when the
// certificate has one) with the runs' times as date and time to the second, which wrap at most
// once in their column (`2026-11-29 13:44:50Z`, not `2026-11-29T13:44:50.889Z` broken anywhere
// over three lines), and an empty station or operator named, never an empty cell or "by station
// with key".
// Page 7: page 6 for a three-axis unit's certificate (one that has `axes`): a section "Axes"
// with each axis' verdict in the serial's decision, its current model and its reasons, and the
// runs' table with the software column wide enough that the 12-digit git hash stays on one line
// (it broke over two on page 6). A certificate without `axes` (a one-axis unit's, or one issued
// before) is still drawn as page 6, and a three-axis certificate only as page 7: a page drawn
// without its axes table does not check.
constexpr int kPageLatest = 7;
bool one_verdict_layout(const json& cert) { return cert.contains("verifications") || cert.contains("qualification"); }
bool has_axes(const json& cert) { return cert.contains("axes") && cert["axes"].is_array() && !cert["axes"].empty(); }
int latest_page_of(const json& cert) {
  if (!one_verdict_layout(cert)) return 2;
  return has_axes(cert) ? 7 : 6;
}
// The lowest page this fogctl draws for this content: 2 before the one verdict, 7 with axes.
int first_page_of(const json& cert) {
  if (!one_verdict_layout(cert)) return 2;
  return has_axes(cert) ? 7 : 3;
}
std::string renderer_name(int page) { return "fogbench-certificate-page " + std::to_string(page); }
constexpr const char* kRendererMeta = "<meta name=\"generator\" content=\"";

std::string text_of(const json& v, int digits = 4) {
  if (v.is_null()) return "-";
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_number()) {
    const double x = v.get<double>();
    if (!std::isfinite(x)) return "-";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.*g", digits, x);
    return buf;
  }
  if (v.is_string()) return v.get<std::string>();
  return v.dump();
}

std::string field_text(const json& j, const char* key) { return j.contains(key) ? text_of(j[key]) : "-"; }

// A check's limit: the one stored with the verdict, or "limits not recorded" for a verdict
// stored before fogbench kept them (never today's configuration).
std::string cert_limit_text(const json& check) {
  if (check.contains("limit") && check["limit"].is_null() &&
      field_text(check, "rule").find("limits not recorded") != std::string::npos)
    return "limits not recorded";
  return check.contains("limit") ? text_of(check["limit"]) : "-";
}

// A4 is 210 x 297 mm, Letter 216 x 279 mm: 20 mm side margins leave 170 mm on A4, 176 on
// Letter; 18 mm top and bottom fit both heights. No width beyond 170 mm.
constexpr const char* kStyle = R"css(
@page{size:auto;margin:18mm 20mm}
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;color:#1d2430;max-width:170mm;margin:12px auto;font-size:10.5pt}
h1{font-size:16pt;margin:0 0 4px}h2{font-size:12pt;margin:16px 0 4px;border-bottom:1px solid #c8ced6}
table{border-collapse:collapse;width:100%;margin:4px 0 8px;font-size:9pt;table-layout:fixed}
th,td{border-bottom:1px solid #e0e4e9;padding:2px 4px;text-align:left;overflow-wrap:anywhere;vertical-align:top}
th{background:#f1f3f6}.sub{color:#5a6472}.hash{font-family:monospace;font-size:8pt;overflow-wrap:anywhere}
.pass{color:#1e6b24;font-weight:700}.fail{color:#b3261e;font-weight:700}
@media print{body{margin:0;max-width:none}h2{break-after:avoid}tr{break-inside:avoid}}
)css";

// `thead`: the header row in <thead>, which a printed page repeats on every sheet the table runs
// onto (page 4); pages 2 and 3 drew it as a plain first row.
std::string table(const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows, bool thead = false) {
  std::string s = thead ? "<table><thead><tr>" : "<table><tr>";
  for (const auto& h : head) s += "<th>" + html_escape(h) + "</th>";
  s += thead ? "</tr></thead>" : "</tr>";
  for (const auto& r : rows) {
    s += "<tr>";
    for (const auto& c : r) s += "<td>" + html_escape(c) + "</td>";
    s += "</tr>";
  }
  return s + "</table>";
}

std::string estimate_text(const json& e) {
  if (!e.is_object() || !e.contains("value") || e["value"].is_null())
    return "not visible" + (e.is_object() && e.contains("note") && !e["note"].get<std::string>().empty() ? " (" + e["note"].get<std::string>() + ")" : std::string());
  std::string s = text_of(e["value"]) + " (" + text_of(e["ci_low"]) + " .. " + text_of(e["ci_high"]) + ", tau " +
                  text_of(e["from_tau_s"]) + ".." + text_of(e["to_tau_s"]) + " s";
  // Certificates issued before the EDF was recorded have none: nothing is invented for them.
  if (e.contains("edf") && e["edf"].is_number()) s += ", EDF " + text_of(e["edf"]);
  if (e.contains("share") && e["share"].is_number()) s += ", " + fixed(100.0 * e["share"].get<double>(), 0) + " % of sigma^2";
  return s + ")";
}

// A scale-factor coefficient of the certificate: "12.3 +- 0.4" (1 sigma), or "not identified (why)".
std::string sf_coefficient_text(const json& c) {
  if (!c.is_object() || !c.contains("value") || c["value"].is_null())
    return "not identified" + (c.is_object() && c.contains("note") ? " (" + text_of(c["note"]) + ")" : std::string());
  return text_of(c["value"], 4) + " +- " + text_of(c["sigma"], 2);
}

// The rows of the scale-factor tables: per run, and per plateau.
std::vector<std::vector<std::string>> sf_run_rows(const json& cert) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& s : cert.value("scale_factor", json::array())) {
    if (s.contains("error")) {
      rows.push_back({field_text(s, "run_id"), field_text(s, "role"), "no fit: " + field_text(s, "error"), "", "", "", ""});
      continue;
    }
    const json& f = s["model_form"];
    rows.push_back({field_text(s, "run_id"), field_text(s, "role"), text_of(s["sf0"], 9), sf_coefficient_text(s["tc_ppm_per_c"]),
                    sf_coefficient_text(s["temp_rate_ppm_per_c_per_min"]),
                    "SF0 " + text_of(f["sf0"], 9) + ", k1 " + sf_coefficient_text(f["k1_ppm_per_c"]) + " ppm/degC, k2 " +
                        sf_coefficient_text(f["k2_ppm_per_c2"]) + " ppm/degC^2, T0 " + field_text(s, "t0_c") + " degC",
                    text_of(f["rms_ppm"], 3)});
  }
  return rows;
}
std::vector<std::vector<std::string>> sf_plateau_rows(const json& cert) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& s : cert.value("scale_factor", json::array()))
    for (const auto& p : s.value("plateaus", json::array()))
      rows.push_back({field_text(s, "run_id"), field_text(p, "plateau"), text_of(p["coil_c"], 4), text_of(p["scale_factor"], 9),
                      text_of(p["sigma"], 2), text_of(p["bias_dph"], 4), text_of(p["nonlinearity_ppm"], 3),
                      text_of(p["asymmetry_ppm"], 3)});
  return rows;
}
const std::vector<std::string> kSfRunHead = {"run", "role", "SF0", "temperature sensitivity, ppm/degC (1 sigma)",
                                              "temperature rate, ppm per degC/min", "model form SF0 (1 + k1 (T - T0) + k2 (T - T0)^2)",
                                              "model rms, ppm"};
const std::vector<std::string> kSfPlateauHead = {"run", "plateau", "coil, degC", "scale factor", "1 sigma", "bias, deg/h",
                                                 "nonlinearity, ppm", "asymmetry, ppm"};

// Who decided the verdict: "plan NAME (plan 7, text sha256 ab12...)" or "the station's analysis
// settings".
std::string decided_by_text(const json& q) {
  std::string by = verdict_by_text(q);
  if (q.value("rule", "") == "plan" && q.contains("plan") && q["plan"].is_object())
    by.insert(by.size() - 1, ", text sha256 " + field_text(q["plan"], "sha256").substr(0, 16) + "...");
  else
    by = "the station's " + by;
  return by;
}

// A judged limit as the verdict keeps it: a plan's "comp_raw < 0.05", an analysis check's
// "compensated std / raw std < 0.2".
std::string limit_text(const json& x) {
  // A three-axis unit's verdict judges each axis: its checks name the axis.
  if (x.contains("axis") && x["axis"].is_string()) {
    json one = x;
    one.erase("axis");
    return "axis " + x["axis"].get<std::string>() + ": " + limit_text(one);
  }
  if (x.contains("bound")) {  // an analysis check: {measurement, limit (the rule), bound}
    std::string rule = field_text(x, "limit");
    const std::string op = rule.find("<=") != std::string::npos ? "<=" : "<";
    return field_text(x, "measurement") + " " + op + " " + text_of(x["bound"]);
  }
  return field_text(x, "limit");
}

// Page 7's axes table: per axis its verdict as decided, the model it was decided on, its
// current model and the axis' reasons.
const std::vector<std::string> kAxesHead = {"axis", "verdict", "decided on model", "current model", "terms", "reasons"};
std::vector<std::vector<std::string>> axis_rows(const json& cert) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& a : cert.value("axes", json::array())) {
    if (!a.is_object()) continue;
    const json model = a.value("model", json(nullptr));
    std::string reasons;
    for (const auto& r : a.value("reasons", json::array())) reasons += (reasons.empty() ? "" : "; ") + text_of(r);
    rows.push_back({field_text(a, "axis"), field_text(a, "verdict"), field_text(a, "decided_on_model"),
                    model.is_object() ? field_text(model, "id") + " (version " + field_text(model, "version") + ", " +
                                            field_text(model, "method") + ")"
                                      : std::string("none"),
                    model.is_object() ? field_text(model, "terms") : std::string("-"), reasons.empty() ? "-" : reasons});
  }
  return rows;
}

int print_summary(const json& cert, std::ostream& out) {
  const json& m = cert["model"];
  out << "certificate of " << field_text(cert, "serial") << ": " << field_text(cert, "verdict") << "\n  model " << field_text(m, "id") << " version "
      << field_text(m, "version") << " (" << field_text(m, "method") << "): " << field_text(m, "terms") << "\n  issued " << field_text(cert, "issued_at")
      << " by station " << field_text(cert, "station_id") << ", fogbench " << field_text(cert["software"], "version") << " ("
      << field_text(cert["software"], "git_hash") << ")\n  sha256 " << field_text(cert, "sha256") << "\n";
  if (cert.contains("signed_by") && cert["signed_by"].is_object())
    out << "  signed (ed25519) by station " << field_text(cert["signed_by"], "station_id") << ", key "
        << field_text(cert["signed_by"], "key_id") << "\n";
  else
    out << "  UNSIGNED (issued before fogbench signed certificates)\n";
  Table c({"term", "value", "1 sigma", "unit"});
  for (const auto& t : m["coefficients"]) c.add({field_text(t, "term"), text_of(t["value"], 6), text_of(t["sigma"], 3), field_text(t, "unit")});
  out << c.str();
  if (!one_verdict_layout(cert)) {  // issued before issue 24: each verification's own verdict
    Table v({"run", "check", "value", "limit", "pass", "verdict"});
    for (const auto& x : cert.value("verdicts", json::array()))
      for (const auto& k : x["checks"]) v.add({field_text(x, "run_id"), field_text(k, "check"), text_of(k["value"]), cert_limit_text(k), text_of(k["pass"]), field_text(x, "verdict")});
    out << v.str();
    return kExitOk;
  }
  const json& q = cert["qualification"];
  if (q.is_object()) {
    out << "  decided by " << decided_by_text(q) << " on " << field_text(q, "decided_at") << " (run " << field_text(q, "run_id") << ")\n";
    if (q.contains("note")) out << "  " << field_text(q, "note") << "\n";
    Table l({"limit", "line", "value", "met", "on fail", "run"});
    for (const auto& x : q.value("limits", json::array()))
      l.add({limit_text(x), field_text(x, "line"), text_of(x["value"]), text_of(x.value("met", json(nullptr))), field_text(x, "on_fail"), field_text(x, "run_id")});
    out << l.str();
    for (const auto& r : q.value("reasons", json::array())) out << "  " << text_of(r) << "\n";
  } else {
    out << "  no verdict decided on this model\n";
  }
  if (has_axes(cert)) {
    out << "  axes (three-axis unit: the verdict is the worst axis')\n";
    Table a(kAxesHead);
    for (auto& r : axis_rows(cert)) a.add(r);
    out << a.str();
  }
  if (cert.contains("scale_factor")) {
    out << "  scale factor over temperature (IEEE Std 952)\n";
    Table s(kSfRunHead);
    for (auto& r : sf_run_rows(cert)) s.add(r);
    out << s.str();
    Table p(kSfPlateauHead);
    for (auto& r : sf_plateau_rows(cert)) p.add(r);
    out << p.str();
  }
  return kExitOk;
}

// A text as a CSS string's content ("..."): quotes, backslashes, '<' (which could end the
// <style> element) and control characters as CSS escapes.
std::string css_string(std::string_view text) {
  std::string s = "\"";
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\' || c == '<' || c == '>' || c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\%x ", static_cast<unsigned>(c));
      s += buf;
    } else {
      s += ch;
    }
  }
  return s + "\"";
}

// Page 6's run time: "2026-11-29T13:44:50.889Z" as "2026-11-29 13:44:50Z" (its one break
// between date and time); another text as it is.
std::string run_time_text(const std::string& ts) {
  const bool iso = ts.size() >= 20 && ts[4] == '-' && ts[7] == '-' && ts[10] == 'T' && ts[13] == ':' && ts[16] == ':' &&
                   ts.back() == 'Z';
  return iso ? ts.substr(0, 10) + " " + ts.substr(11, 8) + "Z" : ts;
}

// Page 6's name of who or where: the text, or `none` when it is empty.
std::string named_or(const std::string& text, const char* none) { return text.empty() ? std::string(none) : text; }

// Page 7's runs table: fixed column widths (percent of the table) that give the software cell
// room for the version and the 12-digit hash, which then breaks only between the two.
std::string runs_table_p7(const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows) {
  static constexpr int kWidthPct[] = {7, 8, 11, 14, 14, 14, 10, 22};
  std::string s = "<table class=\"runs\"><colgroup>";
  for (const int w : kWidthPct) s += "<col style=\"width:" + std::to_string(w) + "%\">";
  s += "</colgroup>";
  return s + table(head, rows, true).substr(std::string("<table>").size());
}

std::string render_certificate(const json& cert, int page) {
  // Page 4 keeps each section on one sheet when it fits (a <section> per heading) and repeats
  // each table's header row on the sheets it runs onto.
  const std::string h2 = page >= 4 ? "</section><section><h2>" : "<h2>";
  auto tbl = [page](const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows) {
    return table(head, rows, page >= 4);
  };
  const json& m = cert["model"];
  const std::string verdict = field_text(cert, "verdict");
  std::string b;
  const bool v3 = page >= 3;
  if (!v3 || verdict == "pass")
    b += "<h1>Certificate of qualification: " + html_escape(field_text(cert, "serial")) + "</h1>";
  else  // a unit that did not pass gets no certificate of qualification, only its record
    b += "<h1>Qualification record: " + html_escape(field_text(cert, "serial")) + " (NOT QUALIFIED)</h1>";
  // Page 6: a station without a station.id said so, not "by station  with".
  auto station_text = [page](const std::string& id) {
    return page >= 6 && id.empty() ? std::string("a station without a station.id") : "station " + id;
  };
  b += "<div class=\"sub\">Thermal drift model, version " + html_escape(field_text(m, "version")) + ", issued " + html_escape(field_text(cert, "issued_at")) +
       " by " + html_escape(station_text(field_text(cert, "station_id"))) + " with fogbench " + html_escape(field_text(cert["software"], "version")) + " (" +
       html_escape(field_text(cert["software"], "git_hash")) + ")</div>";
  b += "<p>Verdict: <span class=\"" + std::string(verdict == "pass" ? "pass" : "fail") + "\">" + html_escape(verdict) + "</span></p>";
  b += h2 + "Model coefficients (1 sigma)</h2><p class=\"sub\">" + html_escape(field_text(m, "terms")) + " (" + html_escape(field_text(m, "method")) +
       " method), noise std sigma_a " + html_escape(text_of(m["sigma_a_dph"])) + " deg/h</p>";
  std::vector<std::vector<std::string>> rows;
  for (const auto& t : m["coefficients"])
    rows.push_back({field_text(t, "term"), text_of(t["value"], 6), text_of(t["sigma"], 3), field_text(t, "unit"), text_of(t["lag_s"])});
  b += tbl({"term", "value", "1 sigma", "unit", "lag, s"}, rows);
  if (!v3) {
    b += h2 + "Verdicts</h2>";
    rows.clear();
    for (const auto& x : cert.value("verdicts", json::array()))
      for (const auto& k : x["checks"])
        rows.push_back({field_text(x, "run_id"), field_text(k, "check"), text_of(k["value"]), cert_limit_text(k), field_text(k, "rule"), text_of(k["pass"]), field_text(x, "verdict")});
    b += rows.empty() ? "<p>No verification of this model.</p>" : tbl({"run", "check", "value", "limit", "rule", "pass", "verdict"}, rows);
  } else {
    // The one verdict: who decided it, by which limits, on what; then the evidence.
    const json& q = cert["qualification"];
    b += h2 + "How the verdict was decided</h2>";
    if (!q.is_object()) {
      b += "<p>No verdict was decided on this model: it has not been verified.</p>";
    } else {
      b += "<p>Decided by " + html_escape(decided_by_text(q)) + " on " + html_escape(field_text(q, "decided_at")) + ", run " +
           html_escape(field_text(q, "run_id")) + ".</p>";
      if (q.contains("note")) b += "<p class=\"sub\">" + html_escape(field_text(q, "note")) + "</p>";
      rows.clear();
      for (const auto& x : q.value("limits", json::array()))
        rows.push_back({limit_text(x), field_text(x, "line"), text_of(x["value"]), text_of(x.value("met", json(nullptr))),
                        field_text(x, "on_fail"), field_text(x, "run_id")});
      b += tbl({"limit", "plan line", "value", "met", "on fail", "run"}, rows);
      std::string reasons;
      for (const auto& r : q.value("reasons", json::array())) reasons += "<li>" + html_escape(text_of(r)) + "</li>";
      if (!reasons.empty()) b += "<ul>" + reasons + "</ul>";
    }
    if (page >= 7 && has_axes(cert)) {
      // A three-axis unit: its verdict is the worst of its axes'; each axis as decided.
      b += h2 + "Axes (three-axis unit: the verdict is the worst axis')</h2>";
      b += tbl(kAxesHead, axis_rows(cert));
    }
    b += h2 + "Verifications of this model (evidence)</h2>";
    rows.clear();
    for (const auto& x : cert.value("verifications", json::array()))
      for (const auto& k : x["checks"])
        rows.push_back({field_text(x, "run_id"), field_text(k, "check"), text_of(k["value"]), cert_limit_text(k), field_text(k, "rule"), text_of(k["met"])});
    b += rows.empty() ? "<p>No verification of this model.</p>" : tbl({"run", "check", "value", "limit", "rule", "met"}, rows);
  }
  b += h2 + "Allan deviation of the compensated output (IEEE Std 952 Annex C)</h2>";
  rows.clear();
  for (const auto& a : cert["allan"])
    rows.push_back({field_text(a, "run_id"), a.contains("error") ? field_text(a, "error") : estimate_text(a["arw_deg_per_sqrt_h"]),
                    a.contains("error") ? "" : estimate_text(a["bias_instability_dph"]),
                    a.contains("error") ? "" : estimate_text(a["rrw_dph_per_sqrt_h"])});
  b += rows.empty() ? "<p>None (no verification run).</p>" : tbl({"run", "ARW, deg/sqrt(h)", "bias instability, deg/h", "RRW, deg/h/sqrt(h)"}, rows);
  if (page >= 5 && cert.contains("scale_factor")) {
    // The runs with rate steps: the scale factor over temperature (model::sf::fit).
    b += h2 + "Scale factor over temperature (IEEE Std 952)</h2><p class=\"sub\">Least squares over each plateau's rate "
               "sequence; the temperature sensitivity relative to SF0 across the plateaus (coil temperature T1).</p>";
    b += tbl(kSfRunHead, sf_run_rows(cert));
    b += tbl(kSfPlateauHead, sf_plateau_rows(cert));
  }
  b += h2 + "Runs</h2>";
  rows.clear();
  for (const auto& r : cert["runs"]) {
    const json& id = r["identity"];
    // The certified unit's lot in this run (issue 24), "-" when none was given.
    std::string lot = "-";
    if (id.is_object() && id.contains("units") && id["units"].is_array())
      for (const auto& u : id["units"])
        if (u.is_object() && u.value("serial", json()) == cert.value("serial", json()) && u.contains("lot") && u["lot"].is_string())
          lot = u["lot"].get<std::string>();
    std::vector<std::string> row{field_text(r, "id"), field_text(r, "role"), field_text(r, "profile"), field_text(r, "ended_at"),
                                 id.is_object() ? field_text(id, "station_id") : "-", id.is_object() ? field_text(id, "operator") : "-"};
    if (page >= 6) {
      row[3] = run_time_text(row[3]);
      row[4] = named_or(row[4], "not configured");
      row[5] = named_or(row[5], "not recorded");
    }
    if (v3) row.push_back(lot);  // page 2 (format 2) is drawn as it was, without the lot
    row.push_back(id.is_object() ? field_text(id, "software_version") + " " + field_text(id, "git_hash").substr(0, 12) : "-");
    rows.push_back(std::move(row));
  }
  if (page >= 7)  // the software column wide enough for "0.1.0 62756e985c7e" with the hash on one line
    b += runs_table_p7({"run", "role", "profile", "ended", "station", "operator", "lot", "software"}, rows);
  else
    b += v3 ? tbl({"run", "role", "profile", "ended", "station", "operator", "lot", "software"}, rows)
            : tbl({"run", "role", "profile", "ended", "station", "operator", "software"}, rows);
  b += h2 + "Integrity</h2><p class=\"hash\">SHA-256 " + html_escape(field_text(cert, "sha256")) + "</p>";
  if (cert.contains("signed_by") && cert["signed_by"].is_object())
    b += "<p class=\"hash\">Signed (Ed25519) by " + html_escape(station_text(field_text(cert["signed_by"], "station_id"))) + " with key " +
         html_escape(field_text(cert["signed_by"], "key_id")) + "</p><p class=\"sub\">Check with <code>fogctl cert --check FILE --key station.pub</code>" +
         " (the station's public key): the signature of the certificate embedded in this page, and this page's tables against it.</p>";
  else
    b += "<p class=\"sub\">Not signed: issued before fogbench signed certificates; nothing in this page proves who issued it.</p>";
  // "</" inside a script would end it: JSON's "\/" keeps it out and parses back to "/".
  std::string j = cert.dump(), safe;
  for (std::size_t i = 0; i < j.size(); ++i) safe += (j[i] == '/' && i > 0 && j[i - 1] == '<') ? std::string("\\/") : std::string(1, j[i]);
  const std::string head = "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">" + std::string(kRendererMeta) + renderer_name(page) + "\">";
  if (page < 4)
    return head + "<title>Certificate " + html_escape(field_text(cert, "serial")) + "</title><style>" + kStyle + "</style></head><body>" + b +
           kScriptOpen + safe + "</script></body></html>\n";
  // The verdict in the title (a browser's tab, a saved PDF's name, a print queue) and in every
  // printed page's margins with the serial and "page x of y"; the SHA-256's first 16 digits tie
  // each sheet to the signed content.
  const std::string serial = field_text(cert, "serial");
  const std::string shown_verdict = verdict == "pass" ? "QUALIFIED (pass)" : "NOT QUALIFIED (" + verdict + ")";
  const std::string title = (verdict == "pass" ? "Certificate of qualification " : "Qualification record ") + serial + ": " + shown_verdict;
  const std::string margins = "@page{@top-left{content:" + css_string(title) + ";font:9pt system-ui,sans-serif;color:#5a6472}" +
                              "@bottom-left{content:" + css_string("SHA-256 " + field_text(cert, "sha256").substr(0, 16) + "...") +
                              ";font:8pt monospace;color:#5a6472}" +
                              "@bottom-right{content:\"page \" counter(page) \" of \" counter(pages);font:9pt system-ui,sans-serif}}"
                              "section{break-inside:avoid}thead{display:table-header-group}p,li{orphans:3;widows:3}" +
                              (page >= 7 ? std::string(".runs td:last-child{overflow-wrap:normal}") : std::string());
  return head + "<title>" + html_escape(title) + "</title><style>" + kStyle + margins + "</style></head><body>" + "<section>" + b + "</section>" + kScriptOpen +
         safe + "</script></body></html>\n";
}

}  // namespace

std::string certificate_html(const json& cert) { return render_certificate(cert, latest_page_of(cert)); }
std::string certificate_html(const json& cert, int page) { return render_certificate(cert, std::clamp(page, 2, kPageLatest)); }

std::expected<json, std::string> certificate_from_text(const std::string& text) {
  std::string body = text;
  if (const auto at = text.find(kScriptOpen); at != std::string::npos) {
    const auto from = at + std::string(kScriptOpen).size();
    const auto end = text.find("</script>", from);
    if (end == std::string::npos) return std::unexpected("the embedded certificate is not closed (no </script>)");
    body = text.substr(from, end - from);
  } else if (text.find("<html") != std::string::npos) {
    return std::unexpected("an HTML file without an embedded certificate");
  }
  json j = json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return std::unexpected("not a certificate: not a JSON object");
  if (j.value("format", "") != "fogbench.certificate") return std::unexpected("not a certificate: format is not fogbench.certificate");
  if (!j.contains("sha256") || !j["sha256"].is_string()) return std::unexpected("not a certificate: no sha256 field");
  return j;
}

namespace {
// The page without its embedded JSON: what a reader sees (and the markup that draws it).
std::string visible_part(const std::string& html) {
  const auto at = html.find(kScriptOpen);
  if (at == std::string::npos) return html;
  const auto end = html.find("</script>", at);
  return html.substr(0, at) + (end == std::string::npos ? std::string() : html.substr(end));
}
std::string excerpt(const std::string& s, std::size_t at) {
  const std::size_t from = at > 30 ? at - 30 : 0;
  std::string e = s.substr(from, 70);
  for (char& ch : e)
    if (static_cast<unsigned char>(ch) < 0x20) ch = ' ';
  return "'" + e + "'";
}
}  // namespace

std::expected<std::string, std::string> visible_difference(const std::string& html, const json& cert) {
  std::string version;
  if (const auto at = html.find(kRendererMeta); at != std::string::npos) {
    const auto from = at + std::string(kRendererMeta).size();
    version = html.substr(from, html.find('"', from) - from);
  }
  // The pages this fogctl can draw for this content: page 2 for a certificate of per-verification
  // verdicts, pages 3 and 4 for one with the one verdict.
  int page = 0;
  for (int p = first_page_of(cert); p <= latest_page_of(cert); ++p)
    if (version == renderer_name(p)) page = p;
  if (page == 0)
    return std::unexpected("the page was drawn by " + (version.empty() ? std::string("an older fogctl") : "'" + version + "'") +
                           ", this fogctl draws its certificate as '" + renderer_name(latest_page_of(cert)) +
                           "': its visible tables cannot be compared (the embedded JSON can)");
  const std::string seen = visible_part(html), signed_page = visible_part(render_certificate(cert, page));
  if (seen == signed_page) return std::string();
  std::size_t i = 0;
  while (i < seen.size() && i < signed_page.size() && seen[i] == signed_page[i]) ++i;
  return "at byte " + std::to_string(i) + " the page shows " + excerpt(seen, i) + " where its signed content draws " +
         excerpt(signed_page, i);
}

namespace {

// --check FILE: the signature (offline, with --key; or with the daemon's key when one answers),
// the HTML's visible part, and whether the daemon's store issued it when one answers.
int check_file(const CertOptions& o, std::ostream& out, std::ostream& err) {
  const std::string me = "fogctl cert: ";
  std::ifstream f(o.check, std::ios::binary);
  if (!f) {
    err << me << o.check << ": cannot open\n";
    return kExitError;
  }
  std::ostringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  auto cert = certificate_from_text(text);
  if (!cert) {
    err << me << o.check << ": " << cert.error() << "\n";
    return kExitError;
  }
  std::vector<signing::PublicKey> keys;
  std::string key_source;
  for (const auto& k : o.keys) {
    auto some = signing::load_public_keys(k);
    if (!some) {
      err << me << "--key " << some.error() << "\n";
      return kExitError;
    }
    keys.insert(keys.end(), some->begin(), some->end());
    key_source += (key_source.empty() ? "" : ", ") + k;
  }
  std::vector<signing::Revocation> revoked;
  if (!o.revoked.empty()) {
    auto r = signing::load_revocations(o.revoked);
    if (!r) {
      err << me << "--revoked " << r.error() << "\n";
      return kExitError;
    }
    revoked = std::move(*r);
  }
  // No key given: the station's own, when its daemon answers (never needed: --key works offline).
  std::optional<Client> daemon;
  if (auto c = commands::open(o.daemon)) daemon.emplace(std::move(*c));
  if (keys.empty() && daemon) {
    if (auto r = daemon->call("cert.public_key", json::object()); r && (*r)["public_key_pem"].is_string()) {
      if (auto k = signing::PublicKey::from_pem((*r)["public_key_pem"].get<std::string>())) {
        keys.push_back(std::move(*k));
        key_source = "the daemon's station key";
      }
    }
  }
  const auto sig = signing::check_certificate(*cert, keys, revoked);
  const std::string claimed = cert->value("sha256", ""), actual = signing::content_sha256(*cert);
  json result = {{"file", o.check}, {"status", sig.status}, {"message", sig.message}, {"key_id", sig.key_id.empty() ? json(nullptr) : json(sig.key_id)},
                 {"keys_from", key_source.empty() ? json(nullptr) : json(key_source)},
                 {"intact", claimed == actual}, {"sha256", claimed}, {"recomputed", actual},
                 {"station_id", cert->value("station_id", "")}, {"visible", nullptr}, {"known_to_store", nullptr}};
  int code = sig.exit_code;
  std::string visible_note;
  if (text.find(kScriptOpen) != std::string::npos) {
    auto diff = visible_difference(text, *cert);
    if (!diff) {
      result["visible"] = "not compared";
      visible_note = "the visible page was NOT checked: " + diff.error();
      if (code == kExitOk) code = kExitError;
    } else if (diff->empty()) {
      result["visible"] = "matches";
      visible_note = "the visible page matches its signed content";
    } else {
      result["visible"] = "differs";
      visible_note = "the visible page was EDITED: " + *diff;
      code = kExitFailed;
    }
  }
  if (daemon && !claimed.empty())
    if (auto r = daemon->call("cert.check", {{"sha256", claimed}})) result["known_to_store"] = (*r)["known"];
  result["exit_code"] = code;
  result["valid"] = code == kExitOk;
  if (o.daemon.json_out) {
    out << result.dump() << "\n";
  } else {
    out << o.check << ": " << (code == kExitOk ? "VALID" : code == kExitFailed ? "NOT VALID" : "CANNOT TELL") << ": " << sig.message << "\n";
    if (!key_source.empty()) out << "  keys from " << key_source << "\n";
    if (!visible_note.empty()) out << "  " << visible_note << "\n";
    if (result["known_to_store"].is_null()) out << "  the station's store was not asked (no daemon reachable)\n";
    else out << "  " << (result["known_to_store"].get<bool>() ? "issued by" : "NOT known to") << " the station's store\n";
  }
  return code;
}

// --public-key: the station's public key as PEM (to stdout, or -o FILE), its id on stderr.
int public_key(const CertOptions& o, std::ostream& out, std::ostream& err) {
  auto c = commands::open(o.daemon);
  if (!c) return commands::report(c.error(), err);
  auto r = c->call("cert.public_key", json::object());
  if (!r) return commands::report(r.error(), err);
  if (o.daemon.json_out) {
    out << r->dump() << "\n";
    return kExitOk;
  }
  const std::string pem = (*r).value("public_key_pem", "");
  if (!o.output.empty()) {
    if (auto w = write_text(o.output, pem); !w) {
      err << "fogctl cert: " << w.error() << "\n";
      return kExitError;
    }
  } else {
    out << pem;
  }
  const std::string station = (*r).value("station_id", "");
  err << (station.empty() ? std::string("station (no station.id configured)") : "station " + station) << ", key id "
      << (*r).value("key_id", "")
      << ((*r)["public_key_path"].is_string() ? ", beside the key as " + (*r)["public_key_path"].get<std::string>() : std::string())
      << (o.output.empty() ? "" : ", written to " + o.output) << "\n";
  return kExitOk;
}

}  // namespace

int run_cert(const CertOptions& o, std::ostream& out, std::ostream& err) {
  const std::string me = "fogctl cert: ";
  if (!o.check.empty()) return check_file(o, out, err);
  if (o.public_key) return public_key(o, out, err);
  if (o.serial.empty()) {
    err << me << "give a SERIAL, --check FILE or --public-key\n";
    return kExitError;
  }
  auto c = commands::open(o.daemon);
  if (!c) return commands::report(c.error(), err);
  auto r = c->call("cert.get", {{"serial", o.serial}});
  if (!r) return commands::report(r.error(), err);
  const json& cert = (*r)["certificate"];
  if (!o.output.empty()) {
    const bool as_json = o.output.ends_with(".json");
    if (auto w = write_text(o.output, as_json ? cert.dump() + "\n" : certificate_html(cert)); !w) {
      err << me << w.error() << "\n";
      return kExitError;
    }
    if (!o.daemon.json_out) err << "certificate of " << o.serial << " written to " << o.output << "\n";
  }
  if (o.daemon.json_out) out << cert.dump() << "\n";
  else if (o.output.empty()) print_summary(cert, out);
  return kExitOk;
}

void add_cert_command(CLI::App& app, int& code) {
  static CertOptions o;
  auto* c = app.add_subcommand("cert", "A serial's signed certificate from fogbenchd (model with 1 sigma, verdicts, runs, Allan figures); --check FILE --key station.pub verifies one offline; --public-key gives the station's key");
  c->add_option("serial", o.serial, "The unit's serial");
  c->add_option("-o,--output", o.output, "Write the certificate: FILE.json its canonical JSON, else printable HTML (A4 and Letter)");
  c->add_option("--check", o.check, "Check a certificate file (JSON or the HTML, its visible tables too): exit 0 valid, 1 altered or a bad signature, 2 cannot tell (unsigned, unknown key, no key, unreadable)");
  c->add_option("--key", o.keys, "With --check: the station's public key (station.pub), a keyring file of several, or a folder of *.pub/*.pem; repeatable. Without it, the daemon's key when one answers");
  c->add_option("--revoked", o.revoked, "With --check: revoked keys, lines 'KEY_ID DATE [reason]': a certificate signed on or after DATE is not valid");
  c->add_flag("--public-key", o.public_key, "The station's public key (PEM) from fogbenchd, to stdout or -o FILE; its key id on stderr");
  commands::add_common(c, o.daemon);
  c->callback([&] { code = run_cert(o, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
