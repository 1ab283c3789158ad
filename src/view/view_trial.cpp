#include "view_trial.hpp"

#include <filesystem>

#include "offline/solve_trial.hpp"
#include "transport/pose_codec.hpp"

namespace fabrik::view {

using nlohmann::json;

namespace {

json vector_json(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

}  // namespace

json minimal_model(const DaemonConfig& config) {
  const Model& model = *config.tracker.model;
  json joints = json::array(), markers = json::array(), segments = json::array(),
       coordinates = json::array(), sensors = json::array();
  for (const Joint& j : model.joints) joints.push_back(j.name);
  for (const MarkerTarget& m : config.tracker.markers) {
    const int seg = m.point >= 0 ? model.points[m.point].segment : -1;
    markers.push_back({{"name", m.marker},
                       {"segment", seg >= 0 ? json(model.segments[seg].name) : json(nullptr)}});
  }
  for (const Segment& s : model.segments)
    segments.push_back({{"name", s.name},
                        {"parent", s.parent >= 0 ? json(model.segments[s.parent].name)
                                                 : json(nullptr)}});
  for (const Coordinate& c : model.coordinates) coordinates.push_back({{"name", c.name}});
  for (const SensorTarget& s : config.tracker.sensors.sensors) sensors.push_back(s.sensor);
  return {{"config", std::filesystem::path(config.file).filename().string()},
          {"units", config.output_units},
          {"lab_axes",
           {{"up", vector_json(model.lab_axes.up_lab)},
            {"forward", vector_json(model.lab_axes.forward_lab)}}},
          {"joints", joints},
          {"markers", markers},
          {"segments", segments},
          {"coordinates", coordinates},
          {"sensors", sensors}};
}

TrialView trial_view(const DaemonConfig& config, const io::MarkerTrial& trial) {
  // Poses are written as the daemon writes them (PoseEncoder, JSON), spliced into one array.
  std::string poses = "[";
  std::string pose;
  std::unique_ptr<wire::PoseEncoder> encoder;
  std::size_t count = 0;
  solve_trial(config, trial, {}, nullptr,
              [&](std::size_t f, double time_s, const Tracker& tracker, const TrackResult& r) {
                if (!encoder)
                  encoder = std::make_unique<wire::PoseEncoder>(tracker, config.output_units,
                                                                wire::PayloadEncoding::json);
                wire::PoseHeader header;
                header.frame = static_cast<std::uint64_t>(std::max<long long>(
                    0, static_cast<long long>(trial.first_frame) + static_cast<long long>(f)));
                header.has_time = true;
                header.time_s = time_s;
                encoder->encode(header, r, pose);
                if (count++ > 0) poses += ',';
                poses += pose;
              });
  poses += ']';
  TrialView v;
  v.poses = count;
  v.message = R"({"topic":"trial","data":{"model":)" + minimal_model(config).dump() +
              R"(,"poses":)" + poses + "}}";
  return v;
}

}  // namespace fabrik::view
