/// @file
/// Loading what fabrik reads at setup: model files and daemon configs (fabrikd-config/1, as
/// `fabrik calibrate` writes them). Every function throws ConfigError naming the file, the
/// JSON pointer of the offending value, the problem and a fix; nothing is thrown later.
#pragma once

#include <string>

#include "../solver/model.hpp"
#include "../tracking/tracker.hpp"
#include "config_error.hpp"

namespace fabrik {

/// A model file (fabrikd-model/1 JSON: segments, points, joints, coordinates). Lengths in the
/// file are in its "units" (mm or m) and come back in metres.
Model load_model_file(const std::string& path);

/// The tracker part of a daemon config file: its model, marker targets, solver and tracking
/// settings. A relative model path resolves against the config's folder.
TrackerSetup load_tracker_setup_file(const std::string& path);

/// The same from a config's text; `file` names it in messages and resolves relative paths.
TrackerSetup load_tracker_setup(const std::string& json_text, const std::string& file);

/// The embedded default config (the built-in full-body model, 45 markers).
TrackerSetup default_tracker_setup();

}  // namespace fabrik
