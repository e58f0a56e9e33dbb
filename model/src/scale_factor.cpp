// Scale factor over temperature (see fogbench/model/scale_factor.hpp and docs/scale-factor.md).
#include "fogbench/model/scale_factor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string_view>
#include <type_traits>

#include "lsq.hpp"

namespace fogbench::model::sf {

namespace {

constexpr double kPpm = 1e6;

// A number as people read it: 6 significant digits (g++ 12 has no <format>).
std::string str(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}
std::string str(const char* s) { return s; }
std::string str(const std::string& s) { return s; }
template <typename I>
  requires std::is_integral_v<I>
std::string str(I v) {
  return std::to_string(v);
}
// `text` with each "{}" replaced by the next argument.
template <typename... A>
std::string format(std::string_view text, const A&... args) {
  const std::string parts[] = {str(args)..., {}};
  std::string out;
  std::size_t k = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '{' && i + 1 < text.size() && text[i + 1] == '}' && k < sizeof...(A)) {
      out += parts[k++];
      ++i;
    } else {
      out += text[i];
    }
  }
  return out;
}
constexpr double kDphPerDps = 3600.0;

std::string where(int plateau) { return format("plateau {}", plateau); }
std::string where(int plateau, std::size_t step, double rate_dps, double start_s) {
  return format("plateau {}, step {} ({} deg/s from t = {} s)", plateau, step, rate_dps, start_s);
}

// The rows of one step: [begin, end) of the record.
struct StepRows {
  std::size_t begin = 0, end = 0;
};
struct PlateauRows {
  int id = 0;
  std::vector<StepRows> steps;
};

std::expected<std::vector<PlateauRows>, std::string> split(const RateRecord& r) {
  const std::size_t n = r.size();
  if (r.plateau.size() != n || r.rate_in_dps.size() != n || r.rate_out_dps.size() != n || r.coil_c.size() != n)
    return std::unexpected(format("columns of different lengths: time_s {}, plateau {}, rate_in_dps {}, rate_out_dps {}, coil_c {}",
                                       n, r.plateau.size(), r.rate_in_dps.size(), r.rate_out_dps.size(), r.coil_c.size()));
  if (n == 0) return std::unexpected("no samples: a rate sequence needs at least one plateau");
  std::vector<PlateauRows> out;
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& [name, v] : std::array{std::pair{"time_s", r.time_s[i]}, std::pair{"rate_in_dps", r.rate_in_dps[i]},
                                            std::pair{"rate_out_dps", r.rate_out_dps[i]}, std::pair{"coil_c", r.coil_c[i]}})
      if (!std::isfinite(v))
        return std::unexpected(format("{}, row {}: {} is not a finite number ({})", where(r.plateau[i]), i, name, v));
    if (i > 0 && !(r.time_s[i] > r.time_s[i - 1]))
      return std::unexpected(format("{}, row {}: time_s {} s does not increase (previous {} s)", where(r.plateau[i]), i,
                                         r.time_s[i], r.time_s[i - 1]));
    const bool new_plateau = out.empty() || out.back().id != r.plateau[i];
    if (new_plateau) {
      for (const auto& p : out)
        if (p.id == r.plateau[i])
          return std::unexpected(format("{}, row {}: the plateau appears again after another one (t = {} s): a plateau's samples must be contiguous",
                                             where(r.plateau[i]), i, r.time_s[i]));
      out.push_back({r.plateau[i], {}});
    }
    auto& steps = out.back().steps;
    if (new_plateau || r.rate_in_dps[i] != r.rate_in_dps[i - 1])
      steps.push_back({i, i + 1});
    else
      steps.back().end = i + 1;
  }
  return out;
}

// Least-squares slope of y over x (sum (x - mx)(y - my) / sum (x - mx)^2); 0 when x does not vary.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
  mx /= static_cast<double>(x.size());
  my /= static_cast<double>(x.size());
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) sxy += (x[i] - mx) * (y[i] - my), sxx += (x[i] - mx) * (x[i] - mx);
  return sxx > 0.0 ? sxy / sxx : 0.0;
}

