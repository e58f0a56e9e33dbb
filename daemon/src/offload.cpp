// The order of the analysis worker's jobs; see offload.hpp.
#include "fogbench/daemon/offload.hpp"

#include <utility>

namespace fogbench::daemon {

void JobQueue::push(Offload::Job job, JobOrigin origin) {
  if (!origin.address.empty()) ++by_address_[origin.address];
  classes_[static_cast<int>(origin.job_class)].push_back({std::move(job), std::move(origin.address)});
}

bool JobQueue::empty() const {
  for (const auto& c : classes_)
    if (!c.empty()) return false;
  return true;
}

std::optional<JobQueue::Next> JobQueue::pop() {
  for (auto& c : classes_) {
    if (c.empty()) continue;
    Next next{std::move(c.front().job), std::move(c.front().address)};
    c.pop_front();
    return next;
  }
  return std::nullopt;
}

void JobQueue::done(const std::string& address) {
  if (address.empty()) return;
  auto it = by_address_.find(address);
  if (it == by_address_.end()) return;
  if (--it->second == 0) by_address_.erase(it);
}

std::size_t JobQueue::pending_from(std::string_view address) const {
  auto it = by_address_.find(address);
  return it == by_address_.end() ? 0 : it->second;
}

}  // namespace fogbench::daemon
