// Model templates (`fabrikd-template/1`, see docs/calibration.md): which
// markers belong to which segment, the segment tree, and how every joint
// centre and end site is defined from static-trial markers. `fabrik
// calibrate` turns a template plus a static trial into a fabrikd-model/1
// model. Loading validates everything that does not need the trial; every
// error is a ConfigError naming the file, the JSON pointer and the fix.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "config/lab_axes_json.hpp"
#include "config/sensors_json.hpp"

namespace fabrik::calib {

// A position taken from the static trial: one name (a marker or a template
// point) or the mean of several.
struct PointRef {
  std::vector<std::string> names;
};

// One axis of a frame built from markers: the direction from -> to.
struct FrameAxis {
  int axis = 0;  // 0 = x, 1 = y, 2 = z
  PointRef from, to;
};

// A right-handed frame: `primary` is exact, `secondary` is made orthogonal to
// it, the third axis completes the frame.
struct FrameSpec {
  FrameAxis primary, secondary;
  std::string pointer;  // where it was defined, for messages
};

enum class PointRule {
  at,          // at a marker (or the mean of several)
  midpoint,    // mean of two or more markers / points
  offset,      // a fixed offset from a position, in a frame built from markers
  regression,  // a published hip joint centre regression
};

enum class HipRegression {
  harrington2007,  // Harrington et al., J Biomech 40 (2007) 595-602, the PW/PD equations
};

struct PointDef {
  std::string name;
  int segment = -1;
  PointRule rule = PointRule::at;
  std::vector<PointRef> refs;  // at: one; midpoint: two or more
  // offset
  Eigen::Vector3d offset_m{0, 0, 0};
  int frame = -1;  // index into CalibTemplate::frames
  // regression
  HipRegression regression = HipRegression::harrington2007;
  bool right = true;
  PointRef r_asis, l_asis, posterior;  // posterior: the sacral marker or the two PSIS
  std::string pointer;
  // Keypoint templates ("kind": "keypoints", docs/keypoints.md): what the point's
  // keypoint lands on ("joint" or "point"; empty: not a target), and the point's rest
  // position: `rest_m` from the point `rest_from` (the segment's base unless named),
  // in OpenSim's axes (x anterior, y up, z right). Its direction is kept; its length
  // is measured from the keypoints. `optional`: the keypoint may be absent.
  std::string target;
  bool has_rest = false;
  Eigen::Vector3d rest_m{0, 0, 0};
  std::string rest_from;
  bool optional = false;
  bool fixed = false;  // seen by no keypoint: at its nominal rest vector (a "~NAME" marker)
};

struct MarkerDef {
  std::string name;
  int segment = -1;
  int level = 0;
  double weight = 1.0;
  bool static_only = false;  // defines joint centres, not part of the model
  std::string pointer;
};

struct SegmentDef {
  std::string name;
  int parent = -1;
  std::string base;  // a point of the parent (the root: one of its own points)
  // The segment's frame: its anatomical frame in the model, and the frame of
  // its offset points. -1 if none.
  int frame = -1;
  // The base joint's type and ranges, copied into the model as they are
  // (fabrikd-model/1 "joint", checked when the model is built); null if none.
  nlohmann::json joint;
  std::string pointer;
};

// "markers": skin markers with a static trial (the default); "keypoints": markerless
// keypoints on joint centres and segment points, no static trial (docs/keypoints.md).
enum class TemplateKind { markers, keypoints };

struct CalibTemplate {
  std::string file;
  TemplateKind kind = TemplateKind::markers;
  std::string name;
  std::string description;
  int default_level = 0;
  double default_weight = 1.0;
  std::vector<SegmentDef> segments;  // parents first
  std::vector<PointDef> points;      // grouped by segment, in file order within it
  std::vector<MarkerDef> markers;
  std::vector<FrameSpec> frames;
  // Named coordinates, copied into the model as they are (fabrikd-model/1
  // "coordinates"); null if none.
  nlohmann::json coordinates;
  // "lab_axes": the lab's up (and forward) axes, when the template declares
  // them; else calibration detects them from the static trial.
  std::optional<LabAxesSpec> lab_axes;
  // Orientation sensors ("sensors": which sensor sits on which segment, the
  // sensors' world and its heading rule); their rotations come from
  // `fabrik calibrate --static-orientations`. No entries if none.
  SensorSection sensors;

  int find_point(const std::string& name) const;
  int find_marker(const std::string& name) const;
  int find_segment(const std::string& name) const;
};

// Throws ConfigError. `file` is used in messages.
CalibTemplate load_template(const nlohmann::json& doc, const std::string& file);
CalibTemplate load_template_file(const std::string& path);

// What a keypoint template given a static trial is told (each caller adds its fix):
// "PATH is a keypoint template: it calibrates from a movement trial or its nominal lengths".
std::string keypoint_template_not_static(const std::string& template_path);
// The note of a calibration that leaves a template's orientation sensors out (each caller adds
// how to calibrate them): "the template's N orientation sensors are left out of the config".
std::string sensors_left_out(std::size_t sensors);

// The regression's hip joint centre in the pelvis frame of the regression
// (origin at the mid-ASIS, x anterior, y superior, z to the right), metres.
// pelvic_width_m: ASIS to ASIS; pelvic_depth_m: mid-ASIS to the posterior
// reference (mid-PSIS or sacral marker).
Eigen::Vector3d hip_centre_in_pelvis_m(HipRegression regression, bool right, double pelvic_width_m,
                                       double pelvic_depth_m);

}  // namespace fabrik::calib
