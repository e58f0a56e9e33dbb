// lags_at_edge: which fitted @auto lags are bounds of their scan rather than estimates.
#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "fogbench/model/model.hpp"

namespace fogbench::model {

std::vector<std::string> lags_at_edge(const Model& m) {
  const int margin = std::max(1, m.max_lag_s / 20);
  // Terms grouped by lag: the paper method's shared lag is one parameter, named once.
  std::map<int, std::vector<std::string>> at_edge;
  for (const auto& ft : m.terms)
    if (ft.term.lag.automatic && m.max_lag_s > 0 && ft.term.lag.seconds >= m.max_lag_s - margin)
      at_edge[ft.term.lag.seconds].push_back(ft.name());
  std::vector<std::string> out;
  for (const auto& [lag, names] : at_edge) {
    std::string who;
    for (std::size_t i = 0; i < names.size(); ++i) who += (i ? ", " : "") + names[i];
    const bool shared = names.size() > 1;
    out.push_back(std::string(shared ? "the shared lag of " : "the lag of ") + who + " is " + std::to_string(lag) +
                  " s, at the edge of its scan (0.." + std::to_string(m.max_lag_s) +
                  " s): a bound, not an estimate; the delayed term" + (shared ? "s stand" : " stands") +
                  " in for a slower effect the model lacks, or the range is too short");
  }
  return out;
}

}  // namespace fogbench::model
