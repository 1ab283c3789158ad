// Whether a measured marker moved relative to its neighbours: the test that
// separates a label swap, ghost or stray sample from a clean marker the model
// cannot fit (a hinge elbow against a pronating forearm's wrist markers).
//
// A marker's neighbours are the other markers of its segment, whose distance
// to it is fixed (its calibrated value), and the markers of the segments
// joined to its own, whose distance to it can be anything the triangle
// through the shared joint centre allows ([|r_a - r_b|, r_a + r_b], r the
// distances to that centre): true whatever the joint's type or ranges, so a
// marker is never judged by what the model lets the joint do.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "solver/model.hpp"

namespace fabrik {

class MarkerNeighbours {
 public:
  // `marker_points[i]`: the model point of marker i.
  MarkerNeighbours(const Model& model, const std::vector<int>& marker_points);

  // True when marker i's measured distances to its measured neighbours
  // (visible[j], finite) break their bounds by more than `tolerance_m` for at
  // least half of them (a marker swapped with a neighbour keeps its distance to
  // that one); also true when none of its neighbours is measured (nothing says
  // it did not move).
  bool moved(int i, std::span<const Eigen::Vector3d> measured_m,
             std::span<const std::uint8_t> visible, double tolerance_m) const;

  // Marker i's neighbours, for tests: [first, last) into the bound arrays.
  int neighbour_count(int i) const { return first_[i + 1] - first_[i]; }

 private:
  std::vector<int> first_;       // marker i's neighbours: [first_[i], first_[i + 1])
  std::vector<int> other_;       // the neighbour's marker index
  std::vector<double> min_m_;    // distance bounds
  std::vector<double> max_m_;
};

}  // namespace fabrik
