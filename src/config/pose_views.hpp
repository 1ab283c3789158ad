// Pose views (output.views): each frame's pose may go out a second time, on a
// topic of its own, with the parts that topic's subscribers want and in the
// encoding they read. A Vicon DataStream or QTM client asks the server for
// the components it wants; over PUB/SUB a subscription is all a client can
// say, so a view is chosen by subscribing to its topic. The daemon encodes a
// view only while a subscription selects it (Daemon, SubscriptionBook).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "encoding.hpp"
#include "json_reader.hpp"
#include "pose_content.hpp"
#include "topics.hpp"
#include "solver/model.hpp"

namespace fabrik {

struct PoseViewConfig {
  std::string topic;                         // multi-subject configs: TOPIC/NAME per subject
  PoseContent content = PoseContent::none();  // the required fields always
  bool measured_markers = false;
  Encoding encoding = Encoding::json;
  std::string units = "mm";  // of positions and translations: "mm" or "m"
  std::optional<LabAxes> axes;  // positions and rotations in these axes; absent: the lab's
};

constexpr std::size_t kMaxPoseViews = 16;

// Whether `topic` may name a view: 1 to kMaxViewTopicBytes letters, digits,
// '_', '-' or '.', and neither a prefix of a topic the daemon has of its own
// (markers, pose, stats, model) nor starting with one (a subscriber of pose
// would receive it too, by prefix).
bool view_topic_ok(std::string_view topic);

// output.views: an array of {topic, pose_content, measured_markers, encoding,
// units, axes}; an absent encoding is `default_encoding` (output.encoding), absent
// units `default_units` (output.units). No topic may be a prefix of
// another's (a subscriber of one would receive both).
std::vector<PoseViewConfig> read_pose_views(const JsonReader& list, Encoding default_encoding,
                                            const std::string& default_units);

}  // namespace fabrik
