#include "model_codec.hpp"

#include <algorithm>
#include <cmath>

#include "solver/units.hpp"
#include "wire_writer.hpp"

namespace fabrik::wire {

namespace {


// Model::joints index of the joint at each segment's base (every base is one).
std::vector<int> base_joints(const Model& model) {
  std::vector<int> joint_of(model.segments.size(), -1);
  for (std::size_t s = 0; s < model.segments.size(); ++s)
    for (std::size_t j = 0; j < model.joints.size(); ++j)
      if (model.joints[j].point == model.segments[s].base_point) joint_of[s] = static_cast<int>(j);
  return joint_of;
}

template <class Writer>
void write_model(Writer& w, const TrackerSetup& setup, std::string_view config_name,
                 std::string_view units) {
  const Model& model = *setup.model;
  const std::vector<int> origin = base_joints(model);
  const auto joint_name = [&](int j) -> const std::string& { return model.joints[j].name; };
  const auto vec = [&](const Eigen::Vector3d& v) {
    w.begin_array(3);
    // Unit axes: whole numbers, written as such.
    for (int k = 0; k < 3; ++k) w.number(v[k] + 0.0, v[k] == std::round(v[k]) ? 0 : 6);  // no -0
    w.end_array();
  };
  w.begin_map(9);
  w.key("config");
  w.string(config_name);
  w.key("units");
  w.string(units);
  w.key("lab_axes");
  w.begin_map(2);
  w.key("up");
  vec(model.lab_axes.up_lab);
  w.key("forward");
  vec(model.lab_axes.forward_lab);
  w.end_map();

  w.key("joints");
  w.begin_array(model.joints.size());
  for (const Joint& j : model.joints) w.string(j.name);
  w.end_array();

  const std::vector<std::pair<int, int>> bones = model_bones(model);
  w.key("bones");
  w.begin_array(bones.size());
  for (const auto& [a, b] : bones) {
    w.begin_array(2);
    w.string(joint_name(a));
    w.string(joint_name(b));
    w.end_array();
  }
  w.end_array();

  w.key("segments");
  w.begin_array(model.segments.size());
  for (std::size_t s = 0; s < model.segments.size(); ++s) {
    const Segment& seg = model.segments[s];
    w.begin_map(3);
    w.key("name");
    w.string(seg.name);
    w.key("parent");
    if (seg.parent >= 0)
      w.string(model.segments[seg.parent].name);
    else
      w.null();
    w.key("origin");
    w.string(joint_name(origin[s]));
    w.end_map();
  }
  w.end_array();

  w.key("markers");
  w.begin_array(setup.markers.size());
  for (const MarkerTarget& m : setup.markers) {
    w.begin_map(2);
    w.key("name");
    w.string(m.marker);
    w.key("segment");
    w.string(model.segments[model.points[m.point].segment].name);
    w.end_map();
  }
  w.end_array();

  // The pose's angles: the rotational coordinates, in model order.
  const auto rotation = [](const Coordinate& c) { return c.kind == CoordinateKind::rotation; };
  w.key("coordinates");
  w.begin_array(static_cast<std::size_t>(
      std::count_if(model.coordinates.begin(), model.coordinates.end(), rotation)));
  for (const Coordinate& c : model.coordinates) {
    if (!rotation(c)) continue;
    const auto range = coordinate_range_deg(model, c);
    w.begin_map(3);
    w.key("name");
    w.string(c.name);
    const auto bound = [&](const char* key, double deg) {
      w.key(key);
      if (range)
        w.number(deg, 4);
      else
        w.null();
    };
    bound("min_deg", range ? range->first : 0.0);
    bound("max_deg", range ? range->second : 0.0);
    w.end_map();
  }
  w.end_array();

  w.key("sensors");
  w.begin_array(setup.sensors.sensors.size());
  for (const SensorTarget& t : setup.sensors.sensors) w.string(t.sensor);
  w.end_array();
  w.end_map();
}

}  // namespace

std::vector<std::pair<int, int>> model_bones(const Model& model) {
  const std::vector<int> origin = base_joints(model);
  std::vector<std::pair<int, int>> bones;
  for (std::size_t s = 0; s < model.segments.size(); ++s) {
    const Segment& seg = model.segments[s];
    for (int k = 0; k < seg.child_count; ++k)
      bones.emplace_back(origin[s], origin[model.child_ids[seg.first_child + k]]);
  }
  return bones;
}

std::optional<std::pair<double, double>> coordinate_range_deg(const Model& model,
                                                              const Coordinate& c) {
  if (c.kind != CoordinateKind::rotation || c.segment < 0) return std::nullopt;
  const Segment& seg = model.segments[c.segment];
  // The joint's angles are those of the segment relative to its parent.
  if (seg.parent < 0 || c.relative_to != seg.parent || !seg.joint.limited()) return std::nullopt;
  double lo = c.sign * (seg.joint.min_rad[c.angle] + c.offset) * kDegPerRad;
  double hi = c.sign * (seg.joint.max_rad[c.angle] + c.offset) * kDegPerRad;
  if (lo > hi) std::swap(lo, hi);
  return std::pair{lo, hi};
}

std::string encode_model(const TrackerSetup& setup, std::string_view config_name,
                         std::string_view units, PayloadEncoding encoding) {
  std::string out;
  if (encoding == PayloadEncoding::json) {
    JsonWriter w(out, 6);
    write_model(w, setup, config_name, units);
  } else {
    MsgpackWriter w(out);
    write_model(w, setup, config_name, units);
  }
  return out;
}

}  // namespace fabrik::wire
