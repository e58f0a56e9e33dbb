// Internal to model/: the small helpers every part of model/src shares (one copy each).
#pragma once

#include <cmath>
#include <cstddef>
#include <expected>
#include <string>
#include <vector>

#include "fogbench/model/model.hpp"

namespace fogbench::model::detail {

// A failure as the value the model's functions return.
inline std::unexpected<FitError> fail(FitError::Code c, std::string msg) { return std::unexpected(FitError{c, std::move(msg)}); }

// The weight of each sample in a regression: 1, or 0 for a quality-flagged sample or an
// output not taken (NaN). flagged, when given, receives the number of zeros.
inline std::vector<double> good_weights(const RunData& run, std::size_t* flagged = nullptr) {
  std::vector<double> w(run.size(), 1.0);
  std::size_t nf = 0;
  for (std::size_t t = 0; t < run.size(); ++t) {
    if (run.flagged(t) || !std::isfinite(run.gyro_dph[t])) {
      w[t] = 0.0;
      ++nf;
    }
  }
  if (flagged) *flagged = nf;
  return w;
}

}  // namespace fogbench::model::detail
