// The fleet generator (generate.hpp).
#include "fogbench/plant/generate.hpp"

#include <cstring>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <set>

namespace fogbench::plant {
namespace {

struct FigureLaw {
  const char* name;
  const char* source;
  double mean, sd;
};

// Plausible values for the paper's model and its verification (units as in docs/model.md).
constexpr FigureLaw kLaws[] = {
    {"mu0", "model", 0.50, 0.20},       {"d(T1)", "model", 2.00, 0.30},        {"grad", "model", -0.80, 0.10},
    {"sigma_a", "model", 0.15, 0.01},   {"ratio", "verification", 0.12, 0.02}, {"comp_std", "verification", 0.050, 0.005},
};

std::string iso(std::int64_t unix_s) {
  std::time_t t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

void num(std::string& out, double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace

PlantResult<GeneratedPlant> generate_fleet(Connection& c, const GenerateOptions& o) {
  if (o.runs < 1 || o.units_per_run < 1 || o.lots < 1 || o.lots > o.runs || o.benches < 1 || o.shifted_lot < 0 ||
      o.shifted_lot >= o.lots || o.outliers < 0 || o.sample_runs.value_or(0) < 0 || o.samples_per_unit < 1 || o.samples_commit_runs < 1 ||
      !(o.fail_rate >= 0 && o.marginal_rate >= 0 && o.marginal_bench_rate >= 0 && o.fail_rate + o.marginal_rate <= 1 &&
        o.fail_rate + o.marginal_bench_rate <= 1) ||
      o.marginal_bench < 0 || o.marginal_bench > o.benches)
    return std::unexpected(PlantError{PlantErrc::invalid_argument, "generate a fleet: inconsistent options"});
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal;
  auto truncated = [&] {
    for (;;) {
      const double z = normal(rng);
      if (std::abs(z) <= 2.5) return z;
    }
  };
  auto lot_of = [&](int run) { return static_cast<int>(static_cast<std::int64_t>(run) * o.lots / o.runs); };
  auto lot_name = [&](int k) { return "LOT-" + std::to_string(1000 + k); };

  // The outliers: units outside the shifted lot, in the second half of the runs.
  std::set<std::pair<int, int>> outliers;
  std::uniform_int_distribution<int> pick_run(o.runs / 2, o.runs - 1), pick_unit(0, o.units_per_run - 1);
  for (int guard = 0; static_cast<int>(outliers.size()) < o.outliers && guard < 100000; ++guard) {
    const int r = pick_run(rng);
    if (lot_of(r) != o.shifted_lot) outliers.insert({r, pick_unit(rng)});
  }

  // The verdicts from a generator of their own: the figures are the same whatever the rates.
  std::mt19937_64 verdict_rng(o.seed ^ 0x9e3779b97f4a7c15ULL);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  GeneratedPlant g;
  g.shifted_lot = lot_name(o.shifted_lot);
  if (o.marginal_bench > 0) g.marginal_bench = o.bench_prefix + std::to_string(o.marginal_bench);
  std::string runs, units, models, verifications, verdicts, figures, samples;
  const std::int64_t t0 = 1767225600;  // 2026-01-01T00:00:00Z
  for (int r = 0; r < o.runs; ++r) {
    const std::string bench = o.bench_prefix + std::to_string(1 + r % o.benches);
    const std::int64_t run_id = 1 + r / o.benches;
    const std::int64_t start = t0 + static_cast<std::int64_t>(r) * 1800, end = start + 10800;
    runs += bench + "\t" + std::to_string(run_id) + "\t" + iso(start) + "\tqualification\tfit\tcompleted\tprofile finished\t" +
            iso(start) + "\t" + iso(end) + "\n";
    ++g.runs;
    for (int u = 0; u < o.units_per_run; ++u) {
      const std::string serial = "GEN-" + std::to_string(100000 + r * o.units_per_run + u);
      const std::string lot = lot_name(lot_of(r));
      units += bench + "\t" + std::to_string(run_id) + "\t" + std::to_string(u) + "\t" + serial + "\t" + lot + "\n";
      ++g.units;
      const std::string model_id = std::to_string(run_id * 100 + u), ver_id = model_id;
      models += bench + "\t" + model_id + "\t" + std::to_string(run_id) + "\t" + std::to_string(u) + "\t" + serial +
                "\t1\t" + iso(end) + "\tpaper\td(T1)@auto + grad@auto\t{\"generated\": true}\n";
      const bool planted = outliers.contains({r, u});
      if (planted) g.outlier_serials.push_back(serial);
      for (const auto& law : kLaws) {
        double z = truncated();
        if (law.name == o.figure && lot_of(r) == o.shifted_lot) z += o.shift_sigma;
        if (law.name == o.figure && planted) z = (u % 2 ? -1 : 1) * o.outlier_sigma;
        const double v = law.mean + law.sd * z;
        figures += bench + "\t" + std::to_string(run_id) + "\t" + std::to_string(u) + "\t" + law.source + "\t" +
                   (std::string_view(law.source) == "model" ? model_id : ver_id) + "\t" + law.name + "\t";
        num(figures, v);
        figures += "\n";
        ++g.figures;
      }
      const bool planted_bench = 1 + r % o.benches == o.marginal_bench && r >= o.marginal_from_run;
      const double draw = uniform(verdict_rng);
      const char* verdict = draw < o.fail_rate ? "f\tfail"
                            : draw < o.fail_rate + (planted_bench ? o.marginal_bench_rate : o.marginal_rate)
                                ? "f\tmarginal"
                                : "t\tpass";
      verifications += bench + "\t" + ver_id + "\t" + std::to_string(run_id) + "\t" + std::to_string(u) + "\t" +
                       model_id + "\t" + iso(end) + "\t" + verdict + "\t{\"generated\": true}\n";
      // The unit's verdict as a bench decides it (issue 24): the analysis settings' rule.
      verdicts += bench + "\t" + ver_id + "\t" + serial + "\t" + std::to_string(run_id) + "\t" + std::to_string(u) + "\t" +
                  model_id + "\t" + (std::strchr(verdict, '\t') + 1) + "\tanalysis\t[]\t[]\t" + iso(end) + "\n";
    }
  }

  auto fail = [&](PlantError e) {
    if (e.code != PlantErrc::connection_lost) (void)c.exec("ROLLBACK", "generate");
    e.message = "generate a fleet: " + e.message;
    return std::unexpected(std::move(e));
  };
  if (auto ok = c.exec("BEGIN", "begin"); !ok) return fail(ok.error());
  const std::string like = o.bench_prefix + "%";
  for (const char* t : {"samples", "runs"})
    if (auto ok = c.query(std::string("DELETE FROM fogbench.") + t + " WHERE bench_id LIKE $1", {like}, "delete");
        !ok)
      return fail(ok.error());
  struct Copy {
    const char* sql;
    const std::string* data;
  };
  for (const Copy& cp :
       {Copy{"COPY fogbench.runs (bench_id, run_id, created_at, profile_name, purpose, state, state_reason, started_at, "
             "ended_at) FROM STDIN",
             &runs},
        Copy{"COPY fogbench.units (bench_id, run_id, unit_index, serial, lot) FROM STDIN", &units},
        Copy{"COPY fogbench.models (bench_id, model_id, run_id, unit_index, serial, version, created_at, method, terms, "
             "model_json) FROM STDIN",
             &models},
        Copy{"COPY fogbench.verifications (bench_id, verification_id, run_id, unit_index, model_id, created_at, pass, "
             "verdict, result_json) FROM STDIN",
             &verifications},
        Copy{"COPY fogbench.verdicts (bench_id, verdict_id, serial, run_id, unit_index, model_id, verdict, rule, "
             "limits_json, reasons_json, decided_at) FROM STDIN",
             &verdicts},
        Copy{"COPY fogbench.figures (bench_id, run_id, unit_index, source, source_id, name, value) FROM STDIN",
             &figures}}) {
    if (auto n = c.copy_in(cp.sql, *cp.data, cp.sql); !n) return fail(n.error());
  }
  if (auto ok = c.exec("COMMIT", "commit"); !ok) return fail(ok.error());
  for (std::string* s : {&runs, &units, &models, &verifications, &verdicts, &figures}) std::string().swap(*s);

  // The samples of the first sample_runs runs (every run by default): a slow drift with the
  // chamber's ramp and noise (what they look like matters little here: they measure the store).
  // One COPY per run (units_per_run x samples_per_unit rows: the buffer is that big, whatever the
  // plant's size), in key order (bench, then run) so the primary key's index grows at its right
  // edge; committed every samples_commit_runs runs.
  const int sample_runs = std::min(o.sample_runs.value_or(o.runs), o.runs);
  std::int64_t done = 0;
  bool open = false;
  for (int b = 0; b < o.benches; ++b) {
    for (int r = b; r < sample_runs; r += o.benches) {
      if (!open) {
        if (auto ok = c.exec("BEGIN", "begin"); !ok) return fail(ok.error());
        open = true;
      }
      const std::string head = o.bench_prefix + std::to_string(1 + b) + "\t" + std::to_string(1 + r / o.benches) + "\t";
      samples.clear();
      for (int u = 0; u < o.units_per_run; ++u) {
        const std::string unit = head + std::to_string(u) + "\t";
        for (int i = 0; i < o.samples_per_unit; ++i) {
          const double t = i, temp = 20 + 20 * std::sin(t / 3000.0);
          samples += unit;
          num(samples, t);
          samples += '\t';
          num(samples, temp);
          samples += '\t';
          num(samples, 0.5 + 0.02 * temp + 0.1 * normal(rng));
          samples += '\t';
          num(samples, temp - 0.5);
          samples += "\t100\t2\t0\n";
        }
      }
      auto n = c.copy_in("COPY fogbench.samples (bench_id, run_id, unit_index, t_s, chamber_c, gyro_dph, t1_c, "
                         "frames, phase, flags) FROM STDIN",
                         samples, "copy samples");
      if (!n) return fail(n.error());
      g.samples += *n;
      ++done;
      if (done % o.samples_commit_runs == 0 || done == sample_runs) {
        if (auto ok = c.exec("COMMIT", "commit"); !ok) return fail(ok.error());
        open = false;
      }
      if (o.progress) o.progress(done, sample_runs, g.samples);
    }
  }
  return g;
}

}  // namespace fogbench::plant
