// The regression kernel (model/src/lsq.hpp, internal to model/) scored against NIST's
// Statistical Reference Datasets for linear least squares: the certified estimates, their
// standard deviations, the residual standard deviation and R^2, read from NIST's own files
// (tests/model/data/strd/, with their source). Norris is NIST's "lower difficulty" straight
// line; Longley is the classic hard one (six regressors so nearly collinear, plus a constant,
// that normal equations in double keep only a handful of digits).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "../../model/src/lsq.hpp"

using namespace fogbench::model::detail;

namespace {

struct StrdProblem {
  std::vector<double> estimate, sd;  // B0..Bk as certified
  double residual_sd = 0.0, r2 = 0.0;
  double residual_ss = 0.0;          // the certified ANOVA table's residual sum of squares
  std::vector<std::vector<double>> rows;  // y, x1..xk per observation
};

// Reads a NIST StRD linear-regression file: the "Bj estimate sd" lines, "Standard Deviation"
// and "R-Squared" of the certified statistics, the ANOVA table's "Residual" line, and the data
// rows after the line starting with "Data:" whose columns are named (y ...).
StrdProblem read_strd(const std::string& name) {
  const std::string path = std::string(FOGBENCH_SOURCE_DIR) + "/tests/model/data/strd/" + name;
  std::ifstream in(path);
  REQUIRE(in.good());
  StrdProblem p;
  std::string line;
  bool data = false;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string first;
    ls >> first;
    if (data) {
      std::vector<double> row{std::stod(first)};
      for (double v; ls >> v;) row.push_back(v);
      p.rows.push_back(row);
    } else if (first == "Data:" && line.find(" y ") != std::string::npos) {
      data = true;
    } else if (first.size() >= 2 && first[0] == 'B' && std::isdigit(static_cast<unsigned char>(first[1]))) {
      double e = 0.0, s = 0.0;
      if (ls >> e >> s) {
        p.estimate.push_back(e);
        p.sd.push_back(s);
      }
    } else if (first == "Standard" && line.find("Deviation") != std::string::npos) {
      std::string word;
      ls >> word;
      if (ls >> p.residual_sd) {}
    } else if (first == "R-Squared") {
      ls >> p.r2;
    } else if (first == "Residual") {
      double dof = 0.0, ss = 0.0;
      if (ls >> dof >> ss) p.residual_ss = ss;
    }
  }
  return p;
}

LeastSquaresResult fit_with_constant(const StrdProblem& p) {
  const std::size_t k = p.estimate.size();
  LeastSquares ls(k);
  std::vector<double> x(k);
  for (const auto& row : p.rows) {
    x[0] = 1.0;
    for (std::size_t j = 1; j < k; ++j) x[j] = row[j];
    ls.add(x, row[0]);
  }
  return ls.solve();
}

// Significant digits that agree (NIST's log relative error, capped at 15).
double lre(double got, double want) {
  if (got == want) return 15.0;
  return std::min(15.0, -std::log10(std::abs(got - want) / std::abs(want)));
}

void check_certified(const StrdProblem& p, const LeastSquaresResult& r, double digits) {
  REQUIRE(r.ok);
  REQUIRE(r.theta.size() == p.estimate.size());
  for (std::size_t j = 0; j < p.estimate.size(); ++j) {
    INFO("B" << j << " = " << r.theta[j] << ", certified " << p.estimate[j]);
    CHECK(lre(r.theta[j], p.estimate[j]) >= digits);
    INFO("sd(B" << j << ") = " << r.se[j] << ", certified " << p.sd[j]);
    CHECK(lre(r.se[j], p.sd[j]) >= digits);
  }
  INFO("residual sd " << r.sigma << ", certified " << p.residual_sd);
  CHECK(lre(r.sigma, p.residual_sd) >= digits);
  INFO("R^2 " << r.r2 << ", certified " << p.r2);
  CHECK(lre(r.r2, p.r2) >= digits);
  INFO("residual SS " << r.sse << ", certified " << p.residual_ss);
  CHECK(lre(r.sse, p.residual_ss) >= digits);
}

}  // namespace

TEST_CASE("kernel: NIST StRD Norris, every certified value to 12 significant digits", "[strd]") {
  const StrdProblem p = read_strd("Norris.dat");
  REQUIRE(p.rows.size() == 36);      // the header's "36 Observations"
  REQUIRE(p.estimate.size() == 2);   // B0, B1
  // Lower difficulty: the QR keeps 12.6 digits of B0 (the worst) and 14+ of the rest here.
  check_certified(p, fit_with_constant(p), 12.0);
}

TEST_CASE("kernel: NIST StRD Longley, every certified value to 10 significant digits", "[strd]") {
  const StrdProblem p = read_strd("Longley.dat");
  REQUIRE(p.rows.size() == 16);      // "16 Observations"
  REQUIRE(p.estimate.size() == 7);   // B0..B6
  // Longley's normal equations have a reciprocal condition near 3.5e-20 (the kernel's former
  // LDLT refused them at its 1e-13 floor; forced, it kept about 8 digits). The QR keeps 13 or
  // more of every certified value on x86-64; we ask for 10, a margin for another FPU or
  // compiler. NIST's own remarks grade 7 to 8 digits on Longley as adequate.
  check_certified(p, fit_with_constant(p), 10.0);
}

TEST_CASE("kernel: zero-weight rows are skipped, NaN and all, and a repeated column is singular", "[strd]") {
  const StrdProblem p = read_strd("Norris.dat");
  const LeastSquaresResult want = fit_with_constant(p);
  LeastSquares ls(2);
  for (const auto& row : p.rows) {
    ls.add(std::vector<double>{1.0, row[1]}, row[0]);
    // A row that would ruin every sum if it were read.
    ls.add(std::vector<double>{1.0, std::numeric_limits<double>::quiet_NaN()}, 1e300, 0.0);
  }
  const LeastSquaresResult got = ls.solve();
  REQUIRE(got.ok);
  CHECK(got.theta[1] == Approx(want.theta[1]).epsilon(1e-13));
  CHECK(got.dof == want.dof);

  LeastSquares twice(3);
  for (const auto& row : p.rows) twice.add(std::vector<double>{1.0, row[1], 2.0 * row[1]}, row[0]);
  CHECK_FALSE(twice.solve().ok);
  CHECK(twice.covariance(1.0).size() == 0);
}

TEST_CASE("kernel: more rows than one block fold to the same fit as the certified one", "[strd]") {
  // Norris's rows repeated 100 times (3,600 rows, 14 folds of the 256-row buffer): the same
  // estimates; the residual SS 100 times NIST's; dof 3600 - 2.
  const StrdProblem p = read_strd("Norris.dat");
  LeastSquares ls(2);
  for (int rep = 0; rep < 100; ++rep)
    for (const auto& row : p.rows) ls.add(std::vector<double>{1.0, row[1]}, row[0]);
  const LeastSquaresResult r = ls.solve();
  REQUIRE(r.ok);
  CHECK(lre(r.theta[0], p.estimate[0]) >= 11.0);
  CHECK(lre(r.theta[1], p.estimate[1]) >= 11.0);
  CHECK(lre(r.sse, 100.0 * p.residual_ss) >= 11.0);
  CHECK(r.dof == 3598.0);
  CHECK(lre(r.r2, p.r2) >= 11.0);
}
