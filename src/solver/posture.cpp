#include "posture.hpp"

namespace fabrik {

Posture Posture::rest(const Model& model) {
  Posture posture;
  posture.segments.resize(model.segments.size());
  if (!posture.segments.empty()) posture.segments[0].base_world_m = model.root_rest_m;
  connect_joints(model, posture);
  return posture;
}

bool connect_joints(const Model& model, Posture& posture) {
  if (posture.segments.size() != model.segments.size()) return false;
  for (std::size_t s = 1; s < model.segments.size(); ++s) {
    const Segment& seg = model.segments[s];
    posture.segments[s].base_world_m = posture.point_world_m(model, seg.parent_point);
  }
  return true;
}

bool set_from_local(const Model& model, const Eigen::Vector3d& root_base_m,
                    std::span<const Eigen::Quaterniond> q_local, Posture& posture) {
  if (q_local.size() != model.segments.size() || posture.segments.size() != model.segments.size())
    return false;
  for (std::size_t s = 0; s < model.segments.size(); ++s) {
    const int p = model.segments[s].parent;
    posture.segments[s].set_rotation(p < 0 ? q_local[s] : posture.segments[p].q_world * q_local[s]);
  }
  posture.segments[0].base_world_m = root_base_m;
  return connect_joints(model, posture);
}

}  // namespace fabrik
