#include "gap_predictor.hpp"

namespace fabrik {

GapPredictor::GapPredictor(const Model& model, std::span<const int> marker_points,
                           const PredictionSettings& settings)
    : rotation_(model, marker_points, settings), fill_(model, marker_points, settings) {}

void GapPredictor::reset() {
  rotation_.reset();
  fill_.reset();
}

void GapPredictor::before_solve(double time_s, std::span<const std::uint8_t> seen,
                                std::span<Eigen::Vector3d> target_world_m,
                                std::span<Eigen::Quaterniond> q_world,
                                std::span<std::uint8_t> q_visible) {
  if (rotation_.clock_restarted(time_s)) reset();
  // Nothing predicted (prediction off, or nothing measured): no hand-over either.
  if (!rotation_.before_solve(time_s, seen, q_world, q_visible)) return;
  fill_.hand_over(time_s, seen, rotation_, target_world_m);
}

void GapPredictor::after_solve(double time_s, const Posture& posture,
                               std::span<const std::uint8_t> seen,
                               std::span<const Eigen::Vector3d> measured,
                               std::span<Eigen::Vector3d> markers_world_m, std::span<double> gap_s) {
  // The fill first, on this frame's predicted rotations; then the posture
  // joins the recent past.
  fill_.after_solve(time_s, posture, rotation_, seen, measured, markers_world_m, gap_s);
  rotation_.record(time_s, posture);
}

}  // namespace fabrik
