#include "pose_codec.hpp"

#include "config/lab_axes_json.hpp"
#include "solver/units.hpp"
#include "wire_writer.hpp"

namespace fabrik::wire {

std::string_view wire_status(SolveStatus status) {
  return status == SolveStatus::stalled ? "converged" : to_string(status);
}

PoseEncoder::PoseEncoder(const Tracker& tracker, std::string units, PayloadEncoding encoding,
                         bool measured_markers, PoseContent content)
    : units_(std::move(units)),
      lab_axes_(tracker.model().lab_axes),
      scale_(units_ == "m" ? 1.0 : 1e3),
      decimals_(units_ == "m" ? 7 : 4),  // 0.1 micrometre either way
      encoding_(encoding),
      measured_markers_(measured_markers),
      content_(content) {
  const auto n = [&](std::initializer_list<PosePart> parts) {
    std::size_t k = 0;
    for (PosePart p : parts) k += content.has(p) ? 1 : 0;
    return k;
  };
  // Required: frame, units, joints, markers, occluded, residual, solver.
  pose_keys_ = 7 + (measured_markers ? 1 : 0) +
               n({PosePart::held, PosePart::gap_s, PosePart::outliers, PosePart::relabelled,
                  PosePart::angles, PosePart::translations, PosePart::segments});
  residual_keys_ = 4 + n({PosePart::residual_quality, PosePart::residual_beyond});
  solver_keys_ = 3 + n({PosePart::solver_stop});
  for (const Joint& j : tracker.model().joints)
    joints_.push_back({j.name, JsonWriter::json_key(j.name)});
  for (const MarkerTarget& m : tracker.setup().markers)
    markers_.push_back({m.marker, JsonWriter::json_key(m.marker)});
  const Model& model = tracker.model();
  for (std::size_t i = 0; i < model.coordinates.size(); ++i) {
    const Coordinate& c = model.coordinates[i];
    const bool angle = c.kind == CoordinateKind::rotation;
    (angle ? angle_names_ : translation_names_).push_back({c.name, JsonWriter::json_key(c.name)});
    (angle ? angle_index_ : translation_index_).push_back(static_cast<int>(i));
  }
  for (const Segment& seg : model.segments)
    segment_names_.push_back({seg.name, JsonWriter::json_key(seg.name)});
}

void PoseEncoder::set_axes(const LabAxes& out) {
  if (!turned_) ++pose_keys_;
  turned_ = true;
  r_out_lab_ = out.r_from(lab_axes_);
  q_out_lab_ = Eigen::Quaterniond(r_out_lab_).normalized();
  up_out_ = signed_axis_name(out.up_lab);
  forward_out_ = signed_axis_name(out.forward_lab);
}

void PoseEncoder::set_subject(std::string name) {
  if (subject_.empty() && !name.empty()) ++pose_keys_;
  if (!subject_.empty() && name.empty()) --pose_keys_;
  subject_ = std::move(name);
}

template <class Writer>
void PoseEncoder::write(Writer& w, const PoseHeader& header, const TrackResult& r,
                        MeasuredMarkers measured) const {
  // The names of the markers flagged in `flags` (`count` of them), as an array.
  auto flagged_names = [&](std::span<const std::uint8_t> flags, std::size_t count) {
    w.begin_array(count);
    for (std::size_t i = 0; i < markers_.size(); ++i)
      if (flags[i]) w.string(markers_[i].plain);
    w.end_array();
  };
  auto vec = [&](const Eigen::Vector3d& p_lab_m) {
    const Eigen::Vector3d p_m = turned_ ? Eigen::Vector3d(r_out_lab_ * p_lab_m) : p_lab_m;
    w.number_triple(p_m[0] * scale_, p_m[1] * scale_, p_m[2] * scale_);
  };
  const auto has = [&](PosePart p) { return content_.has(p); };
  w.begin_map(pose_keys_ + (header.has_time ? 1 : 0) + (header.has_stamp ? 1 : 0));
  w.key("frame");
  w.uint(header.frame);
  if (!subject_.empty()) {
    w.key("subject");  // addition: whose pose (multi-subject configs)
    w.string(subject_);
  }
  if (header.has_time) {
    w.key("time");
    w.number_exact(header.time_s);
  }
  if (header.has_stamp) {
    w.key("stamp_us");  // addition: echoed from the marker frame
    w.number_exact(header.stamp_us);
  }
  w.key("units");
  w.string(units_);
  if (turned_) {
    w.key("axes");  // addition: the axes of the positions and rotations (a view's)
    w.begin_map(2);
    w.key("up");
    w.string(up_out_);
    w.key("forward");
    w.string(forward_out_);
    w.end_map();
  }
  w.key("joints");
  w.begin_map(joints_.size());
  for (std::size_t j = 0; j < joints_.size(); ++j) {
    w.named_key(joints_[j].plain, joints_[j].json_key);
    vec(r.joints_world_m[j]);
  }
  w.end_map();
  w.key("markers");
  w.begin_map(markers_.size());
  for (std::size_t i = 0; i < markers_.size(); ++i) {
    w.named_key(markers_[i].plain, markers_[i].json_key);
    vec(r.markers_world_m[i]);
  }
  w.end_map();
  if (measured_markers_) {
    // Addition: what this frame measured, where it measured it (visible markers only).
    const auto seen = [&](std::size_t i) {
      return i < measured.p_world_m.size() && i < measured.visible.size() && measured.visible[i] &&
             measured.p_world_m[i].allFinite();
    };
    std::size_t n = 0;
    for (std::size_t i = 0; i < markers_.size(); ++i) n += seen(i) ? 1 : 0;
    w.key("measured");
    w.begin_map(n);
    for (std::size_t i = 0; i < markers_.size(); ++i) {
      if (!seen(i)) continue;
      w.named_key(markers_[i].plain, markers_[i].json_key);
      vec(measured.p_world_m[i]);
    }
    w.end_map();
  }
  w.key("occluded");
  flagged_names(r.occluded, static_cast<std::size_t>(r.occluded_count));
  if (has(PosePart::held)) {
    std::size_t held = 0;
    for (std::uint8_t h : r.held) held += h;
    w.key("held");  // addition: occluded markers still pulled by their last position
    flagged_names(r.held, held);
  }
  if (has(PosePart::gap_s)) {
    w.key("gap_s");  // addition: per occluded marker, seconds since it was last measured
    w.begin_map(static_cast<std::size_t>(r.occluded_count));
    for (std::size_t i = 0; i < markers_.size(); ++i) {
      if (!r.occluded[i]) continue;
      w.named_key(markers_[i].plain, markers_[i].json_key);
      w.number(r.gap_s[i], 4);
    }
    w.end_map();
  }
  if (has(PosePart::outliers)) {
    w.key("outliers");  // addition: measured markers left out of this frame's solve
    flagged_names(r.outliers, static_cast<std::size_t>(r.outlier_count));
  }
  if (has(PosePart::relabelled)) {
    std::size_t relabelled = 0;
    for (std::size_t i = 0; i < markers_.size(); ++i) relabelled += r.relabelled_from[i] >= 0;
    w.key("relabelled");  // addition: swapped labels, solved with the other one's measurement
    w.begin_map(relabelled);
    for (std::size_t i = 0; i < markers_.size(); ++i)
      if (r.relabelled_from[i] >= 0) {
        w.named_key(markers_[i].plain, markers_[i].json_key);
        w.string(markers_[r.relabelled_from[i]].plain);
      }
    w.end_map();
  }
  w.key("residual");
  w.begin_map(residual_keys_);
  w.key("rms");
  w.number(r.residual_rms_m * scale_);
  w.key("max");
  w.number(r.residual_max_m * scale_);
  w.key("worst");
  if (r.worst_marker >= 0)
    w.string(markers_[r.worst_marker].plain);
  else
    w.null();
  w.key("count");
  w.uint(static_cast<std::uint64_t>(r.residual_count));
  if (has(PosePart::residual_quality)) {
    w.key("quality");  // addition: the verdict against the config's quality thresholds
    w.string(to_string(r.quality));
  }
  if (has(PosePart::residual_beyond)) {
    w.key("beyond");  // addition: markers solved with whose residual exceeds quality.max_mm
    flagged_names(r.beyond, static_cast<std::size_t>(r.beyond_count));
  }
  w.end_map();
  if (has(PosePart::angles)) {
    w.key("angles");  // addition: rotational coordinates, degrees
    w.begin_map(angle_names_.size());
    for (std::size_t i = 0; i < angle_names_.size(); ++i) {
      w.named_key(angle_names_[i].plain, angle_names_[i].json_key);
      w.number(r.coordinates[angle_index_[i]] * kDegPerRad, 4);
    }
    w.end_map();
  }
  if (has(PosePart::translations)) {
    w.key("translations");  // addition: translational coordinates, output units
    w.begin_map(translation_names_.size());
    for (std::size_t i = 0; i < translation_names_.size(); ++i) {
      w.named_key(translation_names_[i].plain, translation_names_[i].json_key);
      w.number(r.coordinates[translation_index_[i]] * scale_);
    }
    w.end_map();
  }
  if (has(PosePart::segments)) {
    w.key("segments");  // addition: anatomical frame (world rotation) and origin per segment
    w.begin_map(segment_names_.size());
    for (std::size_t s = 0; s < segment_names_.size(); ++s) {
      w.named_key(segment_names_[s].plain, segment_names_[s].json_key);
      const Eigen::Quaterniond q = turned_ ? q_out_lab_ * r.segment_q_world[s] : r.segment_q_world[s];
      w.begin_map(2);
      w.key("q");
      w.begin_array(4);
      for (const double v : {q.w(), q.x(), q.y(), q.z()}) w.number(v, 7);
      w.end_array();
      w.key("origin");
      vec(r.segment_origin_world_m[s]);
      w.end_map();
    }
    w.end_map();
  }
  w.key("solver");
  w.begin_map(solver_keys_);
  w.key("status");
  w.string(wire_status(r.solve.status));
  if (has(PosePart::solver_stop)) {
    w.key("stop");  // addition: the solver's own stopping reason
    w.string(to_string(r.solve.status));
  }
  w.key("iterations");
  w.uint(static_cast<std::uint64_t>(r.solve.iterations));
  w.key("solve_us");
  w.number(r.solve_us, 2);
  w.end_map();
  w.end_map();
}

void PoseEncoder::encode(const PoseHeader& header, const TrackResult& result, std::string& out,
                         MeasuredMarkers measured) const {
  if (encoding_ == PayloadEncoding::json) {
    JsonWriter w(out, decimals_);
    write(w, header, result, measured);
  } else {
    MsgpackWriter w(out);
    write(w, header, result, measured);
  }
}

}  // namespace fabrik::wire
