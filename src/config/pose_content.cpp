#include "pose_content.hpp"

namespace fabrik {

PoseContent read_pose_content(const JsonReader& value) {
  value.expect_array();
  PoseContent content = PoseContent::none();
  for (std::size_t i = 0; i < value.value().size(); ++i) {
    const JsonReader item = value.at(i);
    const std::string name = item.as_string();
    std::size_t k = 0;
    while (k < kPosePartNames.size() && kPosePartNames[k] != name) ++k;
    if (k == kPosePartNames.size()) {
      std::string names;
      for (std::string_view n : kPosePartNames) names += (names.empty() ? "" : ", ") + std::string(n);
      item.fail("unknown pose part '" + name + "'",
                "use some of: " + names + " (the contract's required fields are always sent)");
    }
    const auto part = static_cast<PosePart>(k);
    if (content.has(part)) item.fail("'" + name + "' is listed twice", "list each part once");
    content = content.with(part);
  }
  return content;
}

}  // namespace fabrik
