#include "view_trial.hpp"

#include <cmath>
#include <vector>

#include "offline/solve_trial.hpp"
#include "common/safe_text.hpp"
#include "transport/model_codec.hpp"
#include "transport/pose_codec.hpp"

namespace fabrik::view {

using nlohmann::json;

TrialView trial_view(const DaemonConfig& config, const io::MarkerTrial& trial,
                     const std::string& file_name) {
  // Poses are written as the daemon writes them (PoseEncoder, JSON), spliced into one array.
  std::string poses = "[";
  std::string pose;
  std::unique_ptr<wire::PoseEncoder> encoder;
  std::size_t count = 0;
  // The frame's measured markers in the tracker's order (as the daemon's MarkerFrame holds
  // them), for the pose's `measured` when the config asks for it (output.measured_markers).
  std::vector<int> column;
  for (const MarkerTarget& m : config.tracker.markers) column.push_back(trial.find(m.marker));
  std::vector<Eigen::Vector3d> measured_m(column.size());
  std::vector<std::uint8_t> visible(column.size());
  solve_trial(
      config, trial, {}, nullptr,
      [&](std::size_t f, double /*tracker_time_s*/, const Tracker& tracker, const TrackResult& r) {
        if (!encoder)
          encoder = std::make_unique<wire::PoseEncoder>(tracker, config.output_units,
                                                        wire::PayloadEncoding::json,
                                                        config.output_measured_markers);
        wire::PoseHeader header;
        header.frame = static_cast<std::uint64_t>(std::max<long long>(
            0, static_cast<long long>(trial.first_frame) + static_cast<long long>(f)));
        header.has_time = true;
        // The file's own time (as `fabrik solve` writes it), not the tracker's from 0.
        header.time_s = trial.file_time_s(f);
        for (std::size_t i = 0; i < column.size(); ++i) {
          measured_m[i] = column[i] >= 0 ? trial.at(f, static_cast<std::size_t>(column[i]))
                                         : Eigen::Vector3d::Constant(NAN);
          visible[i] = measured_m[i].allFinite() ? 1 : 0;
        }
        encoder->encode(header, r, pose, {measured_m, visible});
        if (count++ > 0) poses += ',';
        poses += pose;
      },
      TrialPass::live);  // the poses as fabrikd publishes them; no refit wanted
  poses += ']';
  TrialView v;
  v.poses = count;
  // The model as fabrikd publishes it on its `model` topic (bones, ranges).
  const std::string model = wire::encode_model(config.tracker, safe_text(config.file), config.output_units,
                                               wire::PayloadEncoding::json);
  v.message = R"({"topic":"trial","data":{"model":)" + model + R"(,"file":)" +
              json(file_name).dump(-1, ' ', false, json::error_handler_t::replace) +
              R"(,"poses":)" + poses + "}}";
  return v;
}

}  // namespace fabrik::view
