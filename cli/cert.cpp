// fogctl cert: see cert.hpp. The canonical form and its hash are the daemon's
// (daemon/include/fogbench/daemon/certificate.hpp): nlohmann's dump() of the object without
// `sha256`, SHA-256 in hex.
#include "cert.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "common.hpp"
#include "fogbench/model/sha256.hpp"
#include "table.hpp"
#include "html.hpp"

namespace fogbench::cli {

using nlohmann::json;

namespace {

constexpr const char* kScriptOpen = "<script type=\"application/json\" id=\"fogbench-certificate\">";

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

std::string hash_of(const json& cert) {
  json body = cert;
  body.erase("sha256");
  return model::sha256_hex(body.dump());
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

std::string table(const std::vector<std::string>& head, const std::vector<std::vector<std::string>>& rows) {
  std::string s = "<table><tr>";
  for (const auto& h : head) s += "<th>" + html_escape(h) + "</th>";
  s += "</tr>";
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
  return text_of(e["value"]) + " (" + text_of(e["ci_low"]) + " .. " + text_of(e["ci_high"]) + ", tau " +
         text_of(e["from_tau_s"]) + ".." + text_of(e["to_tau_s"]) + " s)";
}

int print_summary(const json& cert, std::ostream& out) {
  const json& m = cert["model"];
  out << "certificate of " << field_text(cert, "serial") << ": " << field_text(cert, "verdict") << "\n  model " << field_text(m, "id") << " version "
      << field_text(m, "version") << " (" << field_text(m, "method") << "): " << field_text(m, "terms") << "\n  issued " << field_text(cert, "issued_at")
      << " by station " << field_text(cert, "station_id") << ", fogbench " << field_text(cert["software"], "version") << " ("
      << field_text(cert["software"], "git_hash") << ")\n  sha256 " << field_text(cert, "sha256") << "\n";
  Table c({"term", "value", "1 sigma", "unit"});
  for (const auto& t : m["coefficients"]) c.add({field_text(t, "term"), text_of(t["value"], 6), text_of(t["sigma"], 3), field_text(t, "unit")});
  out << c.str();
  Table v({"run", "check", "value", "limit", "pass", "verdict"});
  for (const auto& x : cert["verdicts"])
    for (const auto& k : x["checks"]) v.add({field_text(x, "run_id"), field_text(k, "check"), text_of(k["value"]), cert_limit_text(k), text_of(k["pass"]), field_text(x, "verdict")});
  out << v.str();
  return kExitOk;
}

}  // namespace

std::string certificate_html(const json& cert) {
  const json& m = cert["model"];
  const std::string verdict = field_text(cert, "verdict");
  std::string b;
  b += "<h1>Certificate of qualification: " + html_escape(field_text(cert, "serial")) + "</h1>";
  b += "<div class=\"sub\">Thermal drift model, version " + html_escape(field_text(m, "version")) + ", issued " + html_escape(field_text(cert, "issued_at")) +
       " by station " + html_escape(field_text(cert, "station_id")) + " with fogbench " + html_escape(field_text(cert["software"], "version")) + " (" +
       html_escape(field_text(cert["software"], "git_hash")) + ")</div>";
  b += "<p>Verdict: <span class=\"" + std::string(verdict == "pass" ? "pass" : "fail") + "\">" + html_escape(verdict) + "</span></p>";
  b += "<h2>Model coefficients (1 sigma)</h2><p class=\"sub\">" + html_escape(field_text(m, "terms")) + " (" + html_escape(field_text(m, "method")) +
       " method), noise std sigma_a " + html_escape(text_of(m["sigma_a_dph"])) + " deg/h</p>";
  std::vector<std::vector<std::string>> rows;
  for (const auto& t : m["coefficients"])
    rows.push_back({field_text(t, "term"), text_of(t["value"], 6), text_of(t["sigma"], 3), field_text(t, "unit"), text_of(t["lag_s"])});
  b += table({"term", "value", "1 sigma", "unit", "lag, s"}, rows);
  b += "<h2>Verdicts</h2>";
  rows.clear();
  for (const auto& x : cert["verdicts"])
    for (const auto& k : x["checks"])
      rows.push_back({field_text(x, "run_id"), field_text(k, "check"), text_of(k["value"]), cert_limit_text(k), field_text(k, "rule"), text_of(k["pass"]), field_text(x, "verdict")});
  b += rows.empty() ? "<p>No verification of this model.</p>" : table({"run", "check", "value", "limit", "rule", "pass", "verdict"}, rows);
  b += "<h2>Allan deviation of the compensated output (IEEE Std 952 Annex C)</h2>";
  rows.clear();
  for (const auto& a : cert["allan"])
    rows.push_back({field_text(a, "run_id"), a.contains("error") ? field_text(a, "error") : estimate_text(a["arw_deg_per_sqrt_h"]),
                    a.contains("error") ? "" : estimate_text(a["bias_instability_dph"]),
                    a.contains("error") ? "" : estimate_text(a["rrw_dph_per_sqrt_h"])});
  b += rows.empty() ? "<p>None (no verification run).</p>" : table({"run", "ARW, deg/sqrt(h)", "bias instability, deg/h", "RRW, deg/h/sqrt(h)"}, rows);
  b += "<h2>Runs</h2>";
  rows.clear();
  for (const auto& r : cert["runs"]) {
    const json& id = r["identity"];
    rows.push_back({field_text(r, "id"), field_text(r, "role"), field_text(r, "profile"), field_text(r, "ended_at"),
                    id.is_object() ? field_text(id, "station_id") : "-", id.is_object() ? field_text(id, "operator") : "-",
                    id.is_object() ? field_text(id, "software_version") + " " + field_text(id, "git_hash").substr(0, 12) : "-"});
  }
  b += table({"run", "role", "profile", "ended", "station", "operator", "software"}, rows);
  b += "<h2>Integrity</h2><p class=\"hash\">SHA-256 " + html_escape(field_text(cert, "sha256")) +
       "</p><p class=\"sub\">Check with <code>fogctl cert --check FILE</code>: the hash of the canonical JSON embedded in this page.</p>";
  // "</" inside a script would end it: JSON's "\/" keeps it out and parses back to "/".
  std::string j = cert.dump(), safe;
  for (std::size_t i = 0; i < j.size(); ++i) safe += (j[i] == '/' && i > 0 && j[i - 1] == '<') ? std::string("\\/") : std::string(1, j[i]);
  return "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>Certificate " + html_escape(field_text(cert, "serial")) +
         "</title><style>" + kStyle + "</style></head><body>" + b + kScriptOpen + safe + "</script></body></html>\n";
}

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

int run_cert(const CertOptions& o, std::ostream& out, std::ostream& err) {
  const std::string me = "fogctl cert: ";
  if (!o.check.empty()) {
    std::ifstream f(o.check, std::ios::binary);
    if (!f) {
      err << me << o.check << ": cannot open\n";
      return kExitError;
    }
    std::ostringstream ss;
    ss << f.rdbuf();
    auto cert = certificate_from_text(ss.str());
    if (!cert) {
      err << me << o.check << ": " << cert.error() << "\n";
      return kExitError;
    }
    const std::string claimed = (*cert)["sha256"].get<std::string>(), actual = hash_of(*cert);
    const bool intact = claimed == actual;
    json result = {{"file", o.check}, {"intact", intact}, {"sha256", claimed}, {"recomputed", actual}, {"known_to_store", nullptr}};
    // The daemon, when it can be reached, says whether it issued this hash.
    if (auto c = commands::open(o.daemon)) {
      if (auto r = c->call("cert.check", {{"sha256", claimed}})) result["known_to_store"] = (*r)["known"];
    }
    if (o.daemon.json_out) {
      out << result.dump() << "\n";
    } else {
      out << o.check << ": " << (intact ? "intact" : "ALTERED") << " (sha256 " << claimed
          << (intact ? "" : ", its content hashes to " + actual) << ")\n";
      if (result["known_to_store"].is_null()) out << "  the store was not asked (no daemon reachable)\n";
      else out << "  " << (result["known_to_store"].get<bool>() ? "issued by" : "NOT known to") << " the station's store\n";
    }
    return intact ? kExitOk : kExitFailed;
  }
  if (o.serial.empty()) {
    err << me << "give a SERIAL, or --check FILE\n";
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
  auto* c = app.add_subcommand("cert", "A serial's certificate from fogbenchd (model with 1 sigma, verdicts, runs, Allan figures, SHA-256); --check FILE says whether one was altered");
  c->add_option("serial", o.serial, "The unit's serial");
  c->add_option("-o,--output", o.output, "Write the certificate: FILE.json its canonical JSON, else printable HTML (A4 and Letter)");
  c->add_option("--check", o.check, "Check a certificate file (JSON or the HTML): exit 0 intact, 1 altered, 2 unreadable");
  commands::add_common(c, o.daemon);
  c->callback([&] { code = run_cert(o, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
