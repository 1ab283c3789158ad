// `fabrik bench pipeline`: where a frame's time goes in fabrikd. The
// daemon's own frame path (Daemon::serve_payload: decode a marker payload,
// track, encode the pose, publish it on the output socket to a subscriber
// that reads every pose) driven in-process, one frame at a time, per stage:
// decode, solve, encode, send. The default model and each config given are
// interleaved frame by frame, so they see the same machine load.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct PipelineOptions {
  std::vector<std::string> configs;  // daemon configs measured beside the default one
  int frames = 5000;                 // measured per config, after a warm-up
  double rate_hz = 1000.0;           // the synthetic motion's sampling rate
  std::string transport = "tcp";     // of the output: tcp or ipc (loopback)
  std::string encoding = "json";     // of the marker frames and poses
  // output.pose_content for every config, as its part names ("none": the
  // required fields only); empty: each config's own.
  std::vector<std::string> pose_content;
};
nlohmann::json run_pipeline(const PipelineOptions& options);
std::string pipeline_table(const nlohmann::json& result);

}  // namespace fabrik::bench
