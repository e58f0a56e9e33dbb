// The coil's temperature field and the drift read off it; see coil.hpp and docs/simulation.md.
#include "fogbench/sim/coil.hpp"

#include <algorithm>
#include <cmath>

namespace fogbench::sim {

std::string_view to_string(CoilModel m) { return m == CoilModel::lumped ? "lumped" : "distributed"; }

std::expected<CoilModel, std::string> parse_coil_model(std::string_view s) {
  if (s == "lumped") return CoilModel::lumped;
  if (s == "distributed") return CoilModel::distributed;
  return std::unexpected("unknown coil model '" + std::string(s) + "' (known: distributed, lumped)");
}

std::string_view to_string(Placement p) {
  switch (p) {
    case Placement::hub: return "hub";
    case Placement::inner: return "inner";
    case Placement::middle: return "middle";
    case Placement::outer: return "outer";
  }
  return "?";
}

std::expected<Placement, std::string> parse_placement(std::string_view s) {
  for (auto p : {Placement::hub, Placement::inner, Placement::middle, Placement::outer})
    if (s == to_string(p)) return p;
  return std::unexpected("unknown thermistor placement '" + std::string(s) + "' (known: hub, inner, middle, outer)");
}

std::expected<void, std::string> DistributedCoil::validate() const {
  auto finite = [](double x) { return std::isfinite(x); };
  if (layers < 6 || layers > 64) return std::unexpected(std::string("layers: expected 6..64"));
  if (!(inner_radius_mm > 0) || !finite(inner_radius_mm)) return std::unexpected(std::string("inner_radius_mm: expected a positive number"));
  if (!(outer_radius_mm > inner_radius_mm) || !finite(outer_radius_mm))
    return std::unexpected(std::string("outer_radius_mm: expected a number above inner_radius_mm"));
  for (auto [name, v] : {std::pair{"winding_tau_s", winding_tau_s}, std::pair{"film_tau_s", film_tau_s}, std::pair{"hub_capacity", hub_capacity},
                         std::pair{"mount_tau_s", mount_tau_s}, std::pair{"contact_tau_s", contact_tau_s}}) {
    if (!(v > 0) || !finite(v)) return std::unexpected(std::string(name) + ": expected a positive number");
  }
  for (auto [name, v] : {std::pair{"shupe_dph_per_c_per_min", shupe_dph_per_c_per_min}, std::pair{"stress_dph_per_c", stress_dph_per_c},
                         std::pair{"absolute_dph_per_c", absolute_dph_per_c}}) {
    if (!finite(v)) return std::unexpected(std::string(name) + ": expected a finite number");
  }
  return {};
}

std::expected<CoilField, std::string> CoilField::create(const DistributedCoil& p, double start_c) {
  if (auto ok = p.validate(); !ok) return std::unexpected(ok.error());
  CoilField f;
  f.p_ = p;
  const auto n = static_cast<std::size_t>(p.layers);
  const double h = (p.outer_radius_mm - p.inner_radius_mm) / static_cast<double>(n);  // layer thickness, mm
  auto r = [&](double i) { return p.inner_radius_mm + i * h; };                        // radius at layer index i (i + 0.5: centre)
  // Finite volumes of the cylindrical heat equation, rho c dT/dt = k (1/r) d/dr (r dT/dr): a
  // layer's heat capacity grows with its radius (r h per unit length and angle), the conductance
  // to its neighbour with the radius of the face between them (r_face / h). With the diffusivity
  // alpha = thickness^2 / winding_tau_s, layer i couples to layer i+1 at
  // alpha r_face / (r_i h^2) = (n^2 / winding_tau_s) * r_face / r_i, in 1/s.
  double total = 0.0;
  for (std::size_t i = 0; i < n; ++i) total += r(static_cast<double>(i) + 0.5);
  const double k = static_cast<double>(n * n) / p.winding_tau_s;
  f.cap_.resize(n);
  f.up_.assign(n, 0.0);
  f.down_.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double ri = r(static_cast<double>(i) + 0.5);
    f.cap_[i] = ri / total;
    if (i + 1 < n) f.up_[i] = k * r(static_cast<double>(i) + 1.0) / ri;
    if (i > 0) f.down_[i] = k * r(static_cast<double>(i)) / ri;
  }
  // Boundaries given as whole-winding time constants (capacity / conductance): the share of the
  // conductance a layer sees is divided by that layer's share of the capacity.
  f.film_ = 1.0 / (p.film_tau_s * f.cap_[n - 1]);
  f.contact_layer_ = 1.0 / (p.contact_tau_s * f.cap_[0]);
  f.contact_hub_ = 1.0 / (p.contact_tau_s * p.hub_capacity);
  f.mount_ = 1.0 / p.mount_tau_s;
  // Shupe weights. The Shupe phase weights each element of fibre by its distance from the
  // fibre's midpoint; a quadrupolar winding starts at the midpoint on the inner layer and winds
  // both halves outwards together, so a layer's fibre lies at the length wound inside it plus
  // half its own (each layer's length grows with its radius). Normalised to sum 1, the Shupe
  // term reads a weighted mean of the layers' rates, leaning to the outer layers.
  f.w_.resize(n);
  double wound = 0.0, wsum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double len = r(static_cast<double>(i) + 0.5);
    f.w_[i] = wound + 0.5 * len;
    wound += len;
    wsum += f.w_[i];
  }
  for (auto& w : f.w_) w /= wsum;
  // Explicit Euler is stable while dt times a node's total coupling stays under 1 (Gershgorin
  // bound of the diagonal-dominant matrix at 2, halved for the hub's and film's extra terms);
  // 0.25 keeps the step's error on the slow modes that matter well under the thermistors' noise.
  double fastest = f.contact_hub_ + f.mount_;
  for (std::size_t i = 0; i < n; ++i)
    fastest = std::max(fastest, f.up_[i] + f.down_[i] + (i + 1 == n ? f.film_ : 0.0) + (i == 0 ? f.contact_layer_ : 0.0));
  f.substeps_ = std::max(1, static_cast<int>(std::ceil(fastest / 0.25)));
  f.flow_.assign(n, 0.0);
  f.t_.assign(n, start_c);
  f.prev_ = f.t_;
  f.hub_c_ = start_c;
  return f;
}

