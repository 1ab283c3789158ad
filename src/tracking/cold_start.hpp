// A cold start: the first frame, the first after Tracker::reset, or the first after a long
// gap without any measured marker. The warm start (the last pose) is then missing or stale, so
// the solve starts from the rest posture, first turned and moved as one rigid body onto the
// visible markers (the subject may stand anywhere in the room, facing anywhere), and gets an
// iteration budget of its own: a warm frame needs a few iterations, a cold one may need
// hundreds to bend every joint from rest.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>

#include "solver/model.hpp"
#include "solver/posture.hpp"
#include "solver/solve_types.hpp"

#include "tracking/tracking_settings.hpp"

namespace fabrik {

// The solver options of a cold frame: the warm ones with the cold budget, at least the
// fallback carry as the subtree carry, and anchors at least kColdMinAnchorWeight.
SolverOptions cold_solver_options(const SolverOptions& warm, const ColdStartSettings& cold);
// A cold frame's least anchor weight: the stronger levels' targets weigh at least as much as
// a weaker level's own (weight 1) in its pass.
inline constexpr double kColdMinAnchorWeight = 1.0;

// Turns and moves `posture` (the rest posture) as one rigid body so that the model points
// points[i] best meet measured_world_m[i] where visible[i] (least squares, Kabsch). With fewer
// than three visible points, or points on a line, it only moves it. Allocates nothing.
void align_rigidly(const Model& model, std::span<const int> points,
                   std::span<const Eigen::Vector3d> measured_world_m,
                   std::span<const std::uint8_t> visible, Posture& posture);

}  // namespace fabrik
