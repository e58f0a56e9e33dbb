// fogctl scale-factor and the rate-sequence CSV (see scale_factor.hpp).
#include "scale_factor.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "common.hpp"
#include "table.hpp"

namespace fogbench::cli {

namespace {

// The shortest text that reads back to the same double.
void put(std::string& s, double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, ec == std::errc{} ? end : buf);
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> f;
  while (true) {
    const std::size_t c = line.find(',');
    std::string_view v = line.substr(0, c);
    while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
    while (!v.empty() && (v.back() == ' ' || v.back() == '\t' || v.back() == '\r')) v.remove_suffix(1);
    f.push_back(v);
    if (c == std::string_view::npos) return f;
    line.remove_prefix(c + 1);
  }
}

nlohmann::json coefficient_json(const model::sf::Coefficient& c) {
  if (c.value) return {{"value", *c.value}, {"se", c.se}};
  return {{"value", nullptr}, {"not_identified", c.not_identified}};
}

}  // namespace

std::string coefficient_text(const model::sf::Coefficient& c, int digits, const std::string& unit) {
  if (!c.value) return "not identified: " + c.not_identified;
  // Two significant digits of the standard error at least: never "+- 0.000".
  if (c.se > 0.0) digits = std::clamp(1 - static_cast<int>(std::floor(std::log10(c.se))), digits, 9);
  return fixed(*c.value, digits) + " +- " + fixed(c.se, digits) + " " + unit + " (1 sigma)";
}

std::string rate_sequence_csv(const SimulatedRun& run, const sim::ScaleFactorTruth& truth, const sim::RateSequence& seq) {
  const model::RunData& r = run.units.front();
  const std::vector<double>& tt = run.true_t1_c.front();
  const std::size_t n = r.size();
  std::string s = "time_s,plateau,setpoint_c,chamber_c,t1_c,t2_c,rate_in_dps,rate_out_dps\n";
  s.reserve(n * 120);
  std::size_t step_begin = 0, step_end = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i == 0 || r.step[i] != r.step[i - 1]) {
      step_begin = step_end = i;
      while (step_end < n && r.step[step_end] == r.step[i]) ++step_end;
    }
    // The profile step's length: its samples' span plus the last sample's second.
    const double length_s = r.time_s[step_end - 1] - r.time_s[step_begin] + 1.0;
    const double rate_in = seq.rate_at(r.time_s[i] - r.time_s[step_begin], length_s);
    // The true coil temperature's rate: a centred difference over +-30 s, degC/min.
    const std::size_t a = i >= 30 ? i - 30 : 0, b = std::min(n - 1, i + 30);
    const double tdot = b > a ? 60.0 * (tt[b] - tt[a]) / (r.time_s[b] - r.time_s[a]) : 0.0;
    const double out = r.gyro_dph[i] / 3600.0 + sim::indicated_rate_dps(truth, rate_in, tt[i], tdot);
    put(s, r.time_s[i]);
    s += ',';
    s += std::to_string(r.step[i]);
    for (double v : {r.setpoint_c[i], r.chamber_c[i], r.t1_c[i], r.t2_c[i], rate_in, out}) {
      s += ',';
      put(s, v);
    }
    s += '\n';
  }
  return s;
}

std::string RateCsvSkipped::text() const {
  std::string s;
  if (no_gyro_reading > 0)
    s += std::to_string(no_gyro_reading) + (no_gyro_reading == 1 ? " second" : " seconds") +
         " without a gyro reading (empty rate_out_dps)";
  if (no_coil_reading > 0)
    s += (s.empty() ? "" : "; ") + std::to_string(no_coil_reading) + (no_coil_reading == 1 ? " second" : " seconds") +
         " without a coil temperature (empty " + coil_column + ")";
  if (!at_rest_plateaus.empty()) {
    if (!s.empty()) s += "; ";
    s += at_rest_plateaus.size() == 1 ? "plateau " : "plateaus ";
    for (std::size_t i = 0; i < at_rest_plateaus.size(); ++i) s += (i ? ", " : "") + std::to_string(at_rest_plateaus[i]);
    s += " (" + std::to_string(at_rest_rows) + (at_rest_rows == 1 ? " second" : " seconds") +
         ") with no rate step: the table at rest throughout";
  }
  return s.empty() ? s : "skipped: " + s;
}

