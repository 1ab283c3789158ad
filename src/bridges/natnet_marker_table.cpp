#include "bridges/natnet_marker_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "bridges/natnet_names.hpp"
#include "common/ascii_case.hpp"

namespace fabrik::natnet {

namespace {

bool is_all_set(const std::string& name) {
  return iequals(name, "all");
}

bool seen(const Point3f& p) {
  const bool finite = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
  return finite && !(p[0] == 0.0F && p[1] == 0.0F && p[2] == 0.0F);
}

bool contains(const std::vector<std::int32_t>& ids, std::int32_t id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

}  // namespace

void MarkerTable::reset(const ModelDefinitions& defs) {
  sets_.clear();
  names_.clear();
  for (const auto& set : defs.marker_sets) {
    if (is_all_set(set.name)) continue;
    sets_.push_back({set.name, names_.size(), set.marker_names.size()});
    for (auto& name : qualified_marker_names(set)) names_.push_back(std::move(name));
  }
  rigid_body_ids_.clear();
  for (const auto& b : defs.rigid_bodies) rigid_body_ids_.push_back(b.id);
  skeleton_ids_.clear();
  for (const auto& s : defs.skeletons) skeleton_ids_.push_back(s.id);
}

bool MarkerTable::fill(const FrameOfData& frame, std::vector<Eigen::Vector3d>& p_mm,
                       std::string& why) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  p_mm.assign(names_.size(), Eigen::Vector3d::Constant(kNaN));
  for (const auto& b : frame.rigid_bodies)
    if (!contains(rigid_body_ids_, b.id)) {
      why = "rigid body id " + std::to_string(b.id) + " is not in the model definitions";
      return false;
    }
  for (const auto& s : frame.skeletons)
    if (!contains(skeleton_ids_, s.id)) {
      why = "skeleton id " + std::to_string(s.id) + " is not in the model definitions";
      return false;
    }
  occluded_.clear();
  for (const auto& m : frame.labeled_markers)
    if (m.occluded()) occluded_.push_back(m.p_m);
  for (const auto& data : frame.marker_sets) {
    if (is_all_set(data.name)) continue;
    const auto set = std::find_if(sets_.begin(), sets_.end(),
                                  [&](const Set& s) { return s.name == data.name; });
    if (set == sets_.end() || set->count != data.p_m.size()) {
      why = "marker set '" + data.name + "' with " + std::to_string(data.p_m.size()) +
            " markers is not in the model definitions";
      return false;
    }
    for (std::size_t i = 0; i < set->count; ++i) {
      const Point3f& p = data.p_m[i];
      if (!seen(p) || std::find(occluded_.begin(), occluded_.end(), p) != occluded_.end())
        continue;
      p_mm[set->first + i] = Eigen::Vector3d(p[0], p[1], p[2]) * 1000.0;  // metres -> mm
    }
  }
  return true;
}

}  // namespace fabrik::natnet
