// The `pose` payload of the wire contract (proto/pose.schema.json), written
// straight from a TrackResult into a reused buffer, in JSON or MessagePack.
// Names are escaped once, at construction.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "config/pose_content.hpp"
#include "marker_codec.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::wire {

// The wire status: the contract knows converged, max_iterations and
// no_targets. A solve that stopped because nothing would change any more
// ("stalled": the least-squares optimum of noisy or unreachable targets) is
// reported as converged; `solver.stop` carries the internal reason.
std::string_view wire_status(SolveStatus status);

struct PoseHeader {
  std::uint64_t frame = 0;
  bool has_time = false;
  double time_s = 0.0;
  bool has_stamp = false;  // echo of the frame's stamp_us
  double stamp_us = 0.0;
};

// The frame's own measurements, per marker of the tracker's setup (as
// MarkerFrame holds them), for the pose's `measured` (an addition).
struct MeasuredMarkers {
  std::span<const Eigen::Vector3d> p_world_m;
  std::span<const std::uint8_t> visible;
};

class PoseEncoder {
 public:
  // Positions are written in `units` ("mm" or "m"). With `measured_markers`
  // (config output.measured_markers), each pose also carries `measured`: the
  // visible markers' measured positions; without it, no such key. `content`
  // (config output.pose_content) chooses the optional parts; the required
  // fields are always written.
  PoseEncoder(const Tracker& tracker, std::string units, PayloadEncoding encoding,
              bool measured_markers = false, PoseContent content = PoseContent::all());
  void encode(const PoseHeader& header, const TrackResult& result, std::string& out,
              MeasuredMarkers measured = {}) const;
  PayloadEncoding encoding() const { return encoding_; }
  // Addition: each pose carries "subject": `name` (multi-subject configs);
  // never called: no such key, as before subjects existed.
  void set_subject(std::string name);
  // Addition (a view's output.views[].axes): positions and segment rotations
  // are written in axes whose up and forward are `out`'s, turned from the
  // model's lab axes, and each pose carries "axes" to say so. Angles and
  // translations (OpenSim's ground frame already) do not change.
  void set_axes(const LabAxes& out);

 private:
  template <class Writer>
  void write(Writer& w, const PoseHeader& header, const TrackResult& result,
             MeasuredMarkers measured) const;

  struct Name {
    std::string plain, json_key;
  };
  std::vector<Name> joints_, markers_;
  // Additions to contract v1: joint angles (degrees), translations (output
  // units) and each segment's anatomical frame. Index into the model's
  // coordinates / segments.
  std::vector<Name> angle_names_, translation_names_, segment_names_;
  std::vector<int> angle_index_, translation_index_;
  std::string units_;
  std::string subject_;  // empty: no "subject" key
  LabAxes lab_axes_;     // the model's
  bool turned_ = false;  // set_axes: r_out_lab_ applies and "axes" is written
  Eigen::Matrix3d r_out_lab_ = Eigen::Matrix3d::Identity();
  Eigen::Quaterniond q_out_lab_ = Eigen::Quaterniond::Identity();
  std::string up_out_, forward_out_;  // the axes' names, as configured
  double scale_;  // output units per metre
  int decimals_;
  PayloadEncoding encoding_;
  bool measured_markers_;
  PoseContent content_;
  // Keys of the pose, of its residual and of its solver (MessagePack map headers).
  std::size_t pose_keys_, residual_keys_, solver_keys_;
};

}  // namespace fabrik::wire
