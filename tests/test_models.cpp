#include "test_models.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "config/model_loader.hpp"
#include "solver/joint_angles.hpp"
#include "solver/model_builder.hpp"
#include "synth/random_draws.hpp"

namespace fabrik::test {

Model chain_model(int n, double length_m) {
  std::vector<SegmentSpec> specs;
  for (int i = 0; i < n; ++i) {
    SegmentSpec s;
    s.name = "seg" + std::to_string(i);
    s.parent = i == 0 ? "" : "seg" + std::to_string(i - 1);
    s.base = "j" + std::to_string(i);
    const double bend = (i % 2 == 0 ? 0.1 : -0.05) * length_m;
    s.points.push_back({"j" + std::to_string(i + 1), {bend, length_m, 0.02 * length_m}, false});
    specs.push_back(s);
  }
  return build_model("chain", specs, Eigen::Vector3d::Zero());
}

Model paper_model() {
  return load_model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/paper_upper_body.json");
}

Model fullbody_model() {
  return load_model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
}

Model random_tree_model(std::mt19937_64& rng, int n_segments) {
  return build_model("random", random_tree_specs(rng, n_segments), Eigen::Vector3d::Zero());
}

std::vector<SegmentSpec> random_tree_specs(std::mt19937_64& rng, int n_segments) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> n_points(1, 4);
  auto random_offset = [&] {
    Eigen::Vector3d v = draw_vector3(unit, rng);
    while (v.norm() < 0.1) v = draw_vector3(unit, rng);
    const double len = 0.05 + 0.45 * (unit(rng) + 1.0) / 2.0;
    return Eigen::Vector3d(v.normalized() * len);
  };
  std::vector<SegmentSpec> specs;
  std::vector<std::string> free_joints;  // joint points not yet used as a base
  int point_id = 0;
  for (int s = 0; s < n_segments; ++s) {
    SegmentSpec spec;
    spec.name = "s" + std::to_string(s);
    if (s == 0) {
      spec.base = "root";
    } else {
      if (free_joints.empty()) break;
      std::uniform_int_distribution<std::size_t> pick(0, free_joints.size() - 1);
      const std::size_t k = pick(rng);
      spec.base = free_joints[k];
      free_joints.erase(free_joints.begin() + static_cast<long>(k));
      for (const SegmentSpec& other : specs)
        for (const PointSpec& p : other.points)
          if (p.name == spec.base) spec.parent = other.name;
    }
    const int n = n_points(rng);
    for (int k = 0; k < n; ++k) {
      const bool marker = k > 0 && (unit(rng) > 0.2);
      PointSpec p{(marker ? "m" : "p") + std::to_string(point_id++), random_offset(), marker};
      if (!marker) free_joints.push_back(p.name);
      spec.points.push_back(p);
    }
    specs.push_back(spec);
  }
  return specs;
}

double max_rigidity_error(const Model& model, const Posture& posture) {
  const Posture rest = Posture::rest(model);
  double worst = 0.0;
  for (const Segment& seg : model.segments)
    for (int i = seg.first_point; i < seg.first_point + seg.point_count; ++i)
      for (int j = i + 1; j < seg.first_point + seg.point_count; ++j) {
        const double d0 = (rest.point_world_m(model, i) - rest.point_world_m(model, j)).norm();
        const double d1 =
            (posture.point_world_m(model, i) - posture.point_world_m(model, j)).norm();
        if (d0 > 0) worst = std::max(worst, std::abs(d1 - d0) / d0);
      }
  return worst;
}

double max_joint_gap_m(const Model& model, const Posture& posture) {
  double worst = 0.0;
  for (std::size_t s = 1; s < model.segments.size(); ++s)
    worst = std::max(worst, (posture.point_world_m(model, model.segments[s].parent_point) -
                             posture.segments[s].base_world_m)
                                .norm());
  return worst;
}

