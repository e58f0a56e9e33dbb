// A gyro that streams: its frames at the frame rate, with the noise generated at that rate, so
// that the mean of ANY N consecutive frames (N frames per simulated second) carries the 1 s
// noise the physics specifies (sim::GyroTruth: AR(p) with k1..kp and sigma_a at 1 s), whatever
// the phase of the reader's averaging window. Also the gyro's power (frames only while powered,
// the sequence counter from 0 at each power-on, the status bit `warming_up` for its first second)
// and its optional warm-up transient. Pure: the
// caller steps it one simulated second at a time and sends the frames. docs/mock-bench.md.
#pragma once

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace fogbench::mock {

struct StreamParams {
  int frame_rate_hz = 100;        // N, frames per simulated second (>= 1)
  double counts_per_dph = 1e4;    // counts of one frame per deg/h
  std::vector<double> ar;         // k1..kp of the 1 s noise
  double sigma_a_dph = 0.146;     // innovation std of the 1 s noise, deg/h
  double outlier_rate_per_s = 0;  // spikes of one second, per second
  double outlier_dph = 0;         // their size, deg/h (either sign)
  double white_dph = 0;           // extra white noise per frame (electronics), deg/h, 1 sigma
  double warmup_dph = 0;          // warm-up transient A*exp(-t/tau) after each power-on, deg/h
  double warmup_tau_s = 600;      // its time constant tau, simulated s (> 0)
  // The start-up a real FOG announces: its frames carry the status bit `warming_up` for this
  // long after each power-on, simulated s (0: never). With the counter from 0, the gyro's own
  // evidence of a power-on (docs/can-frames.md "Power-on"); readers that ignore the bit see the
  // same frames as before.
  double startup_flag_s = 1.0;
};

// When the unit has no power: from off_from_s (inclusive) to on_at_s (exclusive), simulated s.
// Powered at t unless off_from_s <= t < on_at_s.
struct PowerWindow {
  double off_from_s = std::numeric_limits<double>::infinity();
  double on_at_s = 0;
  bool powered_at(double t_s) const noexcept { return !(off_from_s <= t_s && t_s < on_at_s); }
};

struct StreamFrame {
  std::int32_t counts = 0;
  std::uint8_t sequence = 0;
  bool powered = false;  // false: no frame in this slot (the gyro had no power)
  bool warming_up = false;  // within startup_flag_s of its power-on: the status bit `warming_up`
};

class GyroStream {
 public:
  // The gyro powers on at simulated time 0 (with the bench).
  explicit GyroStream(StreamParams params);

  // Fills `out` with the N frame slots of the simulated second [second_s, second_s + 1): frame j
  // at time second_s + j/N carries the deterministic drift `drift_dph` (the physics' value for
  // the second, any gyro_spike included) plus the warm-up since the last power-on plus the noise.
  //
  // The noise is a seasonal AR at the frame rate: y_j = k1 y_{j-N} + ... + kp y_{j-pN} + e_j,
  // e_j ~ N(0, sigma_a^2 N). The mean Y of N consecutive frames then obeys
  // Y_k = k1 Y_{k-1} + ... + kp Y_{k-p} + E_k with E_k the mean of N independent e_j, of
  // variance sigma_a^2: exactly the 1 s AR(p) process, for every phase of the window. Outliers
  // start at any frame (probability rate/N each) and last N frames. The counts are quantised
  // with the remainder carried from frame to frame across seconds, so N consecutive frames sum
  // to their values to within one count.
  void second(std::int64_t second_s, double drift_dph, const PowerWindow& power, std::mt19937_64& rng,
              std::vector<StreamFrame>& out);

  bool powered() const noexcept { return powered_; }
  // Simulated time of the last power-on; frames of that time on belong to it.
  double powered_on_at_s() const noexcept { return on_since_s_; }
  // The mean output (deg/h, before quantisation) of the powered frames of the last second; NaN
  // when none was powered.
  double last_mean_dph() const noexcept { return last_mean_dph_; }

 private:
  void power_on(double t_s);

  StreamParams p_;
  std::vector<double> history_;  // y of the last p*N frames, a ring
  std::size_t at_ = 0;           // ring index of the next frame
  double carry_counts_ = 0;      // quantisation remainder
  int spike_left_ = 0;           // frames of the current outlier still to come
  double spike_dph_ = 0;
  std::uint8_t sequence_ = 0;
  bool powered_ = true;
  double on_since_s_ = 0;
  double last_mean_dph_ = 0;
};

}  // namespace fogbench::mock
