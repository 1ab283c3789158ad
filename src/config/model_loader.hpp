// Loads a skeleton model from its JSON format (see README, "Model files").
// Lengths are converted to metres here, once.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "solver/model.hpp"

namespace fabrik {

// `file` is only used in messages. Throws ConfigError.
Model load_model(const nlohmann::json& doc, const std::string& file);
// A model object anywhere in a JSON document (e.g. inline in a daemon config).
class JsonReader;
Model load_model(const JsonReader& model);
Model load_model_file(const std::string& path);

// Metres per unit for "m" and "mm"; throws ConfigError via `reader` otherwise.
class JsonReader;
double metres_per_unit(const JsonReader& units);

}  // namespace fabrik