std::expected<model::sf::RateRecord, std::string> parse_rate_csv(std::string_view text, const std::string& source,
                                                                 const std::string& coil_column, RateCsvSkipped* skipped) {
  RateCsvSkipped skip;
  skip.coil_column = coil_column;
  model::sf::RateRecord rec;
  const std::vector<std::string> wanted = {"time_s", "plateau", "rate_in_dps", "rate_out_dps", coil_column};
  std::vector<std::size_t> col(wanted.size(), SIZE_MAX);
  std::vector<std::string_view> header;
  std::size_t line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') continue;
    auto fields = split_fields(line);
    if (header.empty()) {
      header = fields;
      std::string missing;
      for (std::size_t k = 0; k < wanted.size(); ++k) {
        for (std::size_t j = 0; j < header.size(); ++j)
          if (header[j] == wanted[k]) col[k] = j;
        if (col[k] == SIZE_MAX) missing += (missing.empty() ? "'" : ", '") + wanted[k] + "'";
      }
      if (!missing.empty())
        return std::unexpected(source + ":" + std::to_string(line_no) + ": the header has no column " + missing +
                               " (a rate-sequence CSV has time_s, plateau, rate_in_dps, rate_out_dps and the coil temperature " + coil_column + ")");
      continue;
    }
    if (fields.size() != header.size())
      return std::unexpected(source + ":" + std::to_string(line_no) + ": " + std::to_string(fields.size()) + " fields, the header has " +
                             std::to_string(header.size()));
    // A second stored without a gyro reading: nothing to fit, whatever else the row lacks.
    if (fields[col[3]].empty()) {
      ++skip.no_gyro_reading;
      continue;
    }
    if (fields[col[4]].empty()) {  // nor without the coil's temperature
      ++skip.no_coil_reading;
      continue;
    }
    double v[5] = {};
    for (std::size_t k = 0; k < wanted.size(); ++k) {
      const std::string_view f = fields[col[k]];
      const std::string where = source + ":" + std::to_string(line_no) + ": column " + std::to_string(col[k] + 1) + " '" + wanted[k] + "'";
      if (k == 1) {
        int id = 0;
        const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), id);
        if (f.empty() || ec != std::errc{} || end != f.data() + f.size())
          return std::unexpected(where + ": not an integer plateau id: '" + std::string(f) + "'");
        v[k] = id;
        continue;
      }
      const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), v[k]);
      if (f.empty() || ec != std::errc{} || end != f.data() + f.size())
        return std::unexpected(where + ": not a number: '" + std::string(f) + "'");
      if (!std::isfinite(v[k])) return std::unexpected(where + ": not a finite number: '" + std::string(f) + "'");
    }
    if (!rec.time_s.empty() && !(v[0] > rec.time_s.back()))
      return std::unexpected(source + ":" + std::to_string(line_no) + ": column " + std::to_string(col[0] + 1) +
                             " 'time_s': time does not increase (" + std::string(fields[col[0]]) + " s after " + std::to_string(rec.time_s.back()) + " s)");
    rec.time_s.push_back(v[0]);
    rec.plateau.push_back(static_cast<int>(v[1]));
    rec.rate_in_dps.push_back(v[2]);
    rec.rate_out_dps.push_back(v[3]);
    rec.coil_c.push_back(v[4]);
  }
  if (header.empty()) return std::unexpected(source + ": empty: no header row");
  if (rec.time_s.empty() && skip.no_gyro_reading + skip.no_coil_reading == 0)
    return std::unexpected(source + ": a header but no data rows");
  if (rec.time_s.empty()) return std::unexpected(source + ": no row with both readings (" + skip.text() + ")");
  // The plateaus without a rate step (a run's temperature transits, not a rate sequence) left
  // out as the daemon leaves them out of a stored run (model::sf::turning_plateaus), and named.
  model::sf::RateRecord kept = model::sf::turning_plateaus(rec, &skip.at_rest_rows);
  const std::set<int> turned(kept.plateau.begin(), kept.plateau.end());
  std::set<int> named;
  for (int p : rec.plateau)
    if (!turned.contains(p) && named.insert(p).second) skip.at_rest_plateaus.push_back(p);  // in file order
  if (skipped) *skipped = skip;
  if (kept.time_s.empty())
    return std::unexpected(source + ": no plateau with a rate step (" + skip.text() + ")");
  return kept;
}

