// Fitted models and verifications as stored (store_models.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace fogbench::storage {

struct NewModel {
  std::string serial;
  std::optional<std::int64_t> run_id;     // the run it was fitted on
  std::optional<std::int64_t> parent_id;  // the model it refines
  // Opaque to storage, but must be JSON; an object's `axis` ("x", "y" or "z": a three-axis
  // unit's model, model::to_json) is stored as the model's axis, none as a one-axis unit's.
  std::string model_json;
  std::string method;
  std::string terms;
};

struct ModelRef {
  std::int64_t id = 0;
  int version = 0;  // 1, 2, 3... per serial
};

struct ModelRecord {
  std::int64_t id = 0;
  std::string serial;
  int version = 0;
  std::optional<std::int64_t> run_id;
  std::optional<std::int64_t> parent_id;
  std::string created_at;
  std::string model_json;
  std::string method;
  std::string terms;
  // The axis of a three-axis unit it models: "x", "y" or "z" (its model_json's `axis`); empty
  // for a one-axis unit's model (stored as NULL: the x axis, the unit's only one).
  std::string axis;
};

struct NewVerification {
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::int64_t model_id = 0;
  std::string result_json;
  bool pass = false;
};

struct VerificationRecord {
  std::int64_t id = 0;
  std::int64_t run_id = 0;
  int unit_index = 0;
  std::int64_t model_id = 0;
  std::string created_at;
  std::string result_json;
  bool pass = false;
};

}  // namespace fogbench::storage
