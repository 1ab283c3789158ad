#include "pose_views.hpp"

#include <algorithm>
#include <cctype>
#include <iterator>

#include "lab_axes_json.hpp"
#include "model_loader.hpp"
#include "topics.hpp"

namespace fabrik {

bool view_topic_ok(std::string_view topic) {
  if (topic.empty() || topic.size() > kMaxViewTopicBytes) return false;
  const bool chars_ok = std::all_of(topic.begin(), topic.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.';
  });
  // The daemon's own topics, in and out: a view may not collide with them by prefix.
  const auto collides = [&](std::string_view own) {
    return own.starts_with(topic) || topic.starts_with(own);
  };
  return chars_ok && !collides(kMarkersTopic) &&
         std::none_of(std::begin(kPublishedTopics), std::end(kPublishedTopics), collides);
}

std::vector<PoseViewConfig> read_pose_views(const JsonReader& list, Encoding default_encoding,
                                            const std::string& default_units) {
  list.expect_array();
  const std::size_t n = list.value().size();
  if (n > kMaxPoseViews)
    list.fail("output.views lists " + std::to_string(n) + " views",
              "list at most " + std::to_string(kMaxPoseViews) + " views");
  std::vector<PoseViewConfig> views;
  for (std::size_t i = 0; i < n; ++i) {
    const JsonReader e = list.at(i);
    e.only_keys({"topic", "pose_content", "measured_markers", "encoding", "units", "axes"});
    PoseViewConfig v;
    v.topic = e.at("topic").as_string();
    if (!view_topic_ok(v.topic))
      e.at("topic").fail("view topic '" + v.topic + "' cannot be used",
                         "use 1 to " + std::to_string(kMaxViewTopicBytes) +
                             " letters, digits, '_', '-' or '.', not starting like markers, pose, "
                             "stats or model (a subscriber of those would receive it too), "
                             "e.g. \"joints\"");
    for (const PoseViewConfig& other : views)
      if (other.topic.starts_with(v.topic) || v.topic.starts_with(other.topic))
        e.at("topic").fail("view topic '" + v.topic + "' and '" + other.topic +
                               "' start alike: a subscriber of one would receive both",
                           "give each view a topic that is not the start of another's");
    if (e.has("pose_content")) v.content = read_pose_content(e.at("pose_content"));
    v.measured_markers = e.get("measured_markers", false);
    v.encoding = e.has("encoding")
                     ? read_choice<Encoding>(e.at("encoding"), "encoding",
                                             {{"json", Encoding::json}, {"msgpack", Encoding::msgpack}})
                     : default_encoding;
    v.units = default_units;
    if (e.has("units")) {
      (void)metres_per_unit(e.at("units"));  // refuses any other unit, with the fix
      v.units = e.at("units").as_string();
    }
    if (e.has("axes"))
      v.axes = read_whole_lab_axes(e.at("axes"), "the view's up axis is x and no forward axis is given",
                                   "add \"forward\": \"+y\" or \"+z\" (the view's axis pointing forward)");
    views.push_back(std::move(v));
  }
  return views;
}

}  // namespace fabrik
