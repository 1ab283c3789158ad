#include "tracking/coordinate_branch.hpp"

#include <cmath>
#include <limits>
#include <numbers>

namespace fabrik {

CoordinateBranch::CoordinateBranch(const Model& model)
    : branch_(model.coordinates.size(), 0.0),
      jump_since_s_(model.coordinates.size(), std::numeric_limits<double>::quiet_NaN()),
      turn_(model.coordinates.size(), 0.0) {
  for (std::size_t i = 0; i < model.coordinates.size(); ++i) {
    const Coordinate& c = model.coordinates[i];
    // value = sign * (raw + offset): a whole turn of raw is sign turns of the value.
    if (c.kind == CoordinateKind::rotation) turn_[i] = std::abs(c.sign) * 2.0 * std::numbers::pi;
  }
}

void CoordinateBranch::follow(double time_s, std::span<double> coordinates, bool continues) {
  const std::size_t n = std::min(coordinates.size(), branch_.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (turn_[i] == 0.0 || !std::isfinite(coordinates[i])) continue;
    if (!continues || !std::isfinite(branch_[i])) {
      branch_[i] = coordinates[i];
      jump_since_s_[i] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    double& value = coordinates[i];
    value += turn_[i] * std::round((branch_[i] - value) / turn_[i]);
    if (std::abs(value - branch_[i]) <= kLargestStep_rad) {
      branch_[i] = value;
      jump_since_s_[i] = std::numeric_limits<double>::quiet_NaN();
    } else if (std::isnan(jump_since_s_[i])) {
      jump_since_s_[i] = time_s;
    } else if (time_s - jump_since_s_[i] >= kJumpKept_s) {
      branch_[i] = value;
      jump_since_s_[i] = std::numeric_limits<double>::quiet_NaN();
    }
  }
}

}  // namespace fabrik
