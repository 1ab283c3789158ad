// A small synthetic subject for calibration tests: a template for the
// pelvis, right thigh and shank, and a static trial of it with known joint
// centres (the pelvis turned and tilted, so frames are not the world's).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/marker_trial.hpp"

namespace fabrik::test {

// Pelvis, right thigh and shank; knee and ankle centres from static-only medial markers.
inline nlohmann::json leg_template() {
  return nlohmann::json::parse(R"({
    "format": "fabrikd-template/1", "name": "leg", "units": "mm",
    "defaults": {"level": 0, "weight": 1},
    "segments": [
      {"name": "pelvis", "base": "origin", "level": 2,
       "frame": [{"axis": "z", "from": "LASI", "to": "RASI"},
                 {"axis": "x", "from": "SACR", "to": ["RASI", "LASI"]}],
       "points": {
         "origin": {"midpoint": ["r_hip", "l_hip"]},
         "r_hip": {"regression": "harrington2007", "side": "right",
                   "markers": {"r_asis": "RASI", "l_asis": "LASI", "sacrum": "SACR"}},
         "l_hip": {"regression": "harrington2007", "side": "left",
                   "markers": {"r_asis": "RASI", "l_asis": "LASI", "sacrum": "SACR"}},
         "lumbar": {"offset": [0, 100, 20], "from": ["RASI", "LASI"]}},
       "markers": {"RASI": {}, "LASI": {}, "SACR": {"weight": 2}}},
      {"name": "r_thigh", "parent": "pelvis", "base": "r_hip",
       "points": {"r_knee": {"midpoint": ["RKNE", "RKNM"]}},
       "markers": {"RTHI": {}, "RKNE": {}, "RKNM": {"static_only": true}}},
      {"name": "r_shank", "parent": "r_thigh", "base": "r_knee",
       "points": {"r_ankle": {"midpoint": ["RANK", "RANM"]}},
       "markers": {"RTIB": {}, "RANK": {}, "RANM": {"static_only": true}}}
    ]})");
}

// The synthetic subject: pelvis turned and tilted, so frames are not the world's.
struct Subject {
  Eigen::Matrix3d r_pelvis;
  Eigen::Vector3d mid_asis_m{0.3, 0.95, -0.2};
  std::vector<std::string> labels{"RASI", "LASI", "SACR", "RTHI", "RKNE",
                                  "RKNM", "RTIB", "RANK", "RANM"};
  std::vector<Eigen::Vector3d> pos_m;
  Subject() {
    r_pelvis = (Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitZ()))
                   .toRotationMatrix();
    auto pel = [&](double x, double y, double z) {
      return Eigen::Vector3d(mid_asis_m + r_pelvis * Eigen::Vector3d(x, y, z));
    };
    const Eigen::Vector3d knee(0.35, 0.50, 0.0), ankle(0.33, 0.10, 0.02);
    pos_m = {pel(0, 0, 0.125),  // ASIS 250 mm apart, sacrum 160 mm behind: PW 250, PD 160
             pel(0, 0, -0.125),
             pel(-0.16, 0, 0),
             Eigen::Vector3d(0.40, 0.70, 0.08),
             knee + Eigen::Vector3d(0.01, 0, 0.05),
             knee - Eigen::Vector3d(0.01, 0, 0.05),
             Eigen::Vector3d(0.36, 0.30, 0.07),
             ankle + Eigen::Vector3d(0, 0, 0.035),
             ankle - Eigen::Vector3d(0, 0, 0.035)};
  }
  Eigen::Vector3d at(const std::string& l) const {
    return pos_m[std::find(labels.begin(), labels.end(), l) - labels.begin()];
  }
  // Ten frames with +-0.5 mm alternating noise (the mean is exact) and RTHI
  // missing in frames 2 and 3 (one + and one -, so its mean stays exact).
  io::MarkerTrial trial() const {
    io::MarkerTrial t;
    t.labels = labels;
    t.rate_hz = 100;
    for (int f = 0; f < 10; ++f)
      for (std::size_t m = 0; m < labels.size(); ++m) {
        Eigen::Vector3d p = pos_m[m] + Eigen::Vector3d::Constant(f % 2 ? -5e-4 : 5e-4);
        if (labels[m] == "RTHI" && (f == 2 || f == 3)) p.setConstant(NAN);
        t.positions_m.push_back(p);
      }
    return t;
  }
};

}  // namespace fabrik::test
