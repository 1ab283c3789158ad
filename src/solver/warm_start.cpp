#include "warm_start.hpp"

#include <cmath>

namespace fabrik {

namespace {

// d^r for a unit quaternion d: the same axis, about r times the angle (tan(angle / 2) times r:
// near enough for a start, and exact for r = 1).
Eigen::Quaterniond power(const Eigen::Quaterniond& d, double r) {
  if (r == 1.0) return d;
  const double w = d.w() < 0.0 ? -d.w() : d.w();
  const Eigen::Vector3d v = (d.w() < 0.0 ? -r : r) * d.vec();
  return Eigen::Quaterniond(w, v.x(), v.y(), v.z()).normalized();
}

}  // namespace

WarmStart::WarmStart(const Model& model)
    : model_(model), last_(Posture::rest(model)), before_(Posture::rest(model)) {}

void WarmStart::record(double time_s, const Posture& solved, bool root_placed) {
  std::swap(last_, before_);  // swaps buffers: no allocation
  last_ = solved;             // same size: copies without allocating
  before_s_ = last_s_;
  last_s_ = time_s;
  before_placed_ = last_placed_;
  last_placed_ = root_placed;
  recorded_ = recorded_ < 2 ? recorded_ + 1 : 2;
}

void WarmStart::predict(double time_s, bool markers, Posture& start) const {
  if (recorded_ == 0) return;
  start = last_;
  const double interval_s = last_s_ - before_s_;
  const double ratio = (time_s - last_s_) / interval_s;
  if (recorded_ < 2 || !markers || !last_placed_ || !before_placed_ || !(interval_s > 0.0) ||
      !(ratio > 0.0) || ratio > kMaxStepRatio)
    return;
  const int n = static_cast<int>(model_.segments.size());
  if (n == 0) return;
  const double r = kDamping * ratio;
  const SegmentPose& root1 = last_.segments[0];
  const SegmentPose& root0 = before_.segments[0];
  start.segments[0].base_world_m =
      root1.base_world_m + r * (root1.base_world_m - root0.base_world_m);
  start.segments[0].set_rotation(root1.q_world *
                                 power(root0.q_world.conjugate() * root1.q_world, r));
  for (int s = 1; s < n; ++s) {
    const Segment& seg = model_.segments[s];
    const Eigen::Quaterniond rel1 =
        last_.segments[seg.parent].q_world.conjugate() * last_.segments[s].q_world;
    const Eigen::Quaterniond rel0 =
        before_.segments[seg.parent].q_world.conjugate() * before_.segments[s].q_world;
    SegmentPose& pose = start.segments[s];
    pose.set_rotation(start.segments[seg.parent].q_world * rel1 *
                      power(rel0.conjugate() * rel1, r));
    pose.base_world_m = start.point_world_m(model_, seg.parent_point);
  }
}

}  // namespace fabrik
