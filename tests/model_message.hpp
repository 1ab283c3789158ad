// What a `model` message must say about the poses of its config
// (proto/model.schema.json): the same names, each exactly once, and bones
// and segments that refer to joints and segments it lists.
#pragma once

#include <catch2/catch.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>

namespace fabrik::test {

// Name -> how many times it appears, from a list of names or of {"name": ...}.
inline std::map<std::string, int> name_counts(const nlohmann::json& list) {
  std::map<std::string, int> n;
  for (const nlohmann::json& e : list)
    ++n[e.is_string() ? e.get<std::string>() : e.at("name").get<std::string>()];
  return n;
}

// Each key of a pose's map, once.
inline std::map<std::string, int> key_counts(const nlohmann::json& map) {
  std::map<std::string, int> n;
  for (const auto& [k, v] : map.items()) n[k] = 1;
  return n;
}

inline void check_model_matches_pose(const nlohmann::json& model, const nlohmann::json& pose) {
  CHECK(model.at("units") == pose.at("units"));
  CHECK(name_counts(model.at("joints")) == key_counts(pose.at("joints")));
  CHECK(name_counts(model.at("segments")) == key_counts(pose.at("segments")));
  CHECK(name_counts(model.at("markers")) == key_counts(pose.at("markers")));
  CHECK(name_counts(model.at("coordinates")) == key_counts(pose.at("angles")));
  const auto joints = name_counts(model.at("joints"));
  const auto segments = name_counts(model.at("segments"));
  // A tree: one bone per segment but the root, joining two listed joints, none twice.
  std::set<std::pair<std::string, std::string>> bones;
  for (const nlohmann::json& b : model.at("bones")) {
    REQUIRE(b.size() == 2);
    CHECK(joints.count(b[0].get<std::string>()) == 1);
    CHECK(joints.count(b[1].get<std::string>()) == 1);
    CHECK(b[0] != b[1]);
    bones.insert(std::make_pair(b[0].get<std::string>(), b[1].get<std::string>()));
  }
  CHECK(bones.size() == model.at("bones").size());
  CHECK(bones.size() + 1 == segments.size());
  // Parents before children; each origin is a joint; one root.
  std::set<std::string> seen;
  int roots = 0;
  for (const nlohmann::json& s : model.at("segments")) {
    INFO("segment " << s.dump());
    if (s.at("parent").is_null())
      ++roots;
    else
      CHECK(seen.count(s.at("parent").get<std::string>()) == 1);
    CHECK(joints.count(s.at("origin").get<std::string>()) == 1);
    seen.insert(s.at("name").get<std::string>());
  }
  CHECK(roots == 1);
  for (const nlohmann::json& m : model.at("markers"))
    CHECK(segments.count(m.at("segment").get<std::string>()) == 1);
  // A range is both bounds or neither, in order.
  for (const nlohmann::json& c : model.at("coordinates")) {
    INFO("coordinate " << c.dump());
    CHECK(c.at("min_deg").is_null() == c.at("max_deg").is_null());
    if (c.at("min_deg").is_number())
      CHECK(c.at("min_deg").get<double>() <= c.at("max_deg").get<double>());
  }
}

}  // namespace fabrik::test
