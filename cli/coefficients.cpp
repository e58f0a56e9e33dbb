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
#include <optional>
#include <vector>
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

std::string num3(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.3g", v);
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
  std::vector<double> compensated_dph;  // per sample, the gyro minus the program's drift
};

std::expected<Reference, std::string> reference_of(const fw::Program& p, const model::RunData& run, fw::Precision precision) {
  if (p.uses_ta && !run.has_chamber())
    return std::unexpected("the model uses Ta but the reference run " + run.name + " has no chamber_c column");
  if (p.uses_ton && !run.has_power_on())
    return std::unexpected("the model uses the time since power-on but the reference run " + run.name + " has no since_power_on_s column");
  fw::Compensator c(p, precision);
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
    r.compensated_dph.push_back(run.gyro_dph[i] - mu);
    ++r.rows;
  }
  return r;
}

// The run at the firmware's sample interval: a run sampled k times slower (k a whole number) is
// interpolated linearly between its samples (the inputs a faster firmware would read between
// them, no information added), so that the reference vector is at the firmware's rate.
std::expected<model::RunData, std::string> at_interval(const model::RunData& run, double dt_s, std::size_t& every) {
  every = 1;
  if (run.size() < 2) return run;
  const double run_dt = (run.time_s.back() - run.time_s.front()) / static_cast<double>(run.size() - 1);
  if (std::abs(run_dt - dt_s) <= 0.01 * dt_s) return run;
  const double ratio = run_dt / dt_s;
  const auto k = static_cast<std::size_t>(std::lround(ratio));
  if (k < 2 || std::abs(ratio - static_cast<double>(k)) > 0.01)
    return std::unexpected("the reference run " + run.name + " is sampled every " + num3(run_dt) + " s; --dt " + num3(dt_s) +
                           " needs a run sampled every " + num3(dt_s) + " s or a whole multiple of it (give --run)");
  every = k;
  model::RunData r;
  r.name = run.name + " interpolated to " + num3(dt_s) + " s";
  auto lerp = [&](const std::vector<double>& v, std::vector<double>& out) {
    if (v.empty()) return;
    for (std::size_t i = 0; i + 1 < v.size(); ++i)
      for (std::size_t j = 0; j < k; ++j) out.push_back(v[i] + (v[i + 1] - v[i]) * static_cast<double>(j) / static_cast<double>(k));
    out.push_back(v.back());
  };
  lerp(run.time_s, r.time_s);
  lerp(run.gyro_dph, r.gyro_dph);
  lerp(run.t1_c, r.t1_c);
  lerp(run.t2_c, r.t2_c);
  lerp(run.chamber_c, r.chamber_c);
  lerp(run.since_power_on_s, r.since_power_on_s);
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
  std::size_t every = 1;  // samples of the firmware per sample of the run
  auto fast = at_interval(run, o.dt_s, every);
  if (!fast) {
    err << me << fast.error() << "\n";
    return kExitError;
  }
  auto ref = reference_of(*program, *fast, o.single ? fw::Precision::single_precision : fw::Precision::double_precision);
  if (!ref) {
    err << me << ref.error() << "\n";
    return kExitError;
  }
  if (ref->rows < 1000) {
    err << me << "the reference run " << fast->name << " has " << ref->rows << " samples; a reference vector needs at least 1000\n";
    return kExitError;
  }

  // The firmware form against the model on the reference run: the compensated std of both from
  // the sample where the program's windows hold real samples (before it, both lean on edges:
  // the program on its opening fill, the model on its shrunk windows). Beyond 5 % the form is
  // not the model (a late program, or a run at another sample interval): exit 1.
  for (const auto& t : program->terms)
    if (t.late_s > 0) {
      err << "warning: the model is computed " << t.late_s << " s later than it was fitted (causal firmware: "
          << t.name << " reads its signals ahead of its lag)\n";
      break;
    }
  std::optional<double> firmware_std, offline_std;
  // (in the run's samples; the firmware's at a faster rate are read at the run's instants)
  const std::size_t from = (static_cast<std::size_t>(fw::warm_up_samples(*program)) + every - 1) / every;
  if (auto mu = model::predict(*m, run); mu && run.size() > from + 2) {
    std::vector<double> offline, firmware;
    for (std::size_t k = from; k < run.size(); ++k) {
      offline.push_back(run.gyro_dph[k] - (*mu)[k]);
      firmware.push_back(ref->compensated_dph[k * every]);
    }
    firmware_std = model::stddev(firmware);
    offline_std = model::stddev(offline);
  }
  bool beyond = false;
  if (firmware_std && offline_std) {
    beyond = *firmware_std > 1.05 * *offline_std;
    err << (beyond ? "fogctl coefficients: NOT the model: " : "") << "on the reference run " << run.name << " (from sample " << from
        << ") the compensated std is " << num3(*firmware_std) << " deg/h by the firmware form, " << num3(*offline_std)
        << " deg/h as the model computes it (" << (*firmware_std >= *offline_std ? "+" : "")
        << num3(100.0 * (*firmware_std / *offline_std - 1.0)) << " %, at most +5 %)\n";
  }

  std::string text;
  if (o.format == "json") {
    auto j = nlohmann::json::parse(fw::to_json_text(*program));
    j["model"] = {{"terms", m->terms_string()}, {"fitted_on", m->fitted_on.name}, {"created_at", m->created_at}};
    j["reference"] = {{"run", fast->name}, {"samples", ref->rows}, {"columns", "t1_c,t2_c,ta_c,ton_s,gyro_dph,mu_dph,compensated_dph"},
                      {"from_sample", from}, {"precision", o.single ? "float" : "double"},
                      {"tolerance_dph", o.single ? fw::kToleranceFloat_dph : fw::kToleranceDouble_dph}};
    if (firmware_std && offline_std) {
      j["reference"]["compensated_std_dph"] = *firmware_std;
      j["reference"]["model_compensated_std_dph"] = *offline_std;
      j["reference"]["within_5_percent"] = !beyond;
    }
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
  return beyond ? kExitFailed : kExitOk;
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
  c->add_flag("--float", o.single,
              "The reference vector as a float build computes it (fogcomp.h with FOGCOMP_FLOAT): a port in single precision "
              "matches its mu_dph to 1e-4 deg/h (double: 1e-9)");
  c->add_option("--dt", o.dt_s, "The firmware's sample interval, s (default 1)");
  c->add_flag("--late", o.late,
              "When a term's lag is shorter than its slopes' half-window (30 s), compute the whole model that much later, with a warning, "
              "instead of refusing (exit 1 when that costs more than 5 % of the compensated std on the reference run)");
  add_run_input(c, o.input);
  c->callback([&] { code = run_coefficients(o, std::cout, std::cerr); });
}

}  // namespace fogbench::cli
