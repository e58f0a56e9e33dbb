// fogctl fleet (fleet.hpp): reads the plant's PostgreSQL, never writes it. Runs in fogctl-fleet.
#include "fleet.hpp"

#include <algorithm>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>

#include "fleet_html.hpp"
#include "fleet_pchart.hpp"
#include "fogbench/plant/fleet_spc.hpp"
#include "fogbench/plant/generate.hpp"
#include "progress.hpp"
#include "table.hpp"

namespace fogbench::cli {

using nlohmann::json;

namespace {

json opt(const std::optional<std::string>& s) { return s ? json(*s) : json(nullptr); }

json summary_json(const plant::spc::Summary& s) {
  return {{"n", s.n}, {"mean", s.mean}, {"sd", s.sd}, {"min", s.min}, {"median", s.median}, {"max", s.max}};
}

json value_json(const plant::FigureValue& v) {
  return {{"bench", v.bench}, {"run_id", v.run_id}, {"unit", v.unit_index}, {"serial", v.serial},
          {"lot", opt(v.lot)}, {"ended_at", opt(v.ended_at)}, {"value", v.value}};
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// The figures asked for, or every figure present.
std::expected<std::vector<std::string>, std::string> figure_list(plant::Connection& c, const FleetOptions& o) {
  if (!o.figures.empty()) return o.figures;
  auto names = plant::figure_names(c, o.filter);
  if (!names) return std::unexpected(names.error().message);
  std::vector<std::string> out;
  for (const auto& n : *names)
    if (std::find(out.begin(), out.end(), n.name) == out.end()) out.push_back(n.name);
  return out;
}

// The plant store of --db or --service. One that does not answer is reported after 10 s, not
// after the kernel's two minutes of retries; a connect_timeout written in --db wins. `migrate`:
// create or upgrade the schema (a writer: fleet generate).
plant::PlantResult<plant::Connection> open_plant(const FleetOptions& o, bool migrate) {
  constexpr int kFleetConnectTimeoutS = 10;
  return plant::Connection::open(o.db.empty() ? "service=" + o.service : o.db, migrate, kFleetConnectTimeoutS);
}

// fogctl fleet generate: a demonstration plant (plant/generate.hpp), each option checked by name
// before anything is written; progress on stderr while samples are copied.
int run_generate(const FleetOptions& o, std::ostream& out, std::ostream& err) {
  const std::string where = "fogctl fleet generate: ";
  auto bad = [&](const std::string& what) {
    err << where << what << "\n";
    return kExitError;
  };
  if (o.gen_runs < 1 || o.gen_runs > 1000000) return bad("--runs: expected 1 to 1,000,000, not " + std::to_string(o.gen_runs));
  if (o.gen_units_per_run < 1 || o.gen_units_per_run > 64)
    return bad("--units-per-run: expected 1 to 64 (the bench slots of one run), not " + std::to_string(o.gen_units_per_run));
  if (o.gen_lots < 1 || o.gen_lots > o.gen_runs)
    return bad("--lots: expected 1 to --runs (" + std::to_string(o.gen_runs) + ": a lot holds whole runs), not " + std::to_string(o.gen_lots));
  if (o.gen_benches < 1 || o.gen_benches > 1000) return bad("--benches: expected 1 to 1000, not " + std::to_string(o.gen_benches));
  if (o.gen_outliers < 0 || o.gen_outliers > o.gen_runs)
    return bad("--outliers: expected 0 to --runs (one per run at most), not " + std::to_string(o.gen_outliers));
  if (o.gen_sample_runs < 0 || o.gen_sample_runs > o.gen_runs)
    return bad("--sample-runs: expected 0 to --runs, not " + std::to_string(o.gen_sample_runs));
  if (o.gen_samples_per_unit < 1 || o.gen_samples_per_unit > 1000000)
    return bad("--samples-per-unit: expected 1 to 1,000,000, not " + std::to_string(o.gen_samples_per_unit));
  plant::GenerateOptions g;
  g.runs = o.gen_runs;
  g.units_per_run = o.gen_units_per_run;
  g.lots = o.gen_lots;
  g.benches = o.gen_benches;
  g.shifted_lot = std::min(o.gen_lots - 1, (2 * o.gen_lots) / 3);
  g.outliers = o.gen_outliers;
  // The bench with extra marginal verdicts from the plant's middle on: the p-charts' finding.
  g.marginal_bench = std::min(3, o.gen_benches);
  g.marginal_from_run = o.gen_runs / 2;
  g.sample_runs = o.gen_sample_runs;
  g.samples_per_unit = o.gen_samples_per_unit;
  g.seed = o.gen_seed;
  if (g.shifted_lot == 0 && g.lots > 1) g.shifted_lot = 1;
  Progress progress(err, progress_redraws(), 5.0);
  progress.set_width(progress_width());
  g.progress = [&](std::int64_t done, std::int64_t total, std::int64_t samples) {
    progress.update("copying samples", "samples of " + std::to_string(done) + " of " + std::to_string(total) + " runs copied (" +
                                           std::to_string(samples) + " rows)");
  };
  progress.update("writing runs", "writing " + std::to_string(o.gen_runs) + " runs, their units, models and verdicts");
  auto c = open_plant(o, true);
  if (!c) return bad(c.error().message);
  auto r = plant::generate_fleet(*c, g);
  progress.finish();
  if (!r) return bad(r.error().message);
  const std::string benches = g.bench_prefix + "1.." + g.bench_prefix + std::to_string(g.benches);
  if (o.json) {
    out << json{{"generated", {{"runs", r->runs}, {"units", r->units}, {"figures", r->figures}, {"samples", r->samples},
                               {"benches", benches}, {"shifted_lot", r->shifted_lot}, {"shifted_figure", g.figure},
                               {"shift_sigma", g.shift_sigma}, {"outlier_serials", r->outlier_serials},
                               {"outlier_sigma", g.outlier_sigma},
                               {"marginal_bench", r->marginal_bench.empty() ? json(nullptr) : json(r->marginal_bench)},
                               {"seed", g.seed}}}}
               .dump(2)
        << "\n";
    return kExitOk;
  }
  Table t({"what", "generated"});
  t.add({"runs", std::to_string(r->runs) + " on " + benches});
  t.add({"units", std::to_string(r->units) + " in " + std::to_string(g.lots) + " lots"});
  t.add({"figures", std::to_string(r->figures)});
  t.add({"samples", std::to_string(r->samples)});
  t.add({"shifted lot", r->shifted_lot + ": " + g.figure + " mean moved by " + num(g.shift_sigma) + " sigma"});
  std::string outliers;
  for (const auto& s : r->outlier_serials) outliers += (outliers.empty() ? "" : ", ") + s;
  t.add({"outlier units", outliers.empty() ? "none" : outliers + " (" + g.figure + " " + num(g.outlier_sigma) + " sigma away)"});
  t.add({"marginal bench", r->marginal_bench.empty() ? "none"
                                                      : r->marginal_bench + ": marginal verdicts at " + num(100 * g.marginal_bench_rate) +
                                                            " % from run " + std::to_string(g.marginal_from_run + 1) + " on (" +
                                                            num(100 * g.marginal_rate) + " % elsewhere)"});
  out << t.str() << "What the charts should find: `fogctl fleet spc --figure '" << g.figure
      << "' --html spc.html` with the same --db or --service.\n";
  return kExitOk;
}

}  // namespace

int run_fleet(const std::string& command, const FleetOptions& o, std::ostream& out, std::ostream& err) {
  const std::string where = "fogctl fleet " + command + ": ";
  if (o.db.empty() == o.service.empty()) {
    err << where << "give the plant store with exactly one of --db CONNSTR or --service NAME\n";
    return kExitError;
  }
  std::optional<std::pair<std::string, std::string>> lots;
  if (!o.compare.empty()) {
    const auto comma = o.compare.find(',');
    if (comma == std::string::npos || comma == 0 || comma + 1 == o.compare.size()) {
      err << where << "--compare: expected two lots as LOT_A,LOT_B, not '" << o.compare << "'\n";
      return kExitError;
    }
    lots.emplace(o.compare.substr(0, comma), o.compare.substr(comma + 1));
  }
  if (o.period != "month" && o.period != "week" && o.period != "day") {
    err << where << "--period: expected month, week or day, not '" << o.period << "'\n";
    return kExitError;
  }
  if (!(o.level > 0 && o.level < 1)) {
    err << where << "--level: expected a number between 0 and 1 (e.g. 0.95)\n";
    return kExitError;
  }
  if (command == "generate") return run_generate(o, out, err);
  auto c = open_plant(o, false);
  if (!c) {
    err << where << c.error().message << "\n";
    return kExitError;
  }

  if (command == "serials") {
    auto rows = plant::serials(*c, o.filter);
    if (!rows) return err << where << rows.error().message << "\n", kExitError;
    if (o.json) {
      json a = json::array();
      for (const auto& s : *rows)
        a.push_back({{"serial", s.serial}, {"runs", s.runs}, {"lots", s.lots}, {"benches", s.benches},
                     {"first_at", opt(s.first_at)}, {"last_at", opt(s.last_at)}, {"last_verdict", opt(s.last_verdict)}});
      out << json{{"serials", a}}.dump(2) << "\n";
    } else {
      Table t({"serial", "runs", "lots", "benches", "first run end", "last run end", "last verdict"});
      for (const auto& s : *rows)
        t.add({s.serial, std::to_string(s.runs), s.lots, s.benches, s.first_at.value_or("-"), s.last_at.value_or("-"),
               s.last_verdict.value_or("-")});
      out << t.str() << rows->size() << " serials\n";
    }
    return kExitOk;
  }
  if (command == "history" || command == "serial") {
    auto rows = plant::serial_history(*c, o.serial, o.filter);
    if (!rows) return err << where << rows.error().message << "\n", kExitError;
    if (rows->empty()) {
      err << where << "no runs of serial '" << o.serial << "' in the plant store (with these filters)\n";
      return kExitError;
    }
    auto certs = plant::serial_certificates(*c, o.serial, o.filter);
    if (!certs) return err << where << certs.error().message << "\n", kExitError;
    if (o.json) {
      json a = json::array();
      for (const auto& h : *rows) {
        json f = json::object();
        for (const auto& [k, v] : h.figures) f[k] = v;
        json id = nullptr;
        if (h.identity)
          id = {{"station_id", h.identity->station_id}, {"operator", h.identity->operator_name},
                {"operator_source", h.identity->operator_source}, {"software_version", h.identity->software_version},
                {"git_hash", h.identity->git_hash}, {"config_sha256", h.identity->config_sha256},
                {"profile_sha256", h.identity->profile_sha256}};
        a.push_back({{"bench", h.bench}, {"run_id", h.run_id}, {"unit", h.unit_index}, {"lot", opt(h.lot)},
                     {"ended_at", opt(h.ended_at)}, {"purpose", h.purpose}, {"state", h.state},
                     {"verdict", opt(h.verdict)}, {"identity", id}, {"powered_on_at", opt(h.powered_on_at)},
                     {"since_power_on_s", h.since_power_on_s ? json(*h.since_power_on_s) : json(nullptr)},
                     {"figures", f}});
      }
      json cj = json::array();
      for (const auto& ce : *certs)
        cj.push_back({{"bench", ce.bench}, {"certificate_id", ce.certificate_id}, {"model_id", ce.model_id},
                      {"model_version", ce.model_version}, {"sha256", ce.sha256}, {"issued_at", opt(ce.issued_at)},
                      {"verdict", opt(ce.verdict)}, {"run_id", ce.run_id ? json(*ce.run_id) : json(nullptr)}});
      out << json{{"serial", o.serial}, {"runs", a}, {"certificates", cj}}.dump(2) << "\n";
    } else {
      // Hashes shortened to 12 hex digits in the table (--json has them whole).
      auto short_hash = [](const std::string& h) { return h.size() > 12 ? h.substr(0, 12) : h; };
      Table t({"run end", "bench", "run", "unit", "lot", "purpose", "verdict", "station", "operator", "software",
               "config sha256", "profile sha256"});
      Table ft({"run end", "bench", "run", "figures"});
      for (const auto& h : *rows) {
        std::string f;
        for (const auto& [k, v] : h.figures) f += (f.empty() ? "" : " ") + k + "=" + num(v);
        const auto& id = h.identity;
        t.add({h.ended_at.value_or("-"), h.bench, std::to_string(h.run_id), std::to_string(h.unit_index),
               h.lot.value_or("-"), h.purpose, h.verdict.value_or("-"), id ? id->station_id : "-",
               id ? id->operator_name : "-", id ? id->software_version + " " + short_hash(id->git_hash) : "-",
               id ? short_hash(id->config_sha256) : "-", id ? short_hash(id->profile_sha256) : "-"});
        ft.add({h.ended_at.value_or("-"), h.bench, std::to_string(h.run_id), f.empty() ? "-" : f});
      }
      out << "history of " << o.serial << " (" << rows->size() << (rows->size() == 1 ? " run)\n" : " runs)\n") << t.str() << "\nfigures\n" << ft.str();
      if (certs->empty()) {
        out << "\nno certificates of " << o.serial << " in the plant store\n";
      } else {
        Table ct({"issued", "bench", "certificate", "model", "version", "run", "verdict", "sha256"});
        for (const auto& ce : *certs)
          ct.add({ce.issued_at.value_or("-"), ce.bench, std::to_string(ce.certificate_id), std::to_string(ce.model_id),
                  std::to_string(ce.model_version), ce.run_id ? std::to_string(*ce.run_id) : "-",
                  ce.verdict.value_or("-"), ce.sha256});
        out << "\ncertificates\n" << ct.str();
      }
    }
    return kExitOk;
  }
  if (command == "figures") {
    auto names = plant::figure_names(*c, o.filter);
    if (!names) return err << where << names.error().message << "\n", kExitError;
    if (o.json) {
      json a = json::array();
      for (const auto& n : *names) a.push_back({{"name", n.name}, {"source", n.source}, {"count", n.count}});
      out << json{{"figures", a}}.dump(2) << "\n";
    } else {
      Table t({"figure", "source", "values"});
      for (const auto& n : *names) t.add({n.name, n.source, std::to_string(n.count)});
      out << t.str();
    }
    return kExitOk;
  }
  auto figures = figure_list(*c, o);
  if (!figures) return err << where << figures.error() << "\n", kExitError;
  if (figures->empty()) return err << where << "no figures in the plant store (with these filters)\n", kExitError;

  if (command == "dist") {
    json j = json::object();
    std::string text;
    for (const auto& name : *figures) {
      auto values = plant::figure_values(*c, name, o.filter);
      if (!values) return err << where << values.error().message << "\n", kExitError;
      auto d = plant::distribution(*values, o.by);
      if (!d) return err << where << d.error() << "\n", kExitError;
      json g = json::array();
      Table t({o.by, "n", "mean", "sd", "min", "median", "max"});
      for (const auto& [k, s] : *d) {
        g.push_back({{o.by, k}, {"summary", summary_json(s)}});
        t.add({k, std::to_string(s.n), num(s.mean), num(s.sd), num(s.min), num(s.median), num(s.max)});
      }
      j[name] = g;
      text += name + " by " + o.by + "\n" + t.str() + "\n";
    }
    if (o.json) out << json{{"by", o.by}, {"figures", j}}.dump(2) << "\n";
    else out << text;
    return kExitOk;
  }

  if (command == "spc") {
    plant::Baseline b{o.baseline_n, o.baseline_from, o.baseline_to};
    json charts = json::array();
    std::vector<plant::FigureSpc> all;
    std::string text;
    std::size_t n_flagged = 0;
    for (const auto& name : *figures) {
      auto values = plant::figure_values(*c, name, o.filter);
      if (!values) return err << where << values.error().message << "\n", kExitError;
      if (values->empty()) {
        err << where << "no values of figure '" << name << "' (see `fogctl fleet figures`)\n";
        return kExitError;
      }
      std::optional<plant::spc::Comparison> cmp;
      if (lots) {
        auto r = plant::compare_lots(*values, lots->first, lots->second, o.level);
        if (!r) return err << where << "figure '" << name << "': " << r.error() << "\n", kExitError;
        cmp = *r;
      }
      auto f = plant::figure_spc(name, std::move(*values), b);
      if (!f) return err << where << f.error() << "\n", kExitError;
      const auto& ch = f->chart;
      n_flagged += f->flagged_units.size();
      json signals = json::array();
      for (const auto& s : ch.signals)
        signals.push_back({{"rule", plant::spc::to_string(s.rule)}, {"index", s.index}, {"first", s.first},
                           {"side", s.side}, {"at", value_json(f->values[s.index])}});
      json flagged = json::array();
      for (auto i : f->flagged_units) {
        json u = value_json(f->values[i]);
        u["z"] = ch.sigma > 0 ? (f->values[i].value - ch.center) / ch.sigma : 0.0;
        flagged.push_back(u);
      }
      json lots_j = json::array();
      for (const auto& l : f->lots)
        lots_j.push_back({{"lot", l.lot}, {"n", l.n}, {"mean", l.mean}, {"lcl", l.lcl}, {"ucl", l.ucl}, {"z", l.z},
                          {"side", l.side}});
      json cj = {{"figure", name}, {"n", f->values.size()}, {"baseline", f->baseline}, {"lots", lots_j},
                 {"flagged_lots", f->flagged_lots},
                 {"center", ch.center}, {"sigma", ch.sigma}, {"ucl", ch.ucl}, {"lcl", ch.lcl},
                 {"mr_bar", ch.mr_bar}, {"mr_ucl", ch.mr_ucl}, {"flagged_units", flagged}, {"signals", signals}};
      if (cmp)
        cj["lot_comparison"] = {{"lot_a", lots->first}, {"lot_b", lots->second}, {"a", summary_json(cmp->a)},
                                {"b", summary_json(cmp->b)}, {"difference", cmp->diff}, {"se", cmp->se},
                                {"dof", cmp->dof}, {"level", cmp->level}, {"low", cmp->low}, {"high", cmp->high},
                                {"t", cmp->t}, {"p_value", cmp->p_value}};
      charts.push_back(cj);

      std::size_t by_rule[6] = {};
      for (const auto& s : ch.signals) ++by_rule[static_cast<int>(s.rule)];
      text += name + ": n " + std::to_string(f->values.size()) + ", limits from " + f->baseline + "\n";
      text += "  individuals: centre " + num(ch.center) + ", limits " + num(ch.lcl) + " .. " + num(ch.ucl) +
              " (sigma " + num(ch.sigma) + " = MRbar/1.128); moving range: MRbar " + num(ch.mr_bar) + ", limit " +
              num(ch.mr_ucl) + "\n";
      text += "  signals: rule 1 " + std::to_string(by_rule[1]) + ", rule 2 " + std::to_string(by_rule[2]) +
              ", rule 3 " + std::to_string(by_rule[3]) + ", rule 4 " + std::to_string(by_rule[4]) +
              ", moving range " + std::to_string(by_rule[5]) + "\n";
      if (!f->flagged_units.empty()) {
        Table t({"serial", "lot", "bench", "run", "unit", "run end", "value", "z"});
        for (auto i : f->flagged_units) {
          const auto& v = f->values[i];
          t.add({v.serial, v.lot.value_or("-"), v.bench, std::to_string(v.run_id), std::to_string(v.unit_index),
                 v.ended_at.value_or("-"), num(v.value), num(ch.sigma > 0 ? (v.value - ch.center) / ch.sigma : 0)});
        }
        text += "  flagged units (beyond the limits):\n" + t.str();
      }
      if (!f->flagged_lots.empty()) {
        Table t({"lot", "n", "mean", "limits", "z"});
        for (const auto& l : f->lots)
          if (l.side != 0) t.add({l.lot, std::to_string(l.n), num(l.mean), num(l.lcl) + " .. " + num(l.ucl), num(l.z)});
        text += "  lots out of limits (lot mean against centre +- 3 sigma sqrt(1/n + 1/n_baseline)):\n" + t.str();
      } else if (!f->lots.empty()) {
        text += "  lots out of limits: none of " + std::to_string(f->lots.size()) + "\n";
      }
      if (cmp)
        text += "  lot " + lots->first + " - lot " + lots->second + ": " + num(cmp->diff) + " [" + num(cmp->low) +
                ", " + num(cmp->high) + "] at " + num(100 * cmp->level) + "% (Welch, " + num(cmp->dof) +
                " dof, p " + num(cmp->p_value) + "; n " + std::to_string(cmp->a.n) + " and " +
                std::to_string(cmp->b.n) + ")\n";
      text += "\n";
      all.push_back(std::move(*f));
    }
    // The p-charts of marginal and fail verdicts per bench per period.
    auto verdicts = plant::verdict_values(*c, o.filter);
    if (!verdicts) return err << where << verdicts.error().message << "\n", kExitError;
    json proportions = json::array();
    std::set<std::string> flagged_benches;
    if (!verdicts->empty()) {
      plant::Baseline pb{o.p_baseline_n.value_or(2000), o.baseline_from, o.baseline_to};
      for (const char* v : {"marginal", "fail"}) {
        auto p = plant::proportion_chart(*verdicts, v, pb, o.period);
        if (!p) return err << where << p.error() << "\n", kExitError;
        proportions.push_back(proportion_json(*p));
        text += proportion_text(*p) + "\n";
        flagged_benches.insert(p->flagged_benches.begin(), p->flagged_benches.end());
      }
    } else {
      text += "no verdicts: no p-charts\n\n";
    }
    if (!o.html.empty()) {
      if (auto w = write_text(o.html, fleet_html(all, charts, proportions)); !w)
        return err << where << w.error() << "\n", kExitError;
    }
    if (o.json)
      out << json{{"charts", charts}, {"flagged_units", n_flagged}, {"proportions", proportions},
                  {"flagged_benches", flagged_benches}}.dump(2) << "\n";
    else out << text << n_flagged << " flagged units; " << flagged_benches.size() << " benches out of limits\n";
    return kExitOk;
  }
  err << where << "unknown command\n";
  return kExitError;
}

}  // namespace fogbench::cli
