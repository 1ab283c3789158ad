// The `model` payload of the wire contract (proto/model.schema.json): what a
// viewer needs to draw the poses of one config, named exactly as the poses
// name them (joints, segments, markers, angles). fabrikd builds it once per
// config, and publishes it when a subscription to `model` arrives and after
// a reload; it is not on the per-frame path.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "marker_codec.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::wire {

// The joint-centre pairs a viewer draws as bones, as indices into
// Model::joints: each segment's base joint to the base joint of each of its
// children, in segment order. (A leaf segment's end point is no joint of the
// pose, so it has no bone.)
std::vector<std::pair<int, int>> model_bones(const Model& model);

// The range of a rotational coordinate in degrees, [min, max], where the
// model limits it: the coordinate measures its segment relative to the
// segment's parent and that joint has limits. Nothing otherwise.
std::optional<std::pair<double, double>> coordinate_range_deg(const Model& model,
                                                              const Coordinate& c);

// The payload: {"config", "units", "lab_axes": {"up", "forward"}, "joints",
// "bones", "segments": [{"name", "parent", "origin"}], "markers": [{"name",
// "segment"}], "coordinates": [{"name", "min_deg", "max_deg"}], "sensors"}.
// `config_name` is already safe (safe_text), as in stats.
std::string encode_model(const TrackerSetup& setup, std::string_view config_name,
                         std::string_view units, PayloadEncoding encoding);

}  // namespace fabrik::wire
