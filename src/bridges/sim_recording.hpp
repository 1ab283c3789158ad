// What `fabrik sim qtm|natnet` serves: a recording already read (TRC or C3D,
// by the app) and the script of what the simulated server does to it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace fabrik::bridges {

struct SimRecording {
  double rate_hz = 100.0;
  std::vector<std::string> names;  // marker labels, without any subject prefix
  // p_mm[frame][marker], in the file's axes, millimetres; NaN where not seen.
  std::vector<std::vector<Eigen::Vector3d>> p_mm;
  // The file's up axis ("+y" for OpenSim's TRC files, "+z" for most C3D):
  // a NatNet simulator rotates it into Motive's Y-up.
  std::string up = "+z";
};

// Things the simulated server does, at frame indices of the recording (the
// index counts on across loops: index k of loop n is n * frames + k).
struct SimScript {
  bool loop = false;
  double rate_scale = 1.0;  // 2.0 serves at twice the file's rate
  std::int64_t max_frames = -1;  // stop serving after this many (-1: all / forever when looping)
  struct Pause { std::int64_t at_frame; double seconds; };
  struct Drop { std::string marker; std::int64_t from_frame, to_frame; };  // [from, to)
  struct Rename { std::int64_t at_frame; std::string from, to; };
  struct Restart { std::int64_t at_frame; double down_seconds; };  // close everything, reopen
  std::vector<Pause> pauses;
  std::vector<Drop> drops;
  std::vector<Rename> renames;   // the server's labels change (QTM event / NatNet model change)
  std::vector<Restart> restarts;
  std::string subject_prefix;    // NatNet: names go out as "<prefix>:<marker>" when set
};

}  // namespace fabrik::bridges