std::expected<Plateau, std::string> fit_plateau(const RateRecord& r, const PlateauRows& rows, const Options& o, std::size_t& dropped) {
  Plateau p;
  p.id = rows.id;
  std::vector<double> used_t, used_c;
  for (std::size_t k = 0; k < rows.steps.size(); ++k) {
    const auto [b, e] = rows.steps[k];
    Step s;
    s.index = k;
    s.rate_in_dps = r.rate_in_dps[b];
    s.start_s = r.time_s[b];
    double so = 0.0, sc = 0.0;
    for (std::size_t i = b; i < e; ++i) {
      if (r.time_s[i] < s.start_s + o.settle_s) {
        ++dropped;
        continue;
      }
      ++s.n_used;
      so += r.rate_out_dps[i];
      sc += r.coil_c[i];
      used_t.push_back(r.time_s[i]);
      used_c.push_back(r.coil_c[i]);
    }
    if (s.n_used == 0)
      return std::unexpected(format("{}: no sample left after dropping the first {} s of the step ({} samples over {} s)",
                                         where(p.id, k, s.rate_in_dps, s.start_s), o.settle_s, e - b, r.time_s[e - 1] - s.start_s));
    s.mean_out_dps = so / static_cast<double>(s.n_used);
    s.mean_coil_c = sc / static_cast<double>(s.n_used);
    p.n_used += s.n_used;
    p.steps.push_back(s);
  }
  std::vector<double> x, y;
  bool any_pos = false, any_neg = false;
  for (const auto& s : p.steps) {
    x.push_back(s.rate_in_dps);
    y.push_back(s.mean_out_dps);
    any_pos = any_pos || s.rate_in_dps > 0.0;
    any_neg = any_neg || s.rate_in_dps < 0.0;
  }
  const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
  if (*lo == *hi)
    return std::unexpected(format("{}: a single input rate ({} deg/s over {} steps): a scale factor needs at least two distinct rates",
                                       where(p.id), *lo, x.size()));
  if (!any_pos || !any_neg)
    return std::unexpected(format("{}: no {} input rate, so no asymmetry: the sequence needs both signs", where(p.id),
                                       any_pos ? "negative" : "positive"));
  // The least-squares line of output vs input (IEEE Std 952, 3.1 "scale factor").
  p.scale_factor = slope(x, y);
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
  mx /= static_cast<double>(x.size());
  my /= static_cast<double>(x.size());
  const double intercept = my - p.scale_factor * mx;
  double sse = 0.0, sxx = 0.0, max_abs_in = 0.0, max_res = 0.0, wsum = 0.0, wc = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double res = y[i] - (intercept + p.scale_factor * x[i]);
    sse += res * res;
    sxx += (x[i] - mx) * (x[i] - mx);
    max_abs_in = std::max(max_abs_in, std::abs(x[i]));
    max_res = std::max(max_res, std::abs(res));
    const double w = (x[i] - mx) * x[i];
    wsum += w;
    wc += w * p.steps[i].mean_coil_c;
  }
  p.scale_factor_se = x.size() > 2 ? std::sqrt(sse / static_cast<double>(x.size() - 2) / sxx) : 0.0;
  p.full_scale_out_dps = std::abs(p.scale_factor) * max_abs_in;
  if (!(p.full_scale_out_dps > 0.0))
    return std::unexpected(format("{}: the fitted scale factor is zero: the output does not follow the input", where(p.id)));
  p.nonlinearity_ppm = kPpm * max_res / p.full_scale_out_dps;
  for (std::size_t i = 0; i < x.size(); ++i)
    p.steps[i].residual_ppm_fso = kPpm * (y[i] - (intercept + p.scale_factor * x[i])) / p.full_scale_out_dps;
  p.coil_c = wc / wsum;
  double c_lo = p.steps[0].mean_coil_c, c_hi = c_lo;
  for (const auto& s : p.steps) c_lo = std::min(c_lo, s.mean_coil_c), c_hi = std::max(c_hi, s.mean_coil_c);
  p.coil_span_c = c_hi - c_lo;
  p.temp_rate_c_per_min = 60.0 * slope(used_t, used_c);
  // The bias: the output at zero input, measured where the sequence has zero-rate steps, else
  // the line's intercept. The two half scale factors are slopes through it (least squares
  // through a fixed point: sum (o - B) r / sum r^2), so the asymmetry is not the line's.
  double zero_out = 0.0;
  std::size_t zeros = 0;
  for (const auto& s : p.steps)
    if (s.rate_in_dps == 0.0) zero_out += s.mean_out_dps, ++zeros;
  const double bias_dps = zeros > 0 ? zero_out / static_cast<double>(zeros) : intercept;
  p.bias_from_zero_rate = zeros > 0;
  p.bias_dph = kDphPerDps * bias_dps;
  double np = 0.0, dp = 0.0, nn = 0.0, dn = 0.0;
  for (const auto& s : p.steps) {
    const double d = s.mean_out_dps - bias_dps, rr = s.rate_in_dps * s.rate_in_dps;
    if (s.rate_in_dps > 0.0) np += d * s.rate_in_dps, dp += rr;
    if (s.rate_in_dps < 0.0) nn += d * s.rate_in_dps, dn += rr;
  }
  p.sf_positive = np / dp;
  p.sf_negative = nn / dn;
  p.asymmetry_ppm = kPpm * (p.sf_positive - p.sf_negative) / (0.5 * (p.sf_positive + p.sf_negative));
  return p;
}

