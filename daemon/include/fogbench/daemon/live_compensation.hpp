// Online compensation: while a run acquires, each unit's compensated rate (gyro_dph minus the
// drift its model computes) second by second, through model::firmware's Compensator, the same
// recursions as the gyro's firmware (firmware/fogcomp.h). Stored with the samples
// (SampleRow::compensated_dph), returned by run.samples, published as `compensated_dph`.
//
// The rules (docs/daemon.md "Live compensation"):
// - The model: the serial's current (latest stored) model when the run starts, recorded in the
//   run's `note` event {"live_compensation": [...]} at its first second, and used again by
//   run.resume. No model, or one the firmware form refuses: null for the whole run (the note
//   says why).
// - Warm-up: the first model::firmware::warm_up_samples(program) samples after a (re)start are
//   null (the windows and delays still hold the opening fill, not the unit's history).
// - A gap: a second where an input the program reads is missing (NaN) or flagged out_of_range
//   is null and restarts the compensator at the next good second (re-warm). A second whose
//   gyro_dph alone is missing steps the compensator (its inputs are good) and is null.
// - run.resume: the state is rebuilt by stepping the stored seconds through the same rules, so
//   the live series is a function of the stored inputs alone, whatever the restarts.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fogbench/model/firmware.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"

namespace fogbench::storage {
class Store;  // store.hpp: load() reads it, in live_compensation.cpp
}

namespace fogbench::daemon {

class LiveCompensation {
 public:
  LiveCompensation() = default;
  // Each unit's model, compiled: the serial's current one when model_ids is empty (a run
  // starts), else the one model_ids names by unit (a run resumes; an empty entry: none then).
  static LiveCompensation load(storage::Store& store, const std::vector<std::string>& serials,
                               const std::vector<std::optional<std::int64_t>>& model_ids = {});
  // The models a run recorded in its live_compensation note, by unit (empty: none recorded).
  static std::vector<std::optional<std::int64_t>> recorded_models(const storage::RunDetail& run);

  // The note stored at the run's first second: per unit its model or why there is none.
  nlohmann::json describe() const;

  // Steps unit u's compensator with a stored row's inputs; returns the compensated rate
  // (deg/h), or NaN where there is none. Rows must come in time order, one per second.
  double step(std::size_t u, const storage::SampleRow& row);

  std::size_t size() const { return units_.size(); }

 private:
  struct Unit {
    std::string serial;
    std::optional<std::int64_t> model_id;
    int model_version = 0;
    std::string none;  // why there is no compensation ("" when there is)
    std::unique_ptr<model::firmware::Program> program;  // stable: the compensator points at it
    std::optional<model::firmware::Compensator> comp;
    model::firmware::InputsUsed used;
    int warm_up = 0;   // samples null after a (re)start
    long steps = 0;    // good samples since the last (re)start
  };
  std::vector<Unit> units_;
};

}  // namespace fogbench::daemon
