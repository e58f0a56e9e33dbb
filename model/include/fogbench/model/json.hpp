// A model is a value that saves to JSON and loads back exactly (doubles round-trip);
// verification results serialise for the CLI's --json and the daemon's protocol.
#pragma once

#include <expected>
#include <nlohmann/json.hpp>
#include <string>

#include "fogbench/model/model.hpp"

namespace fogbench::model {

inline constexpr int kModelFormatVersion = 1;

nlohmann::json to_json(const Model& m);
// Errors name the field: "terms[1].lag_s: expected an integer".
std::expected<Model, std::string> model_from_json(const nlohmann::json& j);
// Parses text (a model file's contents) and loads it.
std::expected<Model, std::string> model_from_text(std::string_view text);

// How a fit ended (not part of a model's file, whose format is unchanged): for a reply or a
// log line about a fit that failed or did not converge.
nlohmann::json to_json(const FitSummary& s);
nlohmann::json to_json(const Table1& t);
nlohmann::json to_json(const NoiseFloor& f);
nlohmann::json to_json(const Verification& v);

}  // namespace fogbench::model