// The across-plateau regression SF_i = a + b dT_i [+ c dT_i^2] [+ d Tdot_i].
struct Across {
  bool ok = false;
  std::vector<double> theta, se;
  double sigma = 0.0;
};
Across regress(const std::vector<Plateau>& ps, double t0_c, bool quadratic, bool with_rate) {
  const std::size_t k = 2 + (quadratic ? 1 : 0) + (with_rate ? 1 : 0);
  detail::LeastSquares lsq(k);
  for (const auto& p : ps) {
    const double dt = p.coil_c - t0_c;
    std::vector<double> row{1.0, dt};
    if (quadratic) row.push_back(dt * dt);
    if (with_rate) row.push_back(p.temp_rate_c_per_min);
    lsq.add(row, p.scale_factor);
  }
  auto r = lsq.solve();
  Across a;
  a.ok = r.ok;
  a.theta = r.theta;
  a.se = r.se;
  a.sigma = r.sigma;
  return a;
}

}  // namespace

std::string Options::validate() const {
  if (!(std::isfinite(settle_s) && settle_s >= 0.0)) return format("settle_s must be a finite number >= 0 s, got {}", settle_s);
  if (!std::isfinite(t0_c) || t0_c < -273.15) return format("t0_c must be a temperature in degC, got {}", t0_c);
  if (!(std::isfinite(min_temp_rate_span_c_per_min) && min_temp_rate_span_c_per_min > 0.0))
    return format("min_temp_rate_span_c_per_min must be > 0 degC/min, got {}", min_temp_rate_span_c_per_min);
  return {};
}

RateRecord turning_plateaus(const RateRecord& r, std::size_t* rows_dropped) {
  const std::size_t n = r.size();
  // A column of another length is fit()'s to name: returned as it is.
  if (r.plateau.size() != n || r.rate_in_dps.size() != n || r.rate_out_dps.size() != n ||
      r.coil_c.size() != n)
    return r;
  std::vector<int> turning;
  for (std::size_t i = 0; i < n; ++i)
    if (r.rate_in_dps[i] != 0.0 && std::find(turning.begin(), turning.end(), r.plateau[i]) == turning.end())
      turning.push_back(r.plateau[i]);
  RateRecord out;
  std::size_t dropped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::find(turning.begin(), turning.end(), r.plateau[i]) == turning.end()) {
      ++dropped;
      continue;
    }
    out.time_s.push_back(r.time_s[i]);
    out.plateau.push_back(r.plateau[i]);
    out.rate_in_dps.push_back(r.rate_in_dps[i]);
    out.rate_out_dps.push_back(r.rate_out_dps[i]);
    out.coil_c.push_back(r.coil_c[i]);
  }
  if (rows_dropped) *rows_dropped = dropped;
  return out;
}

std::expected<RateRecord, std::string> rate_record(const RunData& run) {
  const std::size_t n = run.size();
  if (!run.has_rate_in()) return std::unexpected("the run drove no rate table (no commanded rate stored)");
  if (!run.has_step()) return std::unexpected("the run has no profile step per sample: its plateaus are not known");
  if (run.rate_in_dps.size() != n || run.step.size() != n || run.gyro_dph.size() != n || run.t1_c.size() != n ||
      (run.has_phase() && run.phase.size() != n) || (run.has_flags() && run.flags.size() != n))
    return std::unexpected(format("{}: columns of different lengths", run.name));
  RateRecord all;
  for (std::size_t i = 0; i < n; ++i) {
    if (run.has_phase() && run.phase[i] == Phase::settle) continue;
    if (run.flagged(i)) continue;
    const double out = run.gyro_dph[i] / kDphPerDps;
    if (!std::isfinite(run.time_s[i]) || !std::isfinite(run.rate_in_dps[i]) || !std::isfinite(out) ||
        !std::isfinite(run.t1_c[i]))
      continue;
    all.time_s.push_back(run.time_s[i]);
    all.plateau.push_back(run.step[i]);
    all.rate_in_dps.push_back(run.rate_in_dps[i]);
    all.rate_out_dps.push_back(out);
    all.coil_c.push_back(run.t1_c[i]);
  }
  RateRecord turned = turning_plateaus(all);
  if (turned.size() == 0)
    return std::unexpected("no profile step in which the rate table turned (every good sample's commanded rate is 0 deg/s)");
  return turned;
}