double max_limit_excess_rad(const Model& m, const Posture& p) {
  double worst = 0.0;
  for (int s = 1; s < static_cast<int>(m.segments.size()); ++s) {
    const JointLimits& j = m.segments[s].joint;
    if (!j.limited()) continue;
    const Eigen::Vector3d a = joint_angles_rad(m, p, s);
    for (int k = 0; k < 3; ++k) {
      // Outside [lo, hi] on the circle: the distance to the nearer bound.
      auto wrap = [](double x) { return std::remainder(x, 2.0 * std::numbers::pi); };
      const double lo = j.min_rad[k], hi = j.max_rad[k];
      // How far past lo the angle lies, going the positive way round, in [0, 2 pi).
      const double past_lo = std::fmod(a[k] - lo + 4.0 * std::numbers::pi, 2.0 * std::numbers::pi);
      const bool inside = k == 1 ? (a[k] >= lo && a[k] <= hi) : past_lo <= hi - lo + 1e-12;
      if (!inside)
        worst = std::max(worst, std::min(std::abs(wrap(a[k] - lo)), std::abs(wrap(a[k] - hi))));
    }
  }
  return worst;
}

// A hinge child's point's component along the hinge axis (parent frame) is that of the rest
// pose.
double max_hinge_plane_m(const Model& m, const Posture& p) {
  double worst = 0.0;
  for (int s = 1; s < static_cast<int>(m.segments.size()); ++s) {
    const Segment& seg = m.segments[s];
    if (seg.joint.type != JointType::hinge) continue;
    const Eigen::Vector3d u = m.segments[seg.parent].q_anatomical * Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d& r_parent = p.segments[seg.parent].r_world;
    for (int i = seg.first_point; i < seg.first_point + seg.point_count; ++i) {
      const Eigen::Vector3d v =
          r_parent.transpose() * (p.point_world_m(m, i) - p.segments[s].base_world_m);
      worst = std::max(worst, std::abs(v.dot(u) - m.points[i].p_local_m.dot(u)));
    }
  }
  return worst;
}

HingedArm hinged_arm() {
  auto spec = [](const char* name, const char* parent, const char* base,
                 std::vector<PointSpec> points) {
    SegmentSpec s;
    s.name = name;
    s.parent = parent;
    s.base = base;
    s.points = std::move(points);
    return s;
  };
  std::vector<SegmentSpec> specs = {
      spec("torso", "", "root", {{"shoulder", {0, 0.4, 0}, false}, {"T", {0.1, 0.1, 0}, true}}),
      spec("upper", "torso", "shoulder",
           {{"elbow", {0, -0.3, 0}, false}, {"UA", {0, -0.15, 0}, true}}),
      spec("fore", "upper", "elbow",
           {{"wrist", {0, -0.25, 0}, true}, {"thumb", {0.06, -0.25, 0.0}, true}})};
  specs[2].joint.type = JointType::hinge;
  specs[2].joint.min_rad = {-2.6, 0.0, 0.0};
  specs[2].joint.max_rad = {2.6, 0.0, 0.0};
  HingedArm arm;
  arm.model = std::make_shared<const Model>(build_model("arm", specs, Eigen::Vector3d::Zero()));
  const Model& m = *arm.model;
  Posture goal = Posture::rest(m);
  const Eigen::Quaterniond q_upper(
      Eigen::AngleAxisd(60.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitY()));
  goal.segments[1].set_rotation(q_upper);
  goal.segments[2].set_rotation(
      q_upper * Eigen::Quaterniond(Eigen::AngleAxisd(1.4, Eigen::Vector3d::UnitZ())));
  goal.segments[2].base_world_m = goal.point_world_m(m, m.segments[2].parent_point);
  for (int p : m.marker_points()) {
    arm.targets.push_back({p, 0, 1.0});
    arm.goal_m.push_back(goal.point_world_m(m, p));
  }
  arm.start = Posture::rest(m);
  arm.start.segments[2].set_rotation(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ())));
  return arm;
}

}  // namespace fabrik::test
