#include "view_trial.hpp"

#include "offline/solve_trial.hpp"
#include "common/safe_text.hpp"
#include "transport/model_codec.hpp"
#include "transport/pose_codec.hpp"

namespace fabrik::view {

using nlohmann::json;

TrialView trial_view(const DaemonConfig& config, const io::MarkerTrial& trial) {
  // Poses are written as the daemon writes them (PoseEncoder, JSON), spliced into one array.
  std::string poses = "[";
  std::string pose;
  std::unique_ptr<wire::PoseEncoder> encoder;
  std::size_t count = 0;
  solve_trial(
      config, trial, {}, nullptr,
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
      },
      TrialPass::live);  // the poses as fabrikd publishes them; no refit wanted
  poses += ']';
  TrialView v;
  v.poses = count;
  // The model as fabrikd publishes it on its `model` topic (bones, ranges).
  const std::string model = wire::encode_model(config.tracker, safe_text(config.file), config.output_units,
                                               wire::PayloadEncoding::json);
  v.message = R"({"topic":"trial","data":{"model":)" + model +
              R"(,"poses":)" + poses + "}}";
  return v;
}

}  // namespace fabrik::view