void CoilField::step(double air_c, double dt_s) {
  prev_ = t_;
  last_dt_s_ = dt_s;
  const std::size_t n = t_.size();
  const double h = dt_s / substeps_;
  auto& d = flow_;
  for (int s = 0; s < substeps_; ++s) {
    for (std::size_t i = 0; i < n; ++i) {
      double flow = 0.0;
      if (i + 1 < n) flow += up_[i] * (t_[i + 1] - t_[i]);
      if (i > 0) flow += down_[i] * (t_[i - 1] - t_[i]);
      d[i] = flow;
    }
    d[n - 1] += film_ * (air_c - t_[n - 1]);
    d[0] += contact_layer_ * (hub_c_ - t_[0]);
    const double dhub = contact_hub_ * (t_[0] - hub_c_) + mount_ * (air_c - hub_c_);
    for (std::size_t i = 0; i < n; ++i) t_[i] += h * d[i];
    hub_c_ += h * dhub;
  }
}

double CoilField::at(Placement p) const {
  switch (p) {
    case Placement::hub: return hub_c_;
    case Placement::inner: return t_.front();
    case Placement::middle: {
      // The radial middle: one layer's centre for an odd count, two layers' mean for an even one.
      const std::size_t n = t_.size();
      return n % 2 ? t_[n / 2] : 0.5 * (t_[n / 2 - 1] + t_[n / 2]);
    }
    case Placement::outer: return t_.back();
  }
  return t_.front();
}

double CoilField::weighted_rate_c_per_min() const {
  double r = 0.0;
  for (std::size_t i = 0; i < t_.size(); ++i) r += w_[i] * (t_[i] - prev_[i]);
  return r * 60.0 / last_dt_s_;
}

double CoilField::shupe_dph() const { return p_.shupe_dph_per_c_per_min * weighted_rate_c_per_min(); }

double CoilField::stress_dph() const { return p_.stress_dph_per_c * (t_.front() - t_.back()); }

double CoilField::absolute_dph(double tref_c) const {
  double mean = 0.0;
  for (std::size_t i = 0; i < t_.size(); ++i) mean += cap_[i] * t_[i];
  return p_.absolute_dph_per_c * (mean - tref_c);
}

double CoilField::drift_dph(double tref_c) const { return shupe_dph() + stress_dph() + absolute_dph(tref_c); }

}  // namespace fogbench::sim
