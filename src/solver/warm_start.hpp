// The start posture of a frame's solve: the last solved posture moved on at its last velocity
// (every joint's rotation relative to its parent, and the root's pose, turned and moved again
// by kDamping times as much as between the last two frames, scaled to the time since).
// FABRIK's iterations converge linearly, so a start nearer the answer saves iterations
// (docs/speed.md). The solver's answer does not depend on the start beyond its stopping rule
// (and, where markers do not determine a joint, on where that joint starts); the solver brings
// the start's joints within their ranges.
//
// Why damped: where the markers do not determine a joint (the split of a turn between two
// joints in series, such as gait2354's abdomen and torso, or a clavicle's twist) the solver
// leaves it where it starts, so a velocity carried on in full would carry it on for ever. At
// 0.75 such a velocity dies out within a few frames. On synthetic motion of gait2354
// (calibrated on subject01_static, 1 mm marker noise, 1000 frames at 100 Hz, the cycle at 1
// and 3 times its default frequency) the joint centres end 1.85 and 2.47 mm from the truth on
// average, against 2.31 and 2.62 without a velocity, 2.08 and 2.51 at 0.5 and 2.42 and
// 4.83 mm at 1. The value comes from that model and subject01_walk1 (0.5, 0.75 and 1 tried).
// Allocates nothing after construction.
#pragma once

#include "model.hpp"
#include "posture.hpp"

namespace fabrik {

class WarmStart {
 public:
  explicit WarmStart(const Model& model);

  // Forget the past frames (a cold start follows).
  void reset() { recorded_ = 0; }
  // A frame solved at time_s; root_placed: markers placed its root (else the root was held
  // where it was).
  void record(double time_s, const Posture& solved, bool root_placed);
  // The start for a frame at time_s: the last recorded posture, moved on at the velocity of the
  // last two when markers place the root in this frame and placed it in both, and the time
  // since the last is positive and at most kMaxStepRatio times the interval between them; else
  // the last posture as it is. (Without markers, orientation sensors alone set the joints they
  // measure and leave the others where they start: carried on, those would wander, e.g. the
  // arms of a lower-body IMU set.) Leaves `start` as it is before the first record.
  void predict(double time_s, bool markers, Posture& start) const;

  // How far ahead a velocity is carried, in units of the interval it was measured over (a
  // dropped frame still counts; a gap does not).
  static constexpr double kMaxStepRatio = 2.0;
  static constexpr double kDamping = 0.75;

 private:
  const Model& model_;
  Posture last_, before_;
  double last_s_ = 0.0, before_s_ = 0.0;
  int recorded_ = 0;  // frames recorded since the last reset, up to 2
  bool last_placed_ = false, before_placed_ = false;
};

}  // namespace fabrik
