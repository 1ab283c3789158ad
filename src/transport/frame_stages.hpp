// Where a frame's time goes in the daemon: decode, solve (the tracker),
// encode and send, each in microseconds (stats.stages_us, `fabrik bench
// pipeline`). Recording them costs four clock reads and no allocation: the
// samples go into IntervalSamples reserved up front.
#pragma once

#include <array>
#include <cstddef>

#include "interval_stats.hpp"

namespace fabrik::wire {

enum class Stage { decode, solve, encode, send };
inline constexpr std::array<const char*, 4> kStageNames = {"decode", "solve", "encode", "send"};

// One frame's stages (us). decode: the marker payload into the tracker's
// order; solve: Tracker::track (outlier filter, gap fill and every solve it
// runs, the solver's own solve_us among them); encode: the pose payload;
// send: the frame's counts, then the pose handed to ZeroMQ.
struct FrameStages {
  std::array<double, 4> us{};
  // Of solve: the solver's own time (TrackResult::solve_us) and the iterations
  // of the frame's last solve; the rest of solve is the tracker's work around it.
  double solver_us = 0.0;
  int iterations = 0;
  double& operator[](Stage s) { return us[static_cast<std::size_t>(s)]; }
  double operator[](Stage s) const { return us[static_cast<std::size_t>(s)]; }
  // Everything but the solve: what the pipeline adds around it.
  double around_solve_us() const { return us[0] + us[2] + us[3]; }
};

// The stages over one stats interval.
class StageSamples {
 public:
  void add(const FrameStages& f) {
    for (std::size_t k = 0; k < samples_.size(); ++k) samples_[k].add(f.us[k]);
  }
  IntervalSamples& operator[](std::size_t k) { return samples_[k]; }
  void clear() {
    for (IntervalSamples& s : samples_) s.clear();
  }

 private:
  std::array<IntervalSamples, 4> samples_;
};

}  // namespace fabrik::wire
