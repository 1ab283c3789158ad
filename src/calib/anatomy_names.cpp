#include "anatomy_names.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <set>

#include "common/ascii_case.hpp"

namespace fabrik::calib {

namespace {

bool upper_or_digit(char c) {
  return std::isupper(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c));
}

bool is_separator(char c) {
  return c == '_' || c == '.' || c == '-' || c == ' ';
}

bool starts_with_ci(const std::string& s, const std::string& prefix) {
  return s.size() > prefix.size() && ascii_lower(s.substr(0, prefix.size())) == prefix;
}
bool ends_with_ci(const std::string& s, const std::string& suffix) {
  return s.size() > suffix.size() && ascii_lower(s.substr(s.size() - suffix.size())) == suffix;
}

}  // namespace

std::vector<SideReading> side_readings(const std::string& n) {
  std::vector<SideReading> out;
  if (n.size() < 2) return out;
  // "Right"/"Left" as a word before or after the stem: RightThigh, thigh_left.
  for (const auto& [word, side] : {std::pair<std::string, BodySide>{"right", BodySide::right},
                                   {"left", BodySide::left}}) {
    if (starts_with_ci(n, word)) {
      std::string rest = n.substr(word.size());
      if (is_separator(rest[0])) rest.erase(0, 1);
      if (!rest.empty()) out.push_back({"word<" + ascii_lower(rest), rest, side, true});
    }
    if (ends_with_ci(n, word)) {
      std::string head = n.substr(0, n.size() - word.size());
      if (!head.empty() && is_separator(head.back())) head.pop_back();
      if (!head.empty()) out.push_back({"word>" + ascii_lower(head), head, side, true});
    }
  }
  const char first = ascii_lower(n[0]);
  const char last = ascii_lower(n.back());
  // A one-letter token with a separator: r_thigh, R.ASIS, thigh_l.
  if ((first == 'r' || first == 'l') && is_separator(n[1]) && n.size() > 2)
    out.push_back({std::string("pre") + n[1] + n.substr(2), n.substr(2),
                   first == 'r' ? BodySide::right : BodySide::left, true});
  if ((last == 'r' || last == 'l') && n.size() > 2 && is_separator(n[n.size() - 2]))
    out.push_back({std::string("suf") + n[n.size() - 2] + n.substr(0, n.size() - 2),
                   n.substr(0, n.size() - 2), last == 'r' ? BodySide::right : BodySide::left,
                   true});
  // Vicon's bare prefix: RASI, LTH1, RFAsuperior. A side only with its mirror.
  if ((n[0] == 'R' || n[0] == 'L') && n.size() >= 3 && upper_or_digit(n[1]))
    out.push_back(
        {"bare" + n.substr(1), n.substr(1), n[0] == 'R' ? BodySide::right : BodySide::left, false});
  return out;
}

std::vector<std::pair<int, int>> mirrored_pairs(const std::vector<std::string>& names) {
  std::map<std::string, std::pair<int, int>> by_key;  // key -> (right, left)
  for (int i = 0; i < static_cast<int>(names.size()); ++i)
    for (const SideReading& r : side_readings(names[i])) {
      auto& [right, left] = by_key.try_emplace(r.key, -1, -1).first->second;
      (r.side == BodySide::right ? right : left) = i;
    }
  std::set<std::pair<int, int>> pairs;
  for (const auto& [key, p] : by_key)
    if (p.first >= 0 && p.second >= 0 && p.first != p.second) pairs.insert(p);
  return {pairs.begin(), pairs.end()};
}

std::vector<BodySide> sides_of(const std::vector<std::string>& names) {
  std::vector<BodySide> out(names.size(), BodySide::none);
  for (std::size_t i = 0; i < names.size(); ++i)
    for (const SideReading& r : side_readings(names[i]))
      if (r.explicit_token) out[i] = r.side;
  for (const auto& [right, left] : mirrored_pairs(names)) {
    if (out[right] == BodySide::none) out[right] = BodySide::right;
    if (out[left] == BodySide::none) out[left] = BodySide::left;
  }
  return out;
}

