// fogctl coefficients: the model compiled for a gyro's firmware, as JSON, CSV or a C
// initializer for firmware/fogcomp.h, and a reference vector computed by the same program.
#include "coefficients.hpp"

#include <CLI/CLI.hpp>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <unistd.h>
#include <iostream>
#include <nlohmann/json.hpp>

#include "fogbench/model/firmware.hpp"
#include "fogbench/model/json.hpp"
#include "offline.hpp"

namespace fogbench::cli {
namespace {

namespace fw = model::firmware;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

bool c_identifier(const std::string& s) {
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
  for (unsigned char c : s)
    if (!std::isalnum(c) && c != '_') return false;
  return true;
}

// The reference vector: each sample's inputs, the drift the program computes and the gyro's
// output compensated with it. Inputs are what the firmware sees; rows with a missing input are
// left out (the firmware would hold its last value; the reference stays unambiguous).
struct Reference {
  std::string csv;
  std::size_t rows = 0;
};

std::expected<Reference, std::string> reference_of(const fw::Program& p, const model::RunData& run) {
  if (p.uses_ta && !run.has_chamber())
    return std::unexpected("the model uses Ta but the reference run " + run.name + " has no chamber_c column");
  if (p.uses_ton && !run.has_power_on())
    return std::unexpected("the model uses the time since power-on but the reference run " + run.name + " has no since_power_on_s column");
  fw::Compensator c(p);
  Reference r;
  r.csv = "t1_c,t2_c,ta_c,ton_s,gyro_dph,mu_dph,compensated_dph\n";
  for (std::size_t i = 0; i < run.size(); ++i) {
    fw::Input in;
    in.t1_c = run.t1_c[i];
    in.t2_c = run.t2_c[i];
    in.ta_c = run.has_chamber() ? run.chamber_c[i] : 0.0;
    in.ton_s = run.has_power_on() ? run.since_power_on_s[i] : 0.0;
    if (!std::isfinite(in.t1_c) || !std::isfinite(in.t2_c) || !std::isfinite(in.ta_c) || !std::isfinite(in.ton_s) ||
        !std::isfinite(run.gyro_dph[i]))
      return std::unexpected("the reference run " + run.name + " has a missing value at sample " + std::to_string(i) +
                             " (time " + num(run.time_s[i]) + " s): give --run a run without gaps");
    const double mu = c.step(in);
    r.csv += num(in.t1_c) + "," + num(in.t2_c) + "," + num(in.ta_c) + "," + num(in.ton_s) + "," + num(run.gyro_dph[i]) + "," +
             num(mu) + "," + num(run.gyro_dph[i] - mu) + "\n";
    ++r.rows;
  }
  return r;
}

}  // namespace

int run_coefficients(const CoefficientsOptions& o, std::ostream& out, std::ostream& err) {
  const std::string me = "fogctl coefficients: ";
  if (o.format != "json" && o.format != "csv" && o.format != "c") {
    err << me << "--format " << o.format << ": expected json, csv or c\n";
    return kExitError;
  }
  if (!c_identifier(o.name)) {
    err << me << "--name '" << o.name << "' is not a C identifier\n";
    return kExitError;
  }
  // A file, or else a serial whose current model fogbenchd has (model.get).
  std::error_code fec;
  const bool is_file = std::filesystem::exists(o.model, fec) || o.model.ends_with(".json");
  std::expected<model::Model, std::string> m = std::unexpected(std::string());
  if (is_file) {
    m = load_model(o.model);
  } else {
    auto c = commands::open(o.daemon);
    if (!c) return commands::report(c.error(), err);
    auto got = c->call("model.get", {{"serial", o.model}});
    if (!got) return commands::report(got.error(), err);
    m = model::model_from_text((*got)["model"].dump());
    if (!m) m = std::unexpected("serial " + o.model + ": the daemon's model " + (*got)["id"].dump() + " is not readable: " + m.error());
  }
  if (!m) {
    err << me << m.error() << "\n";
    return kExitError;
  }
  auto program = fw::compile(*m, o.dt_s, o.late);
  if (!program) {
    err << me << o.model << ": " << program.error() << (o.late ? "" : " (--late)") << "\n";
    return kExitError;
  }
  // The reference vector: a given run, or the exp1 profile on the simulated bench.
  model::RunData run;
  if (!o.run.empty()) {
    auto r = load_run(o.run, o.input);
    if (!r) {
      err << me << r.error() << "\n";
      return kExitError;
    }
    run = std::move(*r);
  } else {
    // exactly what `fogctl simulate --profile exp1` writes (seed 1, the distributed coil)
    const auto tmp = std::filesystem::temp_directory_path() / ("fogctl-reference-" + std::to_string(::getpid()) + ".csv");
    SimulateOptions so;
    so.profile = "exp1";
    so.output = tmp.string();
    so.quiet = true;
    std::ostringstream sim_out, sim_err;
    if (run_simulate(so, sim_out, sim_err) != kExitOk) {
      err << me << "simulating exp1 for the reference vector: " << sim_err.str() << " (give --run)\n";
      return kExitError;
    }
    auto r = load_run(tmp.string(), {});
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    if (!r) {
      err << me << r.error() << "\n";
      return kExitError;
    }
    run = std::move(*r);
    run.name = "exp1 simulated (seed 1)";
  }
  auto ref = reference_of(*program, run);
  if (!ref) {
    err << me << ref.error() << "\n";
    return kExitError;
  }
  if (ref->rows < 1000) {
    err << me << "the reference run " << run.name << " has " << ref->rows << " samples; a reference vector needs at least 1000\n";
    return kExitError;
  }

  // A late program is not the model: say what it costs on the reference run.
  bool late = false;
  for (const auto& t : program->terms)
    if (t.late_s > 0) {
      late = true;
      err << "warning: " << t.name << " is computed " << t.late_s << " s later than the model (causal firmware)\n";
    }
  if (late) {
    auto mu = model::predict(*m, run);
    if (mu) {
      std::vector<double> offline, firmware;
      std::size_t i = 0;
      for (std::size_t k = 0; k < run.size(); ++k) offline.push_back(run.gyro_dph[k] - (*mu)[k]);
      std::string line;
      for (std::size_t start = ref->csv.find('\n') + 1; start < ref->csv.size(); ++i) {
        const auto end = ref->csv.find('\n', start);
        line = ref->csv.substr(start, end - start);
        firmware.push_back(std::stod(line.substr(line.rfind(',') + 1)));
        start = end + 1;
      }
      err << "warning: on the reference run " << run.name << " the compensated std is " << model::stddev(firmware)
          << " deg/h computed late against " << model::stddev(offline) << " deg/h as the model computes it\n";
    }
  }

  std::string text;
  if (o.format == "json") {
    auto j = nlohmann::json::parse(fw::to_json_text(*program));
    j["model"] = {{"terms", m->terms_string()}, {"fitted_on", m->fitted_on.name}, {"created_at", m->created_at}};
    j["reference"] = {{"run", run.name}, {"samples", ref->rows}, {"columns", "t1_c,t2_c,ta_c,ton_s,gyro_dph,mu_dph,compensated_dph"}};
    text = j.dump(2) + "\n";
  } else if (o.format == "csv") {
    text = fw::to_csv(*program);
  } else {
    text = fw::to_c(*program, o.name);
  }
  // Write the reference first: a failure leaves no program without its reference.
  if (!o.reference.empty())
    if (auto w = write_text(o.reference, ref->csv); !w) {
      err << me << w.error() << "\n";
      return kExitError;
    }
  if (o.output.empty()) {
    out << text;
  } else if (auto w = write_text(o.output, text); !w) {
    err << me << w.error() << "\n";
    return kExitError;
  }
  return kExitOk;
}

void add_coefficients_command(CLI::App& app, int& code) {
  static CoefficientsOptions o;
  auto* c = app.add_subcommand("coefficients", "A model as the gyro's firmware computes it: causal program, coefficients, reference vector");
  c->add_option("model", o.model, "The model's JSON file (fogctl fit -o, or fogctl model get SERIAL -o), or a serial: its current model from fogbenchd")->required();
  commands::add_common(c, o.daemon, /*with_json=*/false);
  c->add_option("--format", o.format, "json (default), csv, or c (an initializer for firmware/fogcomp.h)");
  c->add_option("--name", o.name, "Name of the C initializer (--format c)");
  c->add_option("-o,--output", o.output, "Write to this file instead of standard output");
  c->add_option("--reference", o.reference, "Write the reference vector (inputs, drift, compensated output per sample) to this CSV file");
  c->add_option("--run", o.run, "The run whose inputs make the reference vector (default: exp1 on the simulated bench)");
  c->add_option("--dt", o.dt_s, "The firmware's sample interval, s (default 1)");
  c->add_flag("--late", o.late, "Compute a term whose lag is shorter than its slopes' half-window (30 s) that much later, with a warning, instead of refusing");
  add_run_input(c, o.input);
  c->callback([&] { code = run_coefficients(o, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
