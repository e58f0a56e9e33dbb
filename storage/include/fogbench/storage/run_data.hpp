// What every reader of a stored run shares, once: a run's values not read bridged for analysis,
// the phase a sample is stored with for a profile's phase, and the ISO 8601 UTC time the store,
// the daemon and fogctl write. (storage is the lowest library the daemon and fogctl both link
// that knows runs; model stays pure, profiles knows nothing of ours.)
#pragma once

#include <chrono>
#include <string>

#include <cstdint>

#include "fogbench/model/run.hpp"

namespace fogbench::profiles {
enum class Phase : std::uint8_t;  // profiles/profile.hpp: settle, hold, heating, cooling
}

namespace fogbench::storage {

// A value not read is NaN (NULL in the store, an empty reading on the wire). Each is replaced by
// the last value read before it (the first value read, at the start; 0 if none was), and its
// sample gets the `missing` flag, so no fit trusts it while the lag scans and smoothers, which
// run over every sample, see no NaN. The CSV form needs it too: it has no empty cells.
void bridge_missing(model::RunData& run);

// The phase a sample is stored with, for the profile's phase of its second (the same names).
model::Phase model_phase(profiles::Phase p);

// "2026-11-21T21:55:01Z", or with milliseconds "2026-11-21T21:55:01.924Z" (floored, also before 1970).
std::string iso8601_utc(std::chrono::system_clock::time_point t, bool milliseconds = false);

}  // namespace fogbench::storage
