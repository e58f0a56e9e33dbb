// The fibre coil as a temperature field: radial layers of winding between the hub and the outer
// wall, conducting heat to each other (finite volumes of the cylindrical heat equation), the
// outer layer heated by the air through a film, the hub (the spool) heated by the air through
// the mount and touching the inner layer. The gyro's thermal drift is read off the whole field:
// the Shupe term (layer rates weighted by the winding), the elasto-optic stress of the radial
// gradient, and an absolute-temperature term. docs/simulation.md derives each and says where
// the defaults come from.
#pragma once

#include <expected>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fogbench::sim {

// lumped: the two-node coil (outer wall follows the air, centre follows the wall) with the drift
// written in the term language on its two temperatures, so the paper's model is the exact truth.
// distributed: the layered field below, with the drift computed from the field.
enum class CoilModel { lumped, distributed };
std::string_view to_string(CoilModel m);
std::expected<CoilModel, std::string> parse_coil_model(std::string_view s);

// Where a thermistor sits: on the hub (spool), the inner layer of the winding, its middle layer,
// or its outer layer (the coil's outer wall).
enum class Placement { hub, inner, middle, outer };
std::string_view to_string(Placement p);
std::expected<Placement, std::string> parse_placement(std::string_view s);

struct DistributedCoil {
  int layers = 8;                  // radial finite volumes across the winding (>= 6)
  double inner_radius_mm = 35.0;   // winding's inner radius (on the hub), mm
  double outer_radius_mm = 50.0;   // winding's outer radius, mm
  double winding_tau_s = 200.0;    // radial diffusion time across the winding, thickness^2 / diffusivity, s
  double film_tau_s = 300.0;       // air to the outer layer: winding heat capacity / film conductance, s
  double hub_capacity = 0.6;       // hub (spool) heat capacity / winding heat capacity
  double mount_tau_s = 600.0;      // air to the hub through the mount: hub capacity / mount conductance, s
  double contact_tau_s = 120.0;    // hub to inner layer: winding heat capacity / contact conductance, s
  Placement t1_at = Placement::inner;  // the "coil centre" thermistor (T1)
  Placement t2_at = Placement::outer;  // the "outer wall" thermistor (T2)
  // The drift read off the field (deg/h per unit):
  double shupe_dph_per_c_per_min = -5.5;  // times the winding-weighted mean layer rate, degC/min
  double stress_dph_per_c = -0.6;         // times the radial gradient inner minus outer layer, degC
  double absolute_dph_per_c = 0.01;       // times the winding's mean temperature minus tref, degC

  // The first violated constraint, naming the field.
  std::expected<void, std::string> validate() const;
};

// The field's state, stepped by the world once per second.
class CoilField {
 public:
  static std::expected<CoilField, std::string> create(const DistributedCoil& p, double start_c);

  // Advances the field by dt_s with the air held at air_c (explicit finite volumes, sub-stepped
  // well inside the stability limit).
  void step(double air_c, double dt_s = 1.0);

  double at(Placement p) const;                                 // true temperature there, degC
  double hub_c() const { return hub_c_; }
  std::span<const double> layers_c() const { return t_; }      // inner to outer, degC
  std::span<const double> shupe_weights() const { return w_; }  // per layer, summing to 1
  int substeps() const { return substeps_; }                    // per second

  // The drift of the last step, deg/h, without mu0: the Shupe term on the layers' mean rates
  // over the step, the stress term on the inner-minus-outer gradient at its end, the absolute
  // term on the winding's capacity-weighted mean temperature at its end.
  double drift_dph(double tref_c) const;
  // Its three parts (deg/h), for tests and docs.
  double shupe_dph() const;
  double stress_dph() const;
  double absolute_dph(double tref_c) const;
  // The winding-weighted mean rate over the last step, degC/min.
  double weighted_rate_c_per_min() const;

 private:
  CoilField() = default;
  DistributedCoil p_;
  std::vector<double> t_, prev_;      // layer temperatures now and one step ago, degC
  std::vector<double> up_, down_;     // per layer: coupling to the next outer / inner layer, 1/s
  std::vector<double> cap_;           // per layer: share of the winding's heat capacity
  std::vector<double> w_;             // Shupe weights
  std::vector<double> flow_;          // per layer, dT/dt of the current sub-step (kept to avoid allocating), degC/s
  double film_ = 0.0;                 // outer layer to air, 1/s
  double contact_layer_ = 0.0;        // inner layer to hub, 1/s
  double contact_hub_ = 0.0, mount_ = 0.0;  // hub to inner layer, hub to air, 1/s
  double hub_c_ = 20.0;
  double last_dt_s_ = 1.0;
  int substeps_ = 1;
};

}  // namespace fogbench::sim