double model_scale_factor(const Result& r, double t_c) {
  const double dt = t_c - r.options.t0_c;
  return r.model_sf0 * (1.0 + (r.k1_ppm_per_c.value.value_or(0.0) * dt + r.k2_ppm_per_c2.value.value_or(0.0) * dt * dt) / kPpm);
}

std::expected<Result, std::string> fit(const RateRecord& record, const Options& options) {
  if (auto bad = options.validate(); !bad.empty()) return std::unexpected(bad);
  auto rows = split(record);
  if (!rows) return std::unexpected(rows.error());
  Result res;
  res.options = options;
  for (const auto& pr : *rows) {
    auto p = fit_plateau(record, pr, options, res.n_samples_dropped);
    if (!p) return std::unexpected(p.error());
    res.plateaus.push_back(std::move(*p));
  }
  const auto& ps = res.plateaus;
  const std::size_t n = ps.size();
  double sf_mean = 0.0;
  for (const auto& p : ps) sf_mean += p.scale_factor;
  sf_mean /= static_cast<double>(n);
  res.sf0 = res.model_sf0 = sf_mean;
  // The temperature rate term: only where the plateaus' rates differ enough to tell it from
  // the temperature's, and with a plateau to spare for its standard error.
  double rate_lo = ps[0].temp_rate_c_per_min, rate_hi = rate_lo;
  for (const auto& p : ps) rate_lo = std::min(rate_lo, p.temp_rate_c_per_min), rate_hi = std::max(rate_hi, p.temp_rate_c_per_min);
  bool with_rate = false;
  if (rate_hi - rate_lo < options.min_temp_rate_span_c_per_min)
    res.temp_rate_ppm_per_c_per_min.not_identified =
        format("the plateaus' temperature rates span {} degC/min, under {} degC/min: run some rate sequences on ramps",
                    std::round(1000.0 * (rate_hi - rate_lo)) / 1000.0, options.min_temp_rate_span_c_per_min);
  else if (n < 4)
    res.temp_rate_ppm_per_c_per_min.not_identified =
        format("needs at least 4 plateaus (constant, temperature, temperature rate and one to spare), have {}", n);
  else
    with_rate = true;
  auto fill = [&](Coefficient& c, const Across& a, std::size_t i, double scale) {
    c.value = scale * a.theta[i] / a.theta[0];
    c.se = std::abs(scale * a.se[i] / a.theta[0]);
  };
  const std::size_t k_lin = 2 + (with_rate ? 1 : 0);
  if (n < k_lin + 1) {
    res.tc_ppm_per_c.not_identified = format("needs at least {} plateaus at distinct temperatures, have {}", k_lin + 1, n);
    res.k1_ppm_per_c.not_identified = res.tc_ppm_per_c.not_identified;
  } else if (auto lin = regress(ps, options.t0_c, false, with_rate); !lin.ok || lin.theta[0] == 0.0) {
    res.tc_ppm_per_c.not_identified = "the plateaus' coil temperatures (and temperature rates) do not vary independently";
    res.k1_ppm_per_c.not_identified = res.tc_ppm_per_c.not_identified;
    if (with_rate) res.temp_rate_ppm_per_c_per_min.not_identified = res.tc_ppm_per_c.not_identified;
  } else {
    res.sf0 = res.model_sf0 = lin.theta[0];
    fill(res.tc_ppm_per_c, lin, 1, kPpm);
    if (with_rate) fill(res.temp_rate_ppm_per_c_per_min, lin, 2, kPpm);
    res.k1_ppm_per_c = res.tc_ppm_per_c;
  }
  const std::size_t k_quad = k_lin + 1;
  if (n < k_quad + 1) {
    res.k2_ppm_per_c2.not_identified =
        format("needs at least {} plateaus at distinct temperatures, have {}: the model form is linear (k2 = 0)", k_quad + 1, n);
  } else if (auto quad = regress(ps, options.t0_c, true, with_rate); !quad.ok || quad.theta[0] == 0.0) {
    res.k2_ppm_per_c2.not_identified = "the plateaus' temperatures are too few or too close for a quadratic: the model form is linear (k2 = 0)";
  } else {
    res.model_sf0 = quad.theta[0];
    fill(res.k1_ppm_per_c, quad, 1, kPpm);
    fill(res.k2_ppm_per_c2, quad, 2, kPpm);
  }
  double ss = 0.0;
  for (const auto& p : ps) {
    const double d = kPpm * (p.scale_factor / model_scale_factor(res, p.coil_c) - 1.0);
    ss += d * d;
  }
  res.model_rms_ppm = std::sqrt(ss / static_cast<double>(n));
  return res;
}

}  // namespace fogbench::model::sf
