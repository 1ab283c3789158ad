// The model loader: shipped models load; each kind of bad model is rejected
// with its own message naming the file and JSON pointer.
#include <algorithm>
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "config/config_error.hpp"
#include "config/json_reader.hpp"
#include "config/model_loader.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {
json good() {
  return json::parse(R"({
    "format": "fabrikd-model/1", "name": "t", "units": "mm",
    "segments": [
      {"name": "a", "base": "root", "points": {"j1": [0, 100, 0]}, "markers": {"M1": [10, 50, 0]}},
      {"name": "b", "parent": "a", "base": "j1", "points": {"tip": [0, 100, 0]}}
    ]})");
}

// Loads `doc` and returns the error message (fails the test if it loads).
std::string error_of(const json& doc) {
  try {
    load_model(doc, "bad.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  FAIL("the model loaded but should have been rejected");
  return "";
}
}  // namespace

TEST_CASE("Shipped models load with the expected shape", "[loader]") {
  const Model paper =
      load_model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/paper_upper_body.json");
  CHECK(paper.segments.size() == 6);
  const Segment& trunk = paper.segments[paper.find_segment("trunk")];
  CHECK(trunk.point_count == 3);  // the subbase segment: spine + two shoulders
  CHECK(trunk.child_count == 2);
  const Model body =
      load_model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  CHECK(body.segments.size() >= 12);
  int markers = 0;
  for (const Point& p : body.points) markers += p.kind == PointKind::marker;
  CHECK(markers >= 30);
}

TEST_CASE("Units are converted to metres once, at loading", "[loader]") {
  const Model m = load_model(good(), "t.json");
  CHECK(m.points[m.find_point("j1")].p_local_m.y() == Approx(0.1));
}

TEST_CASE("Each kind of bad model has its own clear message", "[loader]") {
  struct Case {
    const char* what;
    std::function<void(json&)> edit;
    const char* expect_pointer;
    const char* expect_text;
  };
  const std::vector<Case> cases{
      {"missing units", [](json& d) { d.erase("units"); }, "at /units", "'units' is missing"},
      {"bad unit", [](json& d) { d["units"] = "inch"; }, "at /units", "unknown unit 'inch'"},
      {"unknown key", [](json& d) { d["segments"][0]["pionts"] = json::object(); },
       "at /segments/0/pionts", "did you mean 'points'"},
      {"segments not array", [](json& d) { d["segments"] = 3; }, "at /segments",
       "expected an array"},
      {"no segments", [](json& d) { d["segments"] = json::array(); }, "at /segments",
       "no segments"},
      {"duplicate segment", [](json& d) { d["segments"][1]["name"] = "a"; }, "at /segments/1/name",
       "used twice"},
      {"unknown parent", [](json& d) { d["segments"][1]["parent"] = "zz"; },
       "at /segments/1/parent", "unknown parent segment 'zz'"},
      {"two roots", [](json& d) { d["segments"][1].erase("parent"); }, "at /segments/1/parent",
       "two root segments"},
      {"base not in parent", [](json& d) { d["segments"][1]["base"] = "tip0"; },
       "at /segments/1/base", "is not a point of parent segment"},
      {"base is a marker", [](json& d) { d["segments"][1]["base"] = "M1"; }, "at /segments/1/base",
       "is a marker"},
      {"point not a vector",
       [](json& d) {
         d["segments"][0]["points"]["j1"] = json::array({1, 2});
       },
       "at /segments/0/points/j1", "expected [x, y, z]"},
      {"point not a number",
       [](json& d) {
         d["segments"][0]["points"]["j1"] = json::array({1, "x", 2});
       },
       "at /segments/0/points/j1/1", "expected a number"},
      {"duplicate point",
       [](json& d) {
         d["segments"][1]["points"]["M1"] = json::array({0, 1, 0});
       },
       "at /segments/1/points/M1", "used twice"},
      {"no extent",
       [](json& d) {
         d["segments"][1]["points"]["tip"] = json::array({0, 0, 0});
       },
       "at /segments/1/points", "no extent"},
      {"cycle",
       [](json& d) {
         d["segments"][0]["parent"] = "b";
         d["segments"][0]["base"] = "tip";
       },
       "at /segments", "root"},
      {"bad format", [](json& d) { d["format"] = "other/2"; }, "at /format", "unsupported format"},
      {"zero-length bone",
       [](json& d) {
         d["segments"][0]["points"]["j1"] = json::array({0, 0, 0});
       },
       "at /segments/0/points/j1", "joint 'j1' of segment 'a' sits on the segment's base 'root'"},
      {"joint on a root",
       [](json& d) {
         d["segments"][0]["joint"] = {{"type", "hinge"}};
       },
       "at /segments/0/joint", "root segment 'a' has no parent joint"},
      {"unknown joint type",
       [](json& d) {
         d["segments"][1]["joint"] = {{"type", "saddle"}};
       },
       "at /segments/1/joint/type", "unknown joint type 'saddle'"},
      {"range of a held angle",
       [](json& d) {
         d["segments"][1]["joint"] = {{"type", "hinge"}, {"range_deg", {{"x", {-10, 10}}}}};
       },
       "at /segments/1/joint/range_deg/x", "holds its x angle"},
      // Once accepted and ignored: a free joint is never limited.
      {"range of a free joint",
       [](json& d) {
         d["segments"][1]["joint"] = {{"type", "free"}, {"range_deg", {{"z", {-10, 10}}}}};
       },
       "at /segments/1/joint/range_deg", "a free joint is not limited"},
      {"range on a root's free joint",
       [](json& d) {
         d["segments"][0]["joint"] = {{"type", "free"}, {"range_deg", {{"z", {-10, 10}}}}};
       },
       "at /segments/0/joint/range_deg", "a root's joint is free"},
      {"range min above max",
       [](json& d) {
         d["segments"][1]["joint"] = {{"type", "hinge"}, {"range_deg", {{"z", {10, -10}}}}};
       },
       "at /segments/1/joint/range_deg/z", "min is larger than max"},
      {"frame not at right angles",
       [](json& d) {
         d["segments"][1]["frame"] = {{"x", {1, 0, 0}}, {"y", {1, 1, 0}}};
       },
       "at /segments/1/frame", "not at right angles"},
      {"coordinate of an unknown segment",
       [](json& d) {
         d["coordinates"] = {{"flex", {{"segment", "zz"}, {"axis", "z"}}}};
       },
       "at /coordinates/flex/segment", "no segment 'zz'"},
  };
  for (const Case& c : cases) {
    json doc = good();
    c.edit(doc);
    const std::string msg = error_of(doc);
    CAPTURE(c.what, msg);
    CHECK(msg.rfind("bad.json: ", 0) == 0);
    CHECK_THAT(msg, Catch::Contains(c.expect_pointer));
    CHECK_THAT(msg, Catch::Contains(c.expect_text));
    CHECK_THAT(msg, Catch::Contains("Fix: "));
  }
}

TEST_CASE("JSON syntax errors name the line and column", "[loader]") {
  try {
    JsonReader::parse("{\n  \"units\": \"m\",\n  oops\n}", "broken.json");
    FAIL("parsed");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("broken.json"));
    CHECK_THAT(e.what(), Catch::Contains("line 3"));
  }
}

