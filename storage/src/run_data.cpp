// Gap bridging, the stored phase and the ISO time (run_data.hpp).
#include "fogbench/storage/run_data.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "fogbench/profiles/profile.hpp"

namespace fogbench::storage {

void bridge_missing(model::RunData& d) {
  if (d.flags.empty()) d.flags.assign(d.size(), 0);
  for (auto* col : {&d.gyro_dph, &d.t1_c, &d.t2_c, &d.setpoint_c, &d.chamber_c}) {
    auto& v = *col;
    if (v.empty()) continue;
    auto first = std::find_if(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
    double last = first == v.end() ? 0.0 : *first;
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (std::isfinite(v[i])) {
        last = v[i];
      } else {
        v[i] = last;
        d.flags[i] |= model::flag::missing;
      }
    }
  }
}

model::Phase model_phase(profiles::Phase p) {
  switch (p) {
    case profiles::Phase::settle: return model::Phase::settle;
    case profiles::Phase::hold: return model::Phase::hold;
    case profiles::Phase::heating: return model::Phase::heating;
    case profiles::Phase::cooling: return model::Phase::cooling;
  }
  return model::Phase::unknown;
}

std::string iso8601_utc(std::chrono::system_clock::time_point tp, bool milliseconds) {
  using namespace std::chrono;
  const auto ms = duration_cast<std::chrono::milliseconds>(tp.time_since_epoch()).count();
  auto secs = static_cast<std::time_t>(ms / 1000);
  auto milli = static_cast<int>(ms % 1000);
  if (milli < 0) {  // before 1970: floor, not truncate
    milli += 1000;
    --secs;
  }
  std::tm t{};
  gmtime_r(&secs, &t);
  char buf[80];  // ample for any int fields, which keeps -Wformat-truncation quiet
  if (milliseconds)
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", t.tm_year + 1900, t.tm_mon + 1, t.tm_mday,
                  t.tm_hour, t.tm_min, t.tm_sec, milli);
  else
    std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02dZ", t.tm_year + 1900, t.tm_mon + 1, t.tm_mday,
                  t.tm_hour, t.tm_min, t.tm_sec);
  return buf;
}

}  // namespace fogbench::storage
