// A downstream user of the installed fogbench::model: makes a run whose drift is known
// (beta1 = -2.5 deg/h per degC/min on the coil's rate, no noise beyond a tiny AR(1)), fits the
// joint model `d(T1)` at lag 0 and checks the coefficient comes back. Exit 0 on success.
#include <cmath>
#include <cstdio>
#include <numbers>

#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"

int main() {
  namespace m = fogbench::model;
  m::RunData run;
  run.name = "downstream";
  constexpr int n_s = 7200;
  constexpr double beta1_dph_per_c_per_min = -2.5;
  double noise = 0.0;
  unsigned state = 12345u;
  for (int t = 0; t < n_s; ++t) {
    // T1 follows a smooth 20 +/- 10 degC cycle of period 3600 s: its rate is 10 * 2pi/3600 *
    // cos(...) degC/s, so d(T1) reaches 10.5 degC/min.
    const double w = 2.0 * std::numbers::pi / 3600.0;
    const double t1_c = 20.0 + 10.0 * std::sin(w * t);
    const double rate_c_per_min = 60.0 * 10.0 * w * std::cos(w * t);
    state = state * 1103515245u + 12345u;
    const double u = (static_cast<double>(state >> 8) / 16777216.0) - 0.5;  // U(-0.5, 0.5)
    noise = 0.5 * noise + 0.02 * u;
    run.time_s.push_back(t);
    run.t1_c.push_back(t1_c);
    run.t2_c.push_back(t1_c - 0.1);
    run.gyro_dph.push_back(1.0 + beta1_dph_per_c_per_min * rate_c_per_min + noise);
  }
  auto terms = m::parse_terms("d(T1)");
  if (!terms) return std::puts("cannot parse the terms"), 1;
  m::FitOptions options;
  options.method = m::Method::joint;
  auto model = m::fit(run, *terms, options);
  if (!model) return std::printf("fit failed: %s\n", model.error().message.c_str()), 1;
  const double beta = model->terms.at(0).coef;
  std::printf("downstream: %s, beta1 = %.4f (expected %.4f)\n", model->terms_string().c_str(), beta,
              beta1_dph_per_c_per_min);
  // d(T1) is a 61 s least-squares slope: on a sine of period 3600 s it is within 0.5% of the
  // true rate, so beta is recovered to well under 2%.
  return std::abs(beta - beta1_dph_per_c_per_min) < 0.05 ? 0 : 1;
}