TEST_CASE("A missing model file is a clear error", "[loader]") {
  CHECK_THROWS_WITH(load_model_file("/nonexistent/model.json"), Catch::Contains("cannot open"));
}

namespace {
// A model of `segments` segments, each with `markers` markers: a chain
// (every segment on the previous one) or a star (every one on the first).
json generated(int segments, int markers, bool chain) {
  json segs = json::array();
  for (int s = 0; s < segments; ++s) {
    const std::string id = std::to_string(s);
    json seg = {{"name", "s" + id}, {"base", "b" + id}};
    if (chain || s > 0) seg["points"][chain ? "b" + std::to_string(s + 1) : "tip" + id] = {0, -10, 0};
    if (!chain && s == 0) {
      seg["points"]["end"] = {0, 50, 0};
      for (int t = 1; t < segments; ++t) seg["points"]["b" + std::to_string(t)] = {t % 7 + 1, 0, 0};
    }
    for (int k = 0; k < markers; ++k) seg["markers"]["m" + id + "_" + std::to_string(k)] = {5 + k, -5, 0};
    if (s > 0) seg["parent"] = chain ? "s" + std::to_string(s - 1) : "s0";
    segs.push_back(seg);
  }
  return {{"format", "fabrikd-model/1"}, {"units", "mm"}, {"segments", segs}};
}
}  // namespace

