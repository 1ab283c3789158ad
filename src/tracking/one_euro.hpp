// A One Euro filter (Casiez, Roussel and Vogel, "1 Euro Filter: A Simple Speed-based Low-pass
// Filter for Noisy Input in Interactive Systems", CHI 2012) of 3D positions, one state per
// marker: an exponential smoother whose cutoff is min_cutoff + beta * |filtered velocity|, so
// a still marker is smoothed hard (jitter) and a fast one follows closely (lag).
//
// Causal and allocation-free per sample. The time step comes from the samples' times, so a
// dropped frame is no error. A marker's state is forgotten on a gap (an unmeasured frame) and
// on reset(): its next sample passes unchanged and starts afresh, so a marker that reappears
// elsewhere is not dragged from where it vanished.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "tracking/tracking_settings.hpp"

namespace fabrik {

class OneEuroFilter {
 public:
  OneEuroFilter(SmoothingSettings settings, int markers);
  const SmoothingSettings& settings() const { return settings_; }

  // Marker i measured x_m at time_s: returns the filtered position and keeps it as a pending
  // state, which commit(i) makes the marker's state (a sample the frame rejects, an outlier,
  // is never committed: the filter holds its state as if the sample had not come).
  Eigen::Vector3d filter(int i, double time_s, const Eigen::Vector3d& x_m);
  void commit(int i);
  // Marker i was not measured: its next sample starts afresh.
  void forget(int i) { state_[i].valid = false; }
  void reset();

 private:
  struct State {
    Eigen::Vector3d x_m = Eigen::Vector3d::Zero();     // filtered position
    Eigen::Vector3d dx_m_s = Eigen::Vector3d::Zero();  // filtered velocity
    double t_s = 0.0;
    bool valid = false;
  };
  SmoothingSettings settings_;
  std::vector<State> state_, pending_;
};

// The smoothing factor of an exponential smoother with this cutoff over this time step (the
// One Euro paper's alpha = 1 / (1 + tau / Te), tau = 1 / (2 pi f_c)).
double one_euro_alpha(double cutoff_hz, double dt_s);

}  // namespace fabrik
