// What the live plan tests share: polling plan.status until the plan is in one of `states`.
#pragma once

#include <set>
#include <string>

#include "../daemon/live_bench.hpp"

namespace fogbench::daemon::test::live {

// Polls plan.status every 200 ms until the plan is in one of `states`; the last reply (the
// caller checks the state, so a timeout fails there with the reply shown).
inline json wait_plan(LineClient& c, std::int64_t plan_id, const std::set<std::string>& states,
                      std::chrono::seconds timeout) {
  const auto deadline = SteadyClock::now() + timeout;
  json r;
  while (SteadyClock::now() < deadline) {
    r = c.call({{"cmd", "plan.status"}, {"plan_id", plan_id}});
    if (r.is_object() && r.contains("result") && states.contains(r["result"]["state"].get<std::string>())) return r;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return r;
}

}  // namespace fogbench::daemon::test::live
