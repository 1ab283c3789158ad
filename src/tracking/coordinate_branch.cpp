#include "tracking/coordinate_branch.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/joint_angles.hpp"

namespace fabrik {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

CoordinateBranch::CoordinateBranch(const Model& model)
    : model_(model),
      branch_(model.coordinates.size(), kNaN),
      branch_s_(model.coordinates.size(), 0.0),
      jump_since_s_(model.coordinates.size(), kNaN),
      written_(model.coordinates.size(), kNaN),
      near_written_(model.coordinates.size(), kNaN) {}

void CoordinateBranch::follow(double time_s, std::span<double> coordinates, bool continues) {
  if (coordinates.size() != branch_.size()) return;
  if (!continues) {
    std::fill(branch_.begin(), branch_.end(), kNaN);
    std::fill(jump_since_s_.begin(), jump_since_s_.end(), kNaN);
    std::fill(written_.begin(), written_.end(), kNaN);
  }
  const double frame_s = continues ? time_s - previous_s_ : 0.0;
  previous_s_ = time_s;
  // The two candidates, each by whole turns (unwrap_coordinates: the whole-turn rule's owner).
  std::copy(coordinates.begin(), coordinates.end(), near_written_.begin());
  unwrap_coordinates(model_, written_, near_written_);
  unwrap_coordinates(model_, branch_, coordinates);  // coordinates: now nearest the branch
  const bool tellable = kFastestTurn_rad_per_s * frame_s < kTellable_rad;
  for (std::size_t i = 0; i < branch_.size(); ++i) {
    if (model_.coordinates[i].kind != CoordinateKind::rotation) continue;
    double& value = coordinates[i];
    if (!std::isfinite(value)) continue;            // nothing measured: the branch waits
    if (!std::isfinite(branch_[i]) || !tellable) {  // a first value, or a swap looks like a turn
      if (std::isfinite(written_[i])) value = near_written_[i];
      branch_[i] = written_[i] = value;
      branch_s_[i] = time_s;
      jump_since_s_[i] = kNaN;
      continue;
    }
    const double limit_rad = std::clamp(kFastestTurn_rad_per_s * (time_s - branch_s_[i]),
                                        kSmallestLimit_rad, kTellable_rad);
    if (std::abs(value - branch_[i]) <= limit_rad) {
      branch_[i] = value;
      branch_s_[i] = time_s;
      jump_since_s_[i] = kNaN;
    } else {
      value = std::isfinite(written_[i]) ? near_written_[i] : value;
      if (std::isnan(jump_since_s_[i])) {
        jump_since_s_[i] = time_s;
      } else if (time_s - jump_since_s_[i] >= kJumpKept_s) {
        branch_[i] = value;
        branch_s_[i] = time_s;
        jump_since_s_[i] = kNaN;
      }
    }
    written_[i] = value;
  }
}

}  // namespace fabrik
