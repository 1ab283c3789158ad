// The daemon config (`fabrikd-config/1`, docs/daemon-config.md and
// proto/daemon-config.schema.json), validated on load: every error names the
// file, the JSON pointer and the fix. Lengths are converted to metres here.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "encoding.hpp"
#include "pose_content.hpp"
#include "pose_views.hpp"
#include "sensors_json.hpp"
#include "source_config.hpp"
#include "topics.hpp"
#include "tracking/tracker.hpp"

namespace fabrik {

enum class SocketMode { bind, connect };

struct Endpoint {
  std::string address;
  SocketMode mode = SocketMode::bind;
  std::string option{};  // the command-line option that gave it ("--input"); empty: the config
};

// One subject of a multi-subject config (`subjects`, docs/daemon-config.md):
// its name on the wire (`Name:Marker`, a frame's "subject", topic pose/Name)
// and the tracking parts of its own calibrated config.
struct SubjectConfig {
  std::string name;
  std::string file;  // the subject's config file, as resolved
  TrackerSetup tracker;
  SensorSection sensors;
};

// A subject's name is a topic suffix (kMaxSubjectNameBytes, topics.hpp) and a marker-name prefix.
constexpr std::size_t kMaxSubjects = 64;

struct DaemonConfig {
  std::string file;  // where it came from ("<embedded>/default.json" for the default)
  std::string description;
  TrackerSetup tracker;
  Endpoint input{"tcp://127.0.0.1:5555", SocketMode::bind};
  Endpoint output{"tcp://127.0.0.1:5556", SocketMode::bind};
  double input_m_per_unit = 1e-3;   // for frames without "units"
  // A QTM or NatNet server read beside the ZeroMQ input (kind none: no source).
  SourceConfig source;
  double output_m_per_unit = 1e-3;  // pose positions and residuals
  std::string output_units = "mm";
  Encoding output_encoding = Encoding::json;
  // Poses also carry `measured`: each visible marker's measured position.
  bool output_measured_markers = false;
  // The pose's optional parts that poses carry (output.pose_content); all by default.
  PoseContent output_pose_content = PoseContent::all();
  // More poses of each frame, on topics of their own (output.views); none by default.
  std::vector<PoseViewConfig> output_views;
  std::size_t max_payload_bytes = 1 << 20;
  // Input coordinates farther than this from the origin on any axis are not
  // plausible measurements: the marker is taken as occluded (and counted).
  double max_abs_coordinate_m = 100.0;
  // An exact (0, 0, 0) is how several exporters write "not seen".
  bool zero_is_missing = true;
  // A sensor quaternion whose length is not 1 within this is an occlusion.
  double quaternion_tolerance = 0.01;
  // The "sensors" section as written (tracker.sensors is made from it).
  SensorSection sensors;
  // Valid frames solved per wake-up at most; older queued ones are dropped.
  int max_backlog_frames = 16;
  double stats_interval_s = 1.0;
  std::string log_level = "info";
  // Several subjects (`subjects`): each with its own tracker and pose; empty:
  // one subject, `tracker` above (as before subjects existed). When not empty,
  // `tracker` and `sensors` are the first subject's.
  std::vector<SubjectConfig> subjects;
  // A subject none of whose markers (at or above its confidence threshold) or
  // sensors was measured for longer than this (frame time) stops getting poses,
  // and starts cold when it is seen again (docs/multi-subject.md).
  double subject_timeout_s = 0.5;
};

// Throws ConfigError. `file` is used in messages and to resolve a relative
// model path; embedded config files (default.json, models/*.json) resolve too.
DaemonConfig load_daemon_config(const std::string& text, const std::string& file);
DaemonConfig load_daemon_config_file(const std::string& path);
// The embedded config/default.json.
DaemonConfig default_daemon_config();

// A subject's targets as its markers arrive once routed to it: a config calibrated from a
// `Subject:Marker` trial (a Vicon C3D) names its targets `Subject:Marker`, while the stream's
// `subject:Marker` reaches subject `subject` as `Marker`. Targets named `subject:X` become `X`
// (others stay). Returns a name two targets would then share ("" when none do); the
// targets are then left as they were.
std::string unprefix_subject_targets(TrackerSetup& tracker, std::string_view subject);

// Behind a vendor source every subject must be in the first subject's lab axes: the source's
// frames are turned into one lab's, so a subject calibrated in others would get positions in a
// frame it does not use. The first subject that is not, with the problem and the fix; nothing
// when all are (or there is no source, or one subject). The loader refuses such a config, and
// the daemon one built in code.
struct SubjectLabProblem {
  std::size_t subject = 0;  // index into DaemonConfig::subjects
  std::string problem, fix;
};
std::optional<SubjectLabProblem> source_lab_problem(const DaemonConfig& c);

}  // namespace fabrik
