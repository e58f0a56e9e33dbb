// The report's plot helpers alone: robust y-limits, key numbers of the printed legend, the
// drift-vs-T1 loop split, and the plot specification (ids, labels, outlier counts).
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <random>

#include "report_plots.hpp"

using namespace fogbench::cli::plots;

namespace {
std::vector<double> gaussian(std::size_t n, std::uint64_t seed, double sigma = 1.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<double> x(n);
  for (double& v : x) v = g(rng);
  return x;
}
}  // namespace

TEST_CASE("robust_limits: one 1e6 outlier does not set the range, it is counted above") {
  // 10000 N(0,1) samples: the 1% and 99% quantiles are -+2.33, w = 4.65, the fence +-4.65
  // (the largest of 10000 normals is about 3.9, so none of them is past it); the range is the
  // inliers' min..max widened by 5%: within +-(4.65 * 1.1) and at least +-3.
  std::vector<double> x = gaussian(10000, 1);
  x[5000] = 1e6;
  const std::vector<std::span<const double>> ys{x};
  const YLimits l = robust_limits(ys);
  CHECK(l.hi < 5.2);
  CHECK(l.hi > 3.0);
  CHECK(l.lo > -5.2);
  CHECK(l.lo < -3.0);
  CHECK(l.above == 1);
  CHECK(l.below == 0);
  // The same with the outlier below, and a NaN that is simply ignored.
  x[5000] = -1e6;
  x[10] = std::numeric_limits<double>::quiet_NaN();
  const YLimits m = robust_limits(ys);
  CHECK(m.lo > -5.2);
  CHECK(m.below == 1);
  CHECK(m.above == 0);
}

TEST_CASE("robust_limits: a ramp, a short series and limit lines keep every value in range") {
  // A ramp 0..100: quantiles 1 and 99, fence 49 beyond: all inside, range 0..100 +- 5.
  std::vector<double> ramp;
  for (int i = 0; i <= 1000; ++i) ramp.push_back(0.1 * i);
  const YLimits l = robust_limits({std::span<const double>(ramp)});
  CHECK(l.lo == Approx(-5.0));
  CHECK(l.hi == Approx(105.0));
  CHECK(l.outside() == 0);
  // Five samples, one far out: nearest-rank quantiles inward (ranks 1 and 3 of 0..4) are 2 and
  // 4, the fence 1..5: the 1000 is out, the 1 stays in.
  const std::vector<double> few{1, 2, 3, 4, 1000};
  const YLimits f = robust_limits({std::span<const double>(few)});
  CHECK(f.above == 1);
  CHECK(f.hi < 10.0);
  CHECK(f.lo < 1.0);
  // A limit line (always shown) widens the range beyond the data: +-3 around data in +-1.
  const std::vector<double> small = gaussian(2000, 2, 0.3), lines{-3.0, 3.0};
  const YLimits g = robust_limits({std::span<const double>(small)}, lines);
  CHECK(g.lo <= -3.0);
  CHECK(g.hi >= 3.0);
  // A constant series with one outlier: the outlier out, the constant in view (not a 0-wide range).
  std::vector<double> flat(100, 2.0);
  flat[50] = 50.0;
  const YLimits c = robust_limits({std::span<const double>(flat)});
  CHECK(c.above == 1);
  CHECK(c.lo < 2.0);
  CHECK(c.hi > 2.0);
  CHECK(c.hi < 3.0);
  // Nothing finite: a default range.
  const std::vector<double> none{std::nan(""), std::nan("")};
  const YLimits z = robust_limits({std::span<const double>(none)});
  CHECK(z.lo < z.hi);
}

TEST_CASE("keys: mean, std (n - 1), min, max, last over the finite values, and their text") {
  // 1, 2, 3, NaN, 6: mean 3, deviations -2 -1 0 3, squares 14, / 3 -> std sqrt(14/3) = 2.160.
  const std::vector<double> y{1, 2, 3, std::nan(""), 6};
  const Keys k = keys(y);
  CHECK(k.n == 4);
  CHECK(k.mean == Approx(3.0));
  CHECK(k.std == Approx(std::sqrt(14.0 / 3.0)));
  CHECK(k.min == 1.0);
  CHECK(k.max == 6.0);
  CHECK(k.last == 6.0);
  CHECK(keys_text(k, "deg/h") == "mean 3, std 2.16, min 1, max 6, last 6 deg/h");
  CHECK(keys_text(keys(std::vector<double>{}), "deg/h") == "no finite sample");
}

