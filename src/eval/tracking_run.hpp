// One tracking pass over a recorded trial with chosen samples withheld, as
// the gap and marker-reduction evaluations need (internal to src/eval).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <vector>

#include "subject.hpp"

namespace fabrik::eval {

// One tracking pass over frames [0, frames) with some samples withheld.
struct TrackingRun {
  std::size_t refs = 0, n = 0;
  std::vector<Eigen::Vector3d> ref_m;      // [frame * refs + r]
  std::vector<Eigen::Vector3d> markers_m;  // [frame * n + i]: the model's position
  std::vector<double> rms_m;               // residual over the markers it saw
};

// Tracks frames [0, frames); hide(frame, marker) -> true withholds that sample
// from the tracker. col: the trial column of each tracked marker.
TrackingRun track_withholding(const DaemonConfig& config, const io::MarkerTrial& trial,
                              const std::vector<int>& col, const ReferencePoints& refs,
                              std::size_t frames,
                              const std::function<bool(std::size_t, int)>& hide);

}  // namespace fabrik::eval