BodyPart body_part(const std::string& name) {
  static const std::map<std::string, BodyPart> parts = {
      {"pelvis", BodyPart::pelvis},         {"pelvic", BodyPart::pelvis},
      {"hips", BodyPart::pelvis},           {"thigh", BodyPart::thigh},
      {"femur", BodyPart::thigh},           {"upperleg", BodyPart::thigh},
      {"shank", BodyPart::shank},           {"tibia", BodyPart::shank},
      {"shin", BodyPart::shank},            {"lowerleg", BodyPart::shank},
      {"leg", BodyPart::shank},             {"calf", BodyPart::shank},
      {"foot", BodyPart::foot},             {"hindfoot", BodyPart::foot},
      {"rearfoot", BodyPart::foot},         {"calcn", BodyPart::foot},
      {"calcaneus", BodyPart::foot},        {"talus", BodyPart::foot},
      {"forefoot", BodyPart::forefoot},     {"midfoot", BodyPart::forefoot},
      {"metatarsals", BodyPart::forefoot},  {"toes", BodyPart::toes},
      {"toe", BodyPart::toes},              {"hallux", BodyPart::toes},
      {"trunk", BodyPart::trunk},           {"torso", BodyPart::trunk},
      {"thorax", BodyPart::trunk},          {"chest", BodyPart::trunk},
      {"abdomen", BodyPart::trunk},         {"lumbar", BodyPart::trunk},
      {"spine", BodyPart::trunk},           {"back", BodyPart::trunk},
      {"head", BodyPart::head},             {"skull", BodyPart::head},
      {"neck", BodyPart::head},             {"clavicle", BodyPart::shoulder_girdle},
      {"scapula", BodyPart::shoulder_girdle}, {"shoulder", BodyPart::shoulder_girdle},
      {"humerus", BodyPart::upper_arm},     {"upperarm", BodyPart::upper_arm},
      {"arm", BodyPart::upper_arm},         {"forearm", BodyPart::forearm},
      {"lowerarm", BodyPart::forearm},      {"ulna", BodyPart::forearm},
      {"radius", BodyPart::forearm},        {"hand", BodyPart::hand},
  };
  // The whole name first (LUMBAR is no left UMBAR), then without its side
  // token; lower case, separators dropped.
  std::vector<std::string> candidates{name};
  for (const SideReading& r : side_readings(name)) candidates.push_back(r.stem);
  for (const std::string& c : candidates) {
    std::string s;
    for (char ch : ascii_lower(c))
      if (!is_separator(ch)) s += ch;
    if (const auto it = parts.find(s); it != parts.end()) return it->second;
  }
  return BodyPart::unknown;
}

bool is_limb(BodyPart p) {
  switch (p) {
    case BodyPart::thigh:
    case BodyPart::shank:
    case BodyPart::foot:
    case BodyPart::forefoot:
    case BodyPart::toes:
    case BodyPart::shoulder_girdle:
    case BodyPart::upper_arm:
    case BodyPart::forearm:
    case BodyPart::hand:
      return true;
    default:
      return false;
  }
}

bool takes_parent_frame(BodyPart p) {
  return p == BodyPart::foot || p == BodyPart::forefoot || p == BodyPart::toes;
}

JointCoordinateNames opensim_names(BodyPart p) {
  switch (p) {
    case BodyPart::pelvis:
      return {"pelvis_tilt", "pelvis_list", "pelvis_rotation"};
    case BodyPart::thigh:
      return {"hip_flexion", "hip_adduction", "hip_rotation"};
    case BodyPart::shank:
      return {"knee_angle", "", ""};
    case BodyPart::foot:
      return {"ankle_angle", "subtalar_angle", ""};
    case BodyPart::toes:
      return {"mtp_angle", "", ""};
    case BodyPart::trunk:
      return {"lumbar_extension", "lumbar_bending", "lumbar_rotation"};
    case BodyPart::head:
      return {"neck_extension", "neck_bending", "neck_rotation"};
    case BodyPart::upper_arm:
      return {"arm_flex", "arm_add", "arm_rot"};
    case BodyPart::forearm:
      return {"elbow_flex", "", "pro_sup"};
    case BodyPart::hand:
      return {"wrist_flex", "wrist_dev", ""};
    default:
      return {};
  }
}

}  // namespace fabrik::calib
