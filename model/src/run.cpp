// Names of phases, as they appear in CSV files, JSON and reports.
#include "fogbench/model/run.hpp"

namespace fogbench::model {

std::string_view to_string(Phase p) {
  switch (p) {
    case Phase::settle: return "settle";
    case Phase::hold: return "hold";
    case Phase::heating: return "heating";
    case Phase::cooling: return "cooling";
    case Phase::unknown: break;
  }
  return "unknown";
}

std::optional<Phase> phase_from_string(std::string_view s) {
  for (Phase p : {Phase::unknown, Phase::settle, Phase::hold, Phase::heating, Phase::cooling})
    if (to_string(p) == s) return p;
  return std::nullopt;
}

}  // namespace fogbench::model