std::expected<model::sf::Result, std::string> fit_rate_file(const std::string& path, const model::sf::Options& fo, const std::string& coil_column,
                                                            RateCsvSkipped* skipped) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::unexpected(path + ": cannot be read");
  std::stringstream buf;
  buf << in.rdbuf();
  auto rec = parse_rate_csv(buf.str(), path, coil_column, skipped);
  if (!rec) return std::unexpected(rec.error());
  if (auto bad = fo.validate(); !bad.empty()) return std::unexpected(bad);
  // parse_rate_csv kept the plateaus in which the table turned (model::sf::turning_plateaus,
  // as the daemon selects them from a stored run): a run's export fits as its plan limit and
  // certificate measured it.
  auto r = model::sf::fit(*rec, fo);
  if (!r) return std::unexpected(path + ": " + r.error());
  return r;
}

int run_scale_factor(const ScaleFactorOptions& o, std::ostream& out, std::ostream& err) {
  const std::string me = "fogctl scale-factor: ";
  model::sf::Options fo;
  fo.settle_s = o.settle_s;
  fo.t0_c = o.t0_c;
  RateCsvSkipped skipped;
  auto r = fit_rate_file(o.run, fo, o.coil_column, &skipped);
  if (!r) {
    err << me << r.error() << "\n";
    return kExitError;
  }
  if (o.json) {
    nlohmann::json ps = nlohmann::json::array();
    for (const auto& p : r->plateaus) {
      nlohmann::json steps = nlohmann::json::array();
      for (const auto& s : p.steps)
        steps.push_back({{"index", s.index}, {"rate_in_dps", s.rate_in_dps}, {"start_s", s.start_s}, {"n_used", s.n_used},
                         {"mean_out_dps", s.mean_out_dps}, {"mean_coil_c", s.mean_coil_c}, {"residual_ppm_fso", s.residual_ppm_fso}});
      ps.push_back({{"plateau", p.id}, {"coil_c", p.coil_c}, {"temp_rate_c_per_min", p.temp_rate_c_per_min}, {"coil_span_c", p.coil_span_c}, {"bias_dph", p.bias_dph},
                    {"bias_from_zero_rate", p.bias_from_zero_rate}, {"scale_factor", p.scale_factor}, {"scale_factor_se", p.scale_factor_se},
                    {"full_scale_out_dps", p.full_scale_out_dps}, {"nonlinearity_ppm", p.nonlinearity_ppm},
                    {"sf_positive", p.sf_positive}, {"sf_negative", p.sf_negative}, {"asymmetry_ppm", p.asymmetry_ppm},
                    {"n_used", p.n_used}, {"steps", steps}});
    }
    out << nlohmann::json{{"run", o.run}, {"settle_s", o.settle_s}, {"t0_c", o.t0_c}, {"coil_column", o.coil_column},
                          {"nonlinearity_of", "full-scale output"}, {"samples_dropped", r->n_samples_dropped},
                          {"skipped", {{"no_gyro_reading", skipped.no_gyro_reading},
                                       {"no_coil_reading", skipped.no_coil_reading},
                                       {"at_rest_plateaus", skipped.at_rest_plateaus},
                                       {"at_rest_rows", skipped.at_rest_rows}}},
                          {"plateaus", ps},
                          {"sf0", r->sf0}, {"tc_ppm_per_c", coefficient_json(r->tc_ppm_per_c)},
                          {"temp_rate_ppm_per_c_per_min", coefficient_json(r->temp_rate_ppm_per_c_per_min)},
                          {"model", {{"form", "SF(T) = SF0 (1 + k1 (T - T0) + k2 (T - T0)^2)"}, {"sf0", r->model_sf0}, {"t0_c", o.t0_c},
                                     {"k1_ppm_per_c", coefficient_json(r->k1_ppm_per_c)}, {"k2_ppm_per_c2", coefficient_json(r->k2_ppm_per_c2)},
                                     {"rms_ppm", r->model_rms_ppm}}}}
               .dump()
        << "\n";
    return kExitOk;
  }
  // Prose wrapped to the terminal's width (whole lines when piped), as the tables are.
  const auto say = [&](const std::string& prose) {
    const std::size_t width = output_width();
    if (width == 0) {
      out << prose << "\n";
      return;
    }
    for (const auto& line : wrap_text(prose, width)) out << line << "\n";
  };
  say("scale factor over temperature of " + o.run + " (IEEE Std 952 least squares; output and input in deg/s; the first " +
      fixed(o.settle_s, 1) + " s of each rate step dropped: " + std::to_string(r->n_samples_dropped) +
      " samples). " + o.coil_column + ": the coil temperature; degC/min: its rate; dSF: the scale factor against SF0, " +
      "ppm; NL: nonlinearity, ppm of full-scale output; asym: asymmetry, ppm");
  if (const std::string sk = skipped.text(); !sk.empty()) say(sk);
  out << "\n";
  Table t({"plateau", o.coil_column + " degC", "degC/min", "bias deg/h", "SF", "dSF ppm", "NL ppm", "asym ppm", "steps", "samples"});
  for (const auto& p : r->plateaus)
    t.add({std::to_string(p.id), fixed(p.coil_c, 2), fixed(p.temp_rate_c_per_min, 3), fixed(p.bias_dph, 3) + (p.bias_from_zero_rate ? "" : " (line)"),
           fixed(p.scale_factor, 9), fixed(1e6 * (p.scale_factor / r->sf0 - 1.0), 2), fixed(p.nonlinearity_ppm, 2), fixed(p.asymmetry_ppm, 2),
           std::to_string(p.steps.size()), std::to_string(p.n_used)});
  out << t.str() << "\n";
  // The scale factor moves with the temperature over a plateau that is not settled: say where
  // that is in the nonlinearity and asymmetry (0.1 degC is 1.5 ppm at 15 ppm/degC).
  for (const auto& p : r->plateaus)
    if (p.coil_span_c > 0.1)
      say("note: plateau " + std::to_string(p.id) + ": the coil temperature moved " + fixed(p.coil_span_c, 2) +
          " degC over its steps: its NL and asymmetry include the scale factor's change with temperature over the sequence");
  out << "\n";
  out << "temperature sensitivity:  " << coefficient_text(r->tc_ppm_per_c, 3, "ppm/degC") << "\n";
  out << "temperature rate:         " << coefficient_text(r->temp_rate_ppm_per_c_per_min, 3, "ppm per degC/min") << "\n";
  out << "model form (firmware):    SF(T) = SF0 (1 + k1 (T - T0) + k2 (T - T0)^2), T the coil temperature " << o.coil_column << "\n";
  out << "  SF0 " << fixed(r->model_sf0, 9) << ", T0 " << fixed(o.t0_c, 1) << " degC\n";
  out << "  k1  " << coefficient_text(r->k1_ppm_per_c, 3, "ppm/degC") << "\n";
  out << "  k2  " << coefficient_text(r->k2_ppm_per_c2, 5, "ppm/degC^2") << "\n";
  out << "  rms of the plateaus about it " << fixed(r->model_rms_ppm, 2) << " ppm\n";
  return kExitOk;
}

void add_scale_factor_command(CLI::App& app, int& code) {
  static ScaleFactorOptions o;
  auto* c = app.add_subcommand("scale-factor",
                               "Scale factor over temperature of a rate-sequence run (CSV): per plateau bias, scale factor, "
                               "nonlinearity and asymmetry (IEEE Std 952), then its temperature sensitivity and model form");
  c->add_option("run", o.run, "The rate-sequence CSV (time_s, plateau, rate_in_dps, rate_out_dps, t1_c), e.g. from fogctl simulate --rate-sequence")
      ->required();
  c->add_option("--settle", o.settle_s, "Seconds dropped at the start of each rate step, s (default 5)");
  c->add_option("--t0", o.t0_c, "The model form's reference temperature T0, degC (default 20)");
  c->add_option("--coil-column", o.coil_column, "The column of the coil temperature the scale factor is a function of (default t1_c)");
  c->add_flag("--json", o.json, "Print one JSON object");
  c->callback([&] {
    std::ostringstream text;
    code = run_scale_factor(o, text, std::cerr);
    // Within the terminal's width, as verify's; JSON as it is.
    std::cout << (o.json ? text.str() : fit_lines(text.str(), output_width())) << std::flush;
  });
}

}  // namespace fogbench::cli