TEST_CASE("A model beyond what a body needs is refused with the limit, its pointer and a fix, "
          "one at the limits loads",
          "[loader][limits]") {
  using L = ModelLimits;
  SECTION("segments") {
    const std::string e = error_of(generated(L::kSegments + 1, 0, false));
    CHECK_THAT(e, Catch::Contains("at /segments/512:") && Catch::Contains("at most 512") &&
                      Catch::Contains("Fix: merge segments"));
  }
  SECTION("depth") {
    const std::string e = error_of(generated(L::kDepth + 1, 0, true));
    CHECK_THAT(e, Catch::Contains("at /segments/64/parent:") &&
                      Catch::Contains(
                          "ends a chain of more than 64 segments from the root (both counted)"));
    // Listed leaf first, the leaf is named.
    json reversed = generated(L::kDepth + 1, 0, true);
    std::reverse(reversed["segments"].begin(), reversed["segments"].end());
    CHECK_THAT(error_of(reversed), Catch::Contains("at /segments/0/parent:") &&
                                       Catch::Contains("segment 's64'"));
  }
  SECTION("points and markers on one segment") {
    json m = generated(1, L::kPointsPerSegment, false);  // one point besides the markers
    CHECK_THAT(error_of(m), Catch::Contains("at /segments/0/markers:") &&
                                Catch::Contains("257 points and markers"));
  }
  SECTION("markers in the model") {
    // 5 segments of 250 markers: the fifth goes over 1024.
    CHECK_THAT(error_of(generated(5, 250, true)),
               Catch::Contains("at /segments/4/markers:") && Catch::Contains("more than 1024"));
  }
  SECTION("coordinates") {
    json m = good();
    for (int c = 0; c <= L::kCoordinates; ++c)
      m["coordinates"]["c" + std::to_string(c)] = {{"segment", "b"}, {"axis", "z"}};
    CHECK_THAT(error_of(m), Catch::Contains("at /coordinates:") &&
                                Catch::Contains("names 1025 coordinates"));
  }
  SECTION("a parent cycle is still named as one, not as depth") {
    json m = generated(3, 0, true);
    m["segments"][0]["parent"] = "s2";
    m["segments"][0]["base"] = "b3";  // a point of s2
    m["segments"].push_back({{"name", "r"}, {"base", "rb"}, {"points", {{"x", {0, 1, 0}}}}});
    CHECK_THAT(error_of(m), Catch::Contains("cycle"));
  }
  SECTION("at every limit at once, it loads") {
    json m = generated(L::kDepth, L::kMarkers / L::kDepth, true);  // 64 deep, 1024 markers
    for (int t = L::kDepth; t < L::kSegments; ++t) {  // leaves along the chain, none deeper
      const std::string id = std::to_string(t);
      const int parent = t % (L::kDepth - 1);
      m["segments"][parent]["points"]["q" + id] = {t % 7 + 1, 1, 0};
      m["segments"].push_back({{"name", "t" + id}, {"parent", "s" + std::to_string(parent)},
                               {"base", "q" + id}, {"points", {{"tip" + id, {0, -10, 0}}}}});
    }
    const Model model = load_model(m, "limits.json");
    CHECK(model.segments.size() == L::kSegments);
  }
}

TEST_CASE("A file with more JSON values than any model or config needs is refused while parsing",
          "[loader][limits]") {
  std::string text = "{\"description\": [";
  for (std::size_t k = 0; k <= kMaxJsonValues; ++k) text += k ? ",0" : "0";
  text += "]}";
  try {
    JsonReader::parse(text, "many.json");
    FAIL("parsed");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("many.json: at /description/") &&
                             Catch::Contains("more than 1048576 values"));
  }
}
