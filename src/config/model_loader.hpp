// Loads a skeleton model from its JSON format (see docs/models.md).
// Lengths are converted to metres here, once.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "load.hpp"
#include "solver/model.hpp"

namespace fabrik {

// What a model file may hold: a human body with hands, feet and a segmented
// spine fits well within these (OpenSim's largest full-body models have about
// 150 bodies and lab marker sets up to about 300 markers), while a larger file
// would make setup and every frame cost what no real body needs. Each limit
// is named in the error with its pointer and a fix (docs/models.md).
class JsonReader;
struct ModelLimits {
  static constexpr int kSegments = 512;
  static constexpr int kPointsPerSegment = 256;  // points and markers of one segment
  static constexpr int kMarkers = 1024;          // in the whole model
  static constexpr int kDepth = 64;              // segments from the root to a leaf, both counted
  static constexpr int kCoordinates = 1024;

  // Each throws ConfigError at `where` when its limit is passed (models and
  // templates say it the same way).
  static void check_segments(const JsonReader& segments_array);
  static void check_points(const JsonReader& where, std::size_t points_and_markers);
  static void check_markers(const JsonReader& where, std::size_t markers_so_far);
  static void check_depth(const JsonReader& parent, const std::string& segment, int depth);
};

// `file` is only used in messages. Throws ConfigError.
Model load_model(const nlohmann::json& doc, const std::string& file);
// A model object anywhere in a JSON document (e.g. inline in a daemon config).
class JsonReader;
Model load_model(const JsonReader& model);

// Metres per unit for "m" and "mm"; throws ConfigError via `reader` otherwise.
class JsonReader;
double metres_per_unit(const JsonReader& units);

}  // namespace fabrik
