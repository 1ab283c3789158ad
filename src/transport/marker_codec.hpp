// The `markers` payload of the wire contract (proto/markers.schema.json):
// decoding into the tracker's marker order, and encoding (for replay tools,
// benchmarks and tests). Decoding is a SAX pass over JSON or MessagePack
// (told apart by the first byte) straight into preallocated arrays, so a bad
// payload is rejected at the first wrong token and nesting is bounded. A
// payload of the common shape takes a faster path first (marker_json_fast.hpp,
// marker_msgpack_fast.hpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "json_sax_reader.hpp"
#include "marker_name_index.hpp"

namespace fabrik::wire {

enum class PayloadEncoding { json, msgpack };

// MessagePack when the first byte starts a MessagePack map, else JSON.
PayloadEncoding detect_encoding(std::span<const std::uint8_t> payload);

struct MarkerFrame {
  std::uint64_t frame = 0;
  bool has_time = false;
  double time_s = 0.0;
  // Addition to the contract: the source's wall clock at sending (Unix
  // microseconds), echoed in the pose so a client can measure end-to-end latency.
  bool has_stamp = false;
  double stamp_us = 0.0;
  std::vector<Eigen::Vector3d> p_world_m;  // per known marker, metres
  std::vector<std::uint8_t> visible;       // per known marker
  // Addition to the contract: per known marker, the confidence a markerless
  // source gave as a 4th value ([x, y, z, c], clamped to [0, 1]); 1 without one.
  std::vector<float> confidence;
  int confidence_count = 0;  // known markers that carried a confidence
  int rejected_count = 0;  // known markers beyond the plausible range: taken as occluded
  int zero_count = 0;      // known markers at exactly (0, 0, 0): taken as occluded
  int known_count = 0;                     // marker names of the config (null ones included)
  int unknown_count = 0;                   // marker names not in the model
  std::vector<std::string> unknown_names;  // unknown_listed of them (cut), for the log
  int unknown_listed = 0;
  // Set by the reader before a decode, kept by it: the list starts after this many unknown
  // names (the daemon moves it on frame by frame, so that a stream's every unknown name is
  // listed in time, not only its first few).
  int unknown_skip = 0;
  // Unknown names "X:..." where no config name starts "X:": another subject's markers (in a
  // split across processes). All of a frame's, not only the listed ones.
  int unknown_foreign = 0;
  // Addition to the contract, "orientations": per known sensor, its frame's
  // rotation in the sensors' world (normalised) and whether it was measured.
  std::vector<Eigen::Quaterniond> q_sensor;
  std::vector<std::uint8_t> sensor_visible;
  // Known sensors whose value was not a usable quaternion (wrong length, not
  // finite, not unit within the tolerance): taken as occluded.
  int rejected_orientations = 0;
  int unknown_sensor_count = 0;                   // sensor names not in the config
  std::vector<std::string> unknown_sensor_names;  // the first unknown_sensors_listed (cut)
  int unknown_sensors_listed = 0;
  // Addition to the contract, "subject": whose markers the frame's bare
  // names are (multi-subject configs; docs/multi-subject.md). Cut to its
  // reserved capacity (kMaxSubjectBytes), so reading it never allocates.
  bool has_subject = false;
  std::string subject;
};
constexpr std::size_t kMaxSubjectBytes = 64;
// Sets `subject` (cut to kMaxSubjectBytes: a longer one matches no subject).
inline void set_frame_subject(MarkerFrame& f, std::string_view subject) {
  f.has_subject = true;
  f.subject.assign(subject.substr(0, std::min(subject.size(), kMaxSubjectBytes)));
}

// What a measured position must be to count as seen.
struct PlausibleMarkers {
  // A coordinate beyond this (metres, either sign) is an occlusion: nothing
  // a capture volume measures is that far, and squaring it would overflow.
  double max_abs_coordinate_m = 100.0;
  // An exact (0, 0, 0) is an occlusion (exporters write it for "not seen").
  bool zero_is_missing = true;
  // An orientation whose quaternion's length differs from 1 by more than
  // this is an occlusion (a zero or garbage quaternion, not a rounded one).
  double quaternion_tolerance = 0.01;
};

class MarkerDecoder {
 public:
  // `names`: the marker names in tracker order, `sensor_names` the orientation
  // sensors' names in tracker order. Frames without "units" are in
  // `default_m_per_unit`. Larger payloads than `max_payload_bytes` are errors.
  MarkerDecoder(std::span<const std::string> names, double default_m_per_unit,
                std::size_t max_payload_bytes, PlausibleMarkers plausible = {},
                std::span<const std::string> sensor_names = {});

  // A frame sized for this decoder's markers.
  MarkerFrame make_frame() const;
  // Fills `out` and returns true, or returns false with `error` saying why.
  // Not thread-safe (the JSON reader's buffers are reused).
  bool decode(std::span<const std::uint8_t> payload, MarkerFrame& out, std::string& error) const;
  int index_of(const std::string& name) const;

  // The names are a multi-subject config's: see MarkerNameIndex::of_subjects.
  void set_of_subjects(bool on) { index_.set_of_subjects(on); }

  // Off: every payload goes through the full reader (tests compare the two).
  void set_fast_path(bool on) { fast_path_ = on, fast_skip_ = 0; }
  // Payloads a fast path (JSON or MessagePack) decoded, not declined, since construction.
  std::uint64_t fast_path_frames() const { return fast_frames_; }

 private:
  mutable MarkerNameIndex index_;  // its previous-frame hints change as frames arrive
  MarkerNameIndex sensor_index_;
  int count_, sensor_count_;
  double default_m_per_unit_;
  std::size_t max_payload_bytes_;
  PlausibleMarkers plausible_;
  // Its buffers are reused from frame to frame: one decoder per thread.
  mutable JsonSaxReader json_reader_;
  mutable std::string marker_name_;  // the marker being read, for messages
  bool fast_path_ = true;
  mutable std::uint64_t fast_frames_ = 0;
  // After a declined payload the next ones skip the fast path for a while: a
  // source whose frames always decline (e.g. with orientations) pays for the
  // wasted scan once in kFastPathPause frames, not on every frame.
  static constexpr int kFastPathPause = 16;
  mutable int fast_skip_ = 0;
};

// A `markers` payload: names[i] at p[i] in `units` ("mm" or "m"; positions are
// given in metres and converted here), null where visible[i] is 0 or the
// position is not finite; with `confidence` (one per name), each visible marker
// as [x, y, z, confidence].
// Orientation sensors for a frame: names[k] at q[k] ([w, x, y, z]), null
// where visible[k] is 0 or the quaternion is not finite.
struct SensorSamples {
  std::span<const std::string> names;
  std::span<const Eigen::Quaterniond> q;
  std::span<const std::uint8_t> visible;
};

// `stamp_us`, if given, is written as the frame's stamp_us; `sensors`, if
// given, as its "orientations".
void encode_marker_frame(std::uint64_t frame, const double* time_s,
                         std::span<const std::string> names,
                         std::span<const Eigen::Vector3d> p_world_m,
                         std::span<const std::uint8_t> visible, std::string_view units,
                         PayloadEncoding encoding, std::string& out,
                         const double* stamp_us = nullptr, const SensorSamples* sensors = nullptr,
                         std::span<const float> confidence = {});

}  // namespace fabrik::wire