TEST_CASE("split_by_direction: a heat-cool cycle with hysteresis draws two branches apart (a loop)") {
  // T1 rises 0 -> 20 degC over 200 s at 0.1 degC/s, holds 100 s, falls back over 200 s. The
  // output is T1 + 1 on heating and T1 - 1 on cooling: at equal T1 the branches differ by 2.
  std::vector<double> t1, y;
  for (int t = 0; t < 200; ++t) t1.push_back(0.1 * t), y.push_back(0.1 * t + 1.0);
  for (int t = 0; t < 100; ++t) t1.push_back(20.0), y.push_back(20.0);
  for (int t = 0; t < 200; ++t) t1.push_back(20.0 - 0.1 * t), y.push_back(20.0 - 0.1 * t - 1.0);
  const Loop l = split_by_direction(t1, y, 30, 0.05);
  REQUIRE(l.heat_x.size() == t1.size());
  // Mid-ramp samples go to their branch, the middle of the hold to holding (the window of
  // +-30 s sees no rise there).
  CHECK(l.heat_x[100] == Approx(10.0));
  CHECK(std::isnan(l.cool_x[100]));
  CHECK(l.cool_x[400] == Approx(10.0));
  CHECK(std::isnan(l.heat_x[400]));
  CHECK(l.hold_x[250] == Approx(20.0));
  // Every sample is in exactly one part.
  for (std::size_t t = 0; t < t1.size(); ++t)
    CHECK(std::isfinite(l.heat_x[t]) + std::isfinite(l.cool_x[t]) + std::isfinite(l.hold_x[t]) == 1);
  // The loop: at T1 = 10 degC, heating minus cooling is 2.
  CHECK(l.heat_y[100] - l.cool_y[400] == Approx(2.0));
}

TEST_CASE("render: the spec carries robust limits, the title counts outliers, the printed legend the keys") {
  Plot p;
  p.id = "r0";
  p.title = "Residual";
  p.xlabel = "time, s";
  p.ylabel = "residual, deg/h";
  Series s;
  s.name = "residual";
  s.y = gaussian(5000, 3, 0.15);
  s.y[100] = 1e6;
  for (std::size_t i = 0; i < s.y.size(); ++i) p.x.push_back(static_cast<double>(i));
  s.stroke = "#123456";
  s.keys = keys_text(keys(s.y), "deg/h");
  p.series.push_back(s);
  nlohmann::json specs = nlohmann::json::array();
  const std::string html = render(p, specs, 1000);
  REQUIRE(specs.size() == 1);
  const auto& j = specs[0];
  CHECK(j["id"] == "r0");
  CHECK(j["ylim"][1].get<double>() < 1.0);  // 0.15 deg/h noise: not 1e6
  // The title counts what robust_limits leaves out: the spike, and any of the 5000 normals
  // past the fence (+-4.65 sigma, 3e-6 each: seldom one).
  const YLimits l = robust_limits({std::span<const double>(s.y)});
  CHECK(l.above >= 1);
  CHECK(l.outside() <= 3);
  INFO(j["title"].get<std::string>());
  CHECK(j["title"].get<std::string>().find("[" + std::to_string(l.outside()) + " sample") != std::string::npos);
  CHECK(j["title"].get<std::string>().find("beyond the y-range, marked at the edge]") != std::string::npos);
  CHECK(j["x"].size() <= 1000u);
  CHECK(j["series"][0]["y"].size() == j["x"].size());
  // The spike survives decimation (min-max buckets) so the page can mark it at the edge.
  bool spike = false;
  for (const auto& v : j["series"][0]["y"]) spike |= v.is_number() && v.get<double>() > 1e5;
  CHECK(spike);
  CHECK(html.find("id=\"r0\"") != std::string::npos);
  CHECK(html.find("class=\"keys\"") != std::string::npos);
  CHECK(html.find("<b>residual</b>: mean") != std::string::npos);
  // The print stylesheet shows the static legend and hides uPlot's live one.
  const std::string css = kPlotStyle;
  CHECK(css.find("@media print") != std::string::npos);
  CHECK(css.find(".keys{display:block") != std::string::npos);
}
