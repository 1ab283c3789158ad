// The wire codecs without sockets: marker frames in (JSON and MessagePack),
// poses out, and every kind of bad payload refused with its own message.
#include <catch2/catch.hpp>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "common/ascii_case.hpp"
#include "config/daemon_config.hpp"
#include "daemon_thread.hpp"
#include "model_message.hpp"
#include "transport/fixed_decimals.hpp"
#include "transport/json_sax_reader.hpp"
#include "transport/marker_codec.hpp"
#include "transport/model_codec.hpp"
#include "transport/pose_codec.hpp"
#include "transport/safe_text.hpp"
#include "transport/wire_writer.hpp"

using namespace fabrik;
using namespace fabrik::wire;
using nlohmann::json;

namespace {

std::span<const std::uint8_t> bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}
std::string msgpack(const json& j) {
  const auto v = json::to_msgpack(j);
  return {v.begin(), v.end()};
}

const std::vector<std::string> kNames = {"A", "B", "C"};

// The tracked markers at rest, moved by `offset`, and which are visible: all but `hidden`.
struct Measurements {
  std::vector<Eigen::Vector3d> p_m;
  std::vector<std::uint8_t> visible;
};
Measurements rest_measurements(const Tracker& tracker, const Eigen::Vector3d& offset,
                               const std::vector<std::string>& hidden = {}) {
  const Posture rest = Posture::rest(tracker.model());
  Measurements out;
  for (const MarkerTarget& m : tracker.setup().markers) {
    out.p_m.push_back(rest.point_world_m(tracker.model(), m.point) + offset);
    out.visible.push_back(std::count(hidden.begin(), hidden.end(), m.marker) ? 0 : 1);
  }
  return out;
}

}  // namespace

TEST_CASE(
    "Another subject's unknown names are listed once per subject beside a multi-subject "
    "config's names only",
    "[codec]") {
  const std::vector<std::string> names{"Alice:A", "Alice:B"};
  // Bob's 9 markers, then Carol's one (JSON objects keep their order here: Bob first).
  std::string p = R"({"frame": 1, "markers": {"Alice:A": [1, 2, 3])";
  for (int k = 0; k < 9; ++k) p += R"(, "Bob:M)" + std::to_string(k) + R"(": [1, 2, 3])";
  p += R"(, "Carol:A": [1, 2, 3]}})";
  std::string err;
  for (const bool of_subjects : {false, true}) {
    CAPTURE(of_subjects);
    MarkerDecoder d(names, 1e-3, 1 << 20);
    d.set_of_subjects(of_subjects);
    MarkerFrame f = d.make_frame();
    REQUIRE(d.decode(bytes(p), f, err));
    CHECK(f.unknown_count == 10);
    CHECK(f.unknown_foreign == 10);
    std::vector<std::string> listed(f.unknown_names.begin(),
                                    f.unknown_names.begin() + f.unknown_listed);
    if (of_subjects)  // one name a subject: Carol's is not crowded out by Bob's
      CHECK(listed == std::vector<std::string>{"Bob:M0", "Carol:A"});
    else  // one subject's config with prefixed names: every name, up to the list's 8
      CHECK(listed == std::vector<std::string>{"Bob:M0", "Bob:M1", "Bob:M2", "Bob:M3", "Bob:M4",
                                               "Bob:M5", "Bob:M6", "Bob:M7"});
  }
}

TEST_CASE("A JSON marker frame decodes into metres, in tracker order", "[codec]") {
  MarkerDecoder d(kNames, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string err;
  const std::string p =
      R"({"frame": 1042, "time": 17.366, "stamp_us": 1790000000123456, "units": "mm", "extra": {"a": [1, {"b": null}]},
          "markers": {"C": [1000, 2000, 3000], "A": null, "X": [1, 2, 3]}})";
  REQUIRE(d.decode(bytes(p), f, err));
  CHECK(err.empty());
  CHECK(f.frame == 1042);
  CHECK(f.has_time);
  CHECK(f.time_s == Approx(17.366));
  CHECK(f.has_stamp);
  CHECK(f.stamp_us == 1790000000123456.0);
  CHECK(f.visible == std::vector<std::uint8_t>{0, 0, 1});  // A null, B absent, C given
  CHECK(f.p_world_m[2].isApprox(Eigen::Vector3d(1, 2, 3)));
  CHECK(f.unknown_count == 1);
  REQUIRE(f.unknown_listed == 1);
  CHECK(f.unknown_names[0] == "X");

  // Units default from the config when the frame has none; "m" is taken as is.
  REQUIRE(d.decode(bytes(R"({"frame": 1, "markers": {"A": [1, 2, 3]}})"), f, err));
  CHECK(f.p_world_m[0].isApprox(Eigen::Vector3d(1e-3, 2e-3, 3e-3)));
  CHECK_FALSE(f.has_time);
  REQUIRE(d.decode(bytes(R"({"markers": {"A": [1, 2, 3]}, "units": "m", "frame": 2})"), f, err));
  CHECK(f.p_world_m[0].isApprox(Eigen::Vector3d(1, 2, 3)));
}

TEST_CASE("MessagePack frames decode the same, NaN coordinates are occlusions", "[codec]") {
  MarkerDecoder d(kNames, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string err;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const json j = {{"frame", 7},
                  {"time", 0.5},
                  {"markers", {{"A", {1.5, 2.5, 3.5}}, {"B", {1.0, nan, 2.0}}, {"C", nullptr}}}};
  const std::string p = msgpack(j);
  CHECK(detect_encoding(bytes(p)) == PayloadEncoding::msgpack);
  REQUIRE(d.decode(bytes(p), f, err));
  CHECK(f.frame == 7);
  CHECK(f.visible == std::vector<std::uint8_t>{1, 0, 0});
  CHECK(f.p_world_m[0].isApprox(Eigen::Vector3d(1.5e-3, 2.5e-3, 3.5e-3)));
}

TEST_CASE("encode_marker_frame round-trips through the decoder in both encodings", "[codec]") {
  MarkerDecoder d(kNames, 1.0, 1 << 20);
  const std::vector<Eigen::Vector3d> p = {{0.1, 0.2, 0.3}, {1.0, 2.0, 3.0}, {-0.5, 0.25, 9.0}};
  const std::vector<std::uint8_t> vis = {1, 0, 1};
  for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
    for (std::string units : {"mm", "m"}) {
      std::string out;
      const double t = 1.25;
      encode_marker_frame(99, &t, kNames, p, vis, units, enc, out);
      MarkerFrame f = d.make_frame();
      std::string err;
      REQUIRE(d.decode(bytes(out), f, err));
      CHECK(f.frame == 99);
      CHECK(f.time_s == Approx(1.25));
      CHECK(f.visible == vis);
      CHECK((f.p_world_m[0] - p[0]).norm() < 1e-7);
      CHECK((f.p_world_m[2] - p[2]).norm() < 1e-7);
    }
  }
}

TEST_CASE("A 4th value is a keypoint's confidence, clamped, 1 without one, in both encodings",
          "[codec][confidence]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const bool fast : {true, false}) {
    MarkerDecoder d(kNames, 1e-3, 1 << 20);
    d.set_fast_path(fast);
    MarkerFrame f = d.make_frame();
    std::string err;
    CAPTURE(fast);
    REQUIRE(d.decode(
        bytes(R"({"frame": 1, "markers": {"A": [1, 2, 3, 0.25], "B": [4, 5, 6], "C": [7, 8, 9, 1.5], "X": [1, 2, 3, 0.5]}})"),
        f, err));
    CHECK(f.visible == std::vector<std::uint8_t>{1, 1, 1});
    CHECK(f.confidence == std::vector<float>{0.25f, 1.0f, 1.0f});  // C clamped to 1
    CHECK(f.confidence_count == 2);                                 // X is not a known marker
    CHECK(f.p_world_m[0].isApprox(Eigen::Vector3d(1e-3, 2e-3, 3e-3)));
    // The next frame starts from 1 again: confidence is per frame, not remembered.
    REQUIRE(d.decode(bytes(R"({"frame": 2, "markers": {"A": [1, 2, 3], "B": [1, 1, 1, -0.5]}})"),
                     f, err));
    CHECK(f.confidence == std::vector<float>{1.0f, 0.0f, 1.0f});
    CHECK(f.confidence_count == 1);
  }
  // MessagePack can carry a NaN score: it says nothing, so the marker is occluded.
  MarkerDecoder d(kNames, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string err;
  const json j = {{"frame", 3}, {"markers", {{"A", {1.0, 2.0, 3.0, nan}}, {"B", {1.0, 2.0, 3.0, 0.5}}}}};
  REQUIRE(d.decode(bytes(msgpack(j)), f, err));
  CHECK(f.visible == std::vector<std::uint8_t>{0, 1, 0});
  CHECK(f.confidence[1] == 0.5f);
}

TEST_CASE("encode_marker_frame writes confidences as 4th values that decode back", "[codec][confidence]") {
  MarkerDecoder d(kNames, 1.0, 1 << 20);
  const std::vector<Eigen::Vector3d> p = {{0.1, 0.2, 0.3}, {1.0, 2.0, 3.0}, {-0.5, 0.25, 9.0}};
  const std::vector<std::uint8_t> vis = {1, 0, 1};
  const std::vector<float> confidence = {0.125f, 0.5f, 0.75f};
  for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
    std::string out;
    encode_marker_frame(5, nullptr, kNames, p, vis, "m", enc, out, nullptr, nullptr, confidence);
    MarkerFrame f = d.make_frame();
    std::string err;
    REQUIRE(d.decode(bytes(out), f, err));
    CHECK(f.visible == vis);
    CHECK(f.confidence == std::vector<float>{0.125f, 1.0f, 0.75f});  // B occluded: no value sent
    CHECK(f.confidence_count == 2);
  }
}

TEST_CASE("Every kind of bad marker payload is refused with its own message", "[codec]") {
  MarkerDecoder d(kNames, 1e-3, 4096);
  MarkerFrame f = d.make_frame();
  std::string nested = R"({"frame": 1, "x": )";
  for (int i = 0; i < 100; ++i) nested += "[";
  std::string random_bytes;
  std::mt19937 rng(5);
  for (int i = 0; i < 300; ++i) random_bytes += static_cast<char>(rng() & 0xff);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "empty payload"},
      {"{bad", "not valid JSON"},
      {"[1, 2, 3]", "must be an object"},
      {R"({"markers": {}})", "\"frame\" is missing"},
      {R"({"frame": -3, "markers": {}})", "unsigned integer"},
      {R"({"frame": 1.5, "markers": {}})", "unsigned integer, got a float"},
      {R"({"frame": 18446744073709551616, "markers": {}})",
       "unsigned integer below 2^64, got a larger one"},  // was "got a float"
      {R"({"frame": 1e3, "markers": {}})", "unsigned integer, got a float"},
      {R"({"frame": "12", "markers": {}})", "unsigned integer"},
      {R"({"frame": 1, "time": "now"})", "\"time\" must be a number"},
      {R"({"frame": 1, "stamp_us": [1]})", "\"stamp_us\" must be a number"},
      {R"({"frame": 1, "units": "cm"})", "\"units\" must be \"mm\" or \"m\""},
      {R"({"frame": 1, "markers": [1, 2]})", "\"markers\" must be an object"},
      {R"({"frame": 1, "markers": {"A": [1, 2]}})",
       "expected [x, y, z] or [x, y, z, confidence], got 2"},
      {R"({"frame": 1, "markers": {"A": [1, 2, 3, 4, 5]}})", "more than 4 values"},
      {R"({"frame": 1, "markers": {"A": "here"}})", "must be [x, y, z] or null"},
      {R"({"frame": 1, "markers": {"A": [1, "2", 3]}})", "coordinates must be numbers"},
      {R"({"frame": 1, "markers": {"A": [1, NaN, 3]}})", "not valid JSON"},
      {R"({"frame": 1} trailing)", "not valid JSON"},
      {nested, "nesting deeper"},
      {std::string(5000, ' '), "over the limit of 4096"},
      {std::string("\x83\xa5"
                   "frame\x01",
                   8),
       "not valid MessagePack at byte 9: syntax error while parsing MessagePack string"},
      {std::string("\x93\x01\x02\x03", 4),
       "must be a JSON object or a MessagePack map; the "
       "first byte, 0x93, starts neither"},
      {random_bytes, "not valid"},
  };
  for (const auto& [payload, expected] : cases) {
    std::string err;
    CAPTURE(payload.substr(0, 60));
    CHECK_FALSE(d.decode(bytes(payload), f, err));
    CHECK_THAT(err, Catch::Contains(expected));
    CHECK_THAT(err, !Catch::Contains("json.exception"));  // the library's prefix, not ours
  }
}

TEST_CASE("A pose payload carries the contract's fields, equal in JSON and MessagePack",
          "[codec]") {
  DaemonConfig c = default_daemon_config();
  Tracker tracker(c.tracker);
  const auto [measured, visible] = rest_measurements(tracker, {0.001, 0, 0}, {"RKNE"});
  const TrackResult& r = tracker.track(0.0, measured, visible);
  PoseEncoder je(tracker, "mm", PayloadEncoding::json), me(tracker, "mm", PayloadEncoding::msgpack);
  std::string jp, mp;
  je.encode({12, true, 0.5, true, 1790000000123456.0}, r, jp);
  me.encode({12, true, 0.5, true, 1790000000123456.0}, r, mp);
  const json a = json::parse(jp);
  const json b = json::from_msgpack(mp);
  CHECK(a["frame"] == 12);
  CHECK(a["time"].get<double>() == Approx(0.5));
  CHECK(a["units"] == "mm");
  CHECK(a["stamp_us"].get<double>() == 1790000000123456.0);
  CHECK(a["joints"].size() == tracker.model().joints.size());
  CHECK(a["markers"].size() == c.tracker.markers.size());
  CHECK(a["occluded"] == json::array({"RKNE"}));
  CHECK(a["residual"]["count"] == c.tracker.markers.size() - 1);
  CHECK(a["residual"]["rms"].get<double>() == Approx(r.residual_rms_m * 1e3).margin(1e-3));
  CHECK(a["solver"]["status"].is_string());
  for (const char* key : {"frame", "time", "units", "occluded", "held"}) CHECK(a[key] == b[key]);
  CHECK(b["stamp_us"].get<double>() == 1790000000123456.0);
  for (const auto& [name, p] : a["markers"].items())
    for (int k = 0; k < 3; ++k)
      CHECK(p[k].get<double>() == Approx(b["markers"][name][k].get<double>()).margin(1e-4));
  CHECK(a["gap_s"] == json::object({{"RKNE", 0.0}}));  // never measured: since the first frame
  CHECK(b["gap_s"] == a["gap_s"]);
  const TrackResult& later = tracker.track(0.25, measured, visible);
  je.encode({13, true, 0.75, false, 0.0}, later, jp);
  CHECK(json::parse(jp)["gap_s"]["RKNE"].get<double>() == Approx(0.25));
  CHECK(json::parse(jp)["gap_s"].size() == 1);
  CHECK(wire_status(SolveStatus::stalled) == "converged");
  CHECK(wire_status(SolveStatus::max_iterations) == "max_iterations");
}

TEST_CASE("A frame's time and stamp_us are copied exactly into its pose and by the marker encoder",
          "[codec]") {
  // The contract copies them: fixed decimals would round 1.23456789012 to 1.234568 and 1e-9 to 0.
  DaemonConfig c = default_daemon_config();
  Tracker tracker(c.tracker);
  const auto [measured, visible] = rest_measurements(tracker, {0.001, 0, 0}, {});
  const TrackResult& r = tracker.track(0.0, measured, visible);
  MarkerDecoder d(kNames, 1.0, 1 << 20);
  const std::vector<Eigen::Vector3d> p = {{0.1, 0.2, 0.3}, {1.0, 2.0, 3.0}, {-0.5, 0.25, 9.0}};
  const std::vector<std::uint8_t> vis = {1, 1, 1};
  for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
    PoseEncoder e(tracker, "mm", enc);
    for (const double t_s : {1.23456789012, 1e-9, 2.5e-320, 1700000000.1234567, 0.1, 7.0}) {
      const double stamp_us = 1790000000123456.5 + t_s;
      std::string out;
      e.encode({1, true, t_s, true, stamp_us}, r, out);
      const json pose = enc == PayloadEncoding::json ? json::parse(out) : json::from_msgpack(out);
      CAPTURE(t_s, enc == PayloadEncoding::json, out.substr(0, 80));
      CHECK(pose["time"].get<double>() == t_s);
      CHECK(pose["stamp_us"].get<double>() == stamp_us);
      encode_marker_frame(1, &t_s, kNames, p, vis, "mm", enc, out);
      MarkerFrame f = d.make_frame();
      std::string err;
      REQUIRE(d.decode(bytes(out), f, err));
      CHECK(f.time_s == t_s);
    }
  }
}

TEST_CASE("A pose carries measured only when asked: the visible markers' measurements in its units",
          "[codec][measured]") {
  DaemonConfig c = default_daemon_config();
  Tracker tracker(c.tracker);
  auto [measured, visible] = rest_measurements(tracker, {0.01, 0, 0}, {"RKNE", "LHEE"});
  measured[2] = Eigen::Vector3d(NAN, 0.0, 0.0);  // not finite: not a measurement, though "visible"
  const TrackResult& r = tracker.track(0.0, measured, visible);
  const PoseHeader h{5, true, 0.0, false, 0.0};
  std::string plain, off, on;
  PoseEncoder(tracker, "mm", PayloadEncoding::json).encode(h, r, plain);
  PoseEncoder(tracker, "mm", PayloadEncoding::json, false).encode(h, r, off, {measured, visible});
  CHECK(off == plain);  // off: the pose is byte for byte what it was
  CHECK_FALSE(json::parse(off).contains("measured"));
  for (const char* units : {"mm", "m"})
    for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
      CAPTURE(units, enc == PayloadEncoding::json);
      PoseEncoder(tracker, units, enc, true).encode(h, r, on, {measured, visible});
      const json pose = enc == PayloadEncoding::json ? json::parse(on) : json::from_msgpack(on);
      REQUIRE(pose.contains("measured"));
      const double scale = units == std::string("m") ? 1.0 : 1e3;
      json expected = json::object();
      for (std::size_t i = 0; i < measured.size(); ++i)
        if (visible[i] && measured[i].allFinite()) expected[c.tracker.markers[i].marker] = true;
      CHECK(pose["measured"].size() == expected.size());
      CHECK(expected.size() == c.tracker.markers.size() - 3);
      for (std::size_t i = 0; i < measured.size(); ++i) {
        const std::string& name = c.tracker.markers[i].marker;
        INFO(name);
        REQUIRE(pose["measured"].contains(name) == expected.contains(name));
        if (!expected.contains(name)) continue;
        for (int k = 0; k < 3; ++k)
          CHECK(pose["measured"][name][k].get<double>() ==
                Approx(measured[i][k] * scale).margin(1e-6 * scale));
      }
      // The rest of the pose is unchanged by it.
      json without = pose;
      without.erase("measured");
      const json before = json::parse(plain);
      CHECK(without["markers"].size() == before["markers"].size());
      CHECK(without["occluded"] == before["occluded"]);
    }
}

namespace {

json read_proto(const char* file) {
  std::ifstream in(std::string(FABRIK_SOURCE_DIR) + "/proto/" + file);
  return json::parse(in);
}

// A pose's keys, its residual's and its solver's, as "key", "residual.key", "solver.key".
std::set<std::string> pose_keys(const json& pose) {
  std::set<std::string> keys;
  for (const auto& [k, v] : pose.items()) keys.insert(k);
  for (const char* inner : {"residual", "solver"})
    if (pose.contains(inner))
      for (const auto& [k, v] : pose[inner].items()) keys.insert(std::string(inner) + "." + k);
  return keys;
}

}  // namespace

TEST_CASE("output.pose_content chooses a pose's optional parts, never its required fields",
          "[codec][pose_content]") {
  DaemonConfig c = default_daemon_config();
  Tracker tracker(c.tracker);
  const auto [measured, visible] = rest_measurements(tracker, {0.001, 0, 0}, {"RKNE"});
  const TrackResult& r = tracker.track(0.0, measured, visible);
  const PoseHeader h{7, true, 0.25, true, 1790000000123456.0};
  // What the pose schema requires, read from it: the reduced pose's floor.
  const json schema = read_proto("pose.schema.json");
  std::set<std::string> required = {"time", "stamp_us"};  // the header's echoes, always written
  for (const json& k : schema["required"]) required.insert(k.get<std::string>());
  for (const char* inner : {"residual", "solver"})
    for (const json& k : schema["properties"][inner]["required"])
      required.insert(std::string(inner) + "." + k.get<std::string>());
  // The config schema lists exactly the parts the encoder knows, in its order.
  const json parts = read_proto("daemon-config.schema.json")["properties"]["output"]["properties"]
                                ["pose_content"]["items"]["enum"];
  REQUIRE(parts.size() == kPosePartNames.size());
  for (std::size_t k = 0; k < parts.size(); ++k) CHECK(parts[k] == kPosePartNames[k]);

  for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
    CAPTURE(enc == PayloadEncoding::json);
    const auto parse = [&](const std::string& p) {
      return enc == PayloadEncoding::json ? json::parse(p) : json::from_msgpack(p);
    };
    std::string plain, all, none;
    PoseEncoder(tracker, "mm", enc).encode(h, r, plain);
    PoseEncoder(tracker, "mm", enc, false, PoseContent::all()).encode(h, r, all);
    CHECK(all == plain);  // every part: byte for byte the pose as it was
    const json full = parse(plain);
    std::set<std::string> every = required;
    for (std::string_view p : kPosePartNames) every.insert(std::string(p));
    CHECK(pose_keys(full) == every);
    PoseEncoder(tracker, "mm", enc, false, PoseContent::none()).encode(h, r, none);
    CHECK(pose_keys(parse(none)) == required);
    CHECK(none.size() * 10 < plain.size() * 6);  // segments, angles and the rest are most of it
    // Each part alone: the required fields and that part, as the full pose has it.
    for (std::size_t k = 0; k < kPosePartNames.size(); ++k) {
      const std::string name(kPosePartNames[k]);
      CAPTURE(name);
      std::string one;
      PoseEncoder(tracker, "mm", enc, false, PoseContent::none().with(static_cast<PosePart>(k)))
          .encode(h, r, one);
      const json pose = parse(one);
      std::set<std::string> expected = required;
      expected.insert(name);
      CHECK(pose_keys(pose) == expected);
      std::string path = "/" + name;  // residual.quality: /residual/quality
      std::replace(path.begin(), path.end(), '.', '/');
      const json::json_pointer at(path);
      CHECK(pose[at] == full[at]);
      for (const char* kept : {"joints", "markers", "occluded", "frame"})
        CHECK(pose[kept] == full[kept]);
    }
  }

  // As a config file says it; every mistake names the part and the choices.
  const auto load = [](const std::string& content) {
    return load_daemon_config(
        R"({"format": "fabrikd-config/1", "model": "models/fullbody.json", "output": {"pose_content": )" +
            content + "}}",
        "content.json");
  };
  CHECK(default_daemon_config().output_pose_content == PoseContent::all());
  CHECK(load(R"(["angles"])").output_pose_content ==
        PoseContent::none().with(PosePart::angles));
  CHECK(load("[]").output_pose_content == PoseContent::none());
  CHECK(load(R"(["solver.stop", "segments"])").output_pose_content ==
        PoseContent::none().with(PosePart::segments).with(PosePart::solver_stop));
  CHECK_THROWS_WITH(load(R"(["angles", "joints"])"), Catch::Contains("unknown pose part 'joints'") &&
                                                          Catch::Contains("residual.quality"));
  CHECK_THROWS_WITH(load(R"(["angles", "angles"])"), Catch::Contains("listed twice"));
  CHECK_THROWS_WITH(load(R"("angles")"), Catch::Contains("/output/pose_content"));
}

TEST_CASE("The model message names exactly what the poses name, once, in both encodings",
          "[codec][model]") {
  DaemonConfig c = default_daemon_config();
  // A stream name of its own for one marker, and one model marker not tracked: the message
  // lists the markers the poses carry, not the model's marker points.
  c.tracker.markers.front().marker = "Sub:" + c.tracker.markers.front().marker;
  c.tracker.markers.pop_back();
  // Two orientation sensors too, listed in the message.
  c.tracker.sensors.sensors.push_back({"pelvis_imu", 0, 0, 1.0});
  c.tracker.sensors.sensors.push_back({"torso_imu", 1, 0, 1.0});
  Tracker tracker(c.tracker);
  const auto [measured, visible] = rest_measurements(tracker, Eigen::Vector3d::Zero());
  std::string pose_text;
  PoseEncoder(tracker, "m", PayloadEncoding::json)
      .encode({1, false, 0.0, false, 0.0}, tracker.track(0.0, measured, visible), pose_text);
  const json pose = json::parse(pose_text);
  const json model =
      json::parse(encode_model(c.tracker, "my config.json", "m", PayloadEncoding::json));
  const json packed =
      json::from_msgpack(encode_model(c.tracker, "my config.json", "m", PayloadEncoding::msgpack));
  CHECK(test::largest_difference(packed, model) < 1e-4);  // JSON's numbers have 4 decimals
  test::check_model_matches_pose(model, pose);
  CHECK(model["config"] == "my config.json");
  CHECK(model["lab_axes"] == json::parse(R"({"up": [0, 1, 0], "forward": [1, 0, 0]})"));
  CHECK(model["sensors"] == json::array({"pelvis_imu", "torso_imu"}));
  // The built-in model: its bones, a segment's origin, a marker's segment, ranges.
  const auto has_bone = [&](const char* a, const char* b) {
    return std::count(model["bones"].begin(), model["bones"].end(), json::array({a, b})) == 1;
  };
  CHECK(has_bone("pelvis_origin", "r_hip"));
  CHECK(has_bone("r_hip", "r_knee"));
  CHECK(has_bone("lumbosacral", "neck"));
  const auto entry = [&](const char* list, const std::string& name) {
    for (const json& e : model[list])
      if (e["name"] == name) return e;
    FAIL("no " << name << " in " << list);
    return json();
  };
  CHECK(entry("segments", "r_shank") ==
        json::parse(R"({"name": "r_shank", "parent": "r_thigh", "origin": "r_knee"})"));
  CHECK(entry("segments", "pelvis")["parent"].is_null());
  CHECK(entry("markers", "RKNE")["segment"] == "r_thigh");
  CHECK(entry("coordinates", "knee_angle_r") ==
        json::parse(R"({"name": "knee_angle_r", "min_deg": -140.0, "max_deg": 5.0})"));
  CHECK(entry("coordinates", "pelvis_tilt")["min_deg"].is_null());  // relative to the world
  int ranged = 0;
  for (const json& e : model["coordinates"])
    ranged += e["min_deg"].is_number() && e["min_deg"].get<double>() < e["max_deg"].get<double>();
  CHECK(ranged == static_cast<int>(model["coordinates"].size()) - 3);  // all but the pelvis'
  // A coordinate's sign and offset turn its range (value = sign * (angle + offset)).
  const Model& m = tracker.model();
  Coordinate knee = m.coordinates[m.find_coordinate("knee_angle_r")];
  knee.sign = -1.0;
  knee.offset = 10.0 * 3.141592653589793 / 180.0;
  const auto range = coordinate_range_deg(m, knee);
  REQUIRE(range);
  CHECK(range->first == Approx(-15.0));
  CHECK(range->second == Approx(130.0));
  knee.relative_to = -1;  // the same angle relative to the world: no joint limits it
  CHECK_FALSE(coordinate_range_deg(m, knee));
}

namespace {
// A handler that takes everything: only the reader's own syntax checks decide.
struct AcceptAll {
  bool null() { return true; }
  bool boolean(bool) { return true; }
  bool number_integer(std::int64_t) { return true; }
  bool number_unsigned(std::uint64_t) { return true; }
  bool number_float(double, const std::string&) { return true; }
  bool string(std::string&) { return true; }
  bool start_object(std::size_t) { return true; }
  bool key(std::string&) { return true; }
  bool end_object() { return true; }
  bool start_array(std::size_t) { return true; }
  bool end_array() { return true; }
};
}  // namespace

TEST_CASE("to_fixed_chars writes what to_chars writes with fixed decimals", "[codec][numbers]") {
  const auto both = [](double v, int decimals) {
    char a[400], b[400];  // room for 1e300 in full
    const auto fast = to_fixed_chars(a, a + sizeof a, v, decimals);
    const auto slow = std::to_chars(b, b + sizeof b, v, std::chars_format::fixed, decimals);
    return std::pair{std::string(a, fast.ptr), std::string(b, slow.ptr)};
  };
  // Ties in binary (k/8) round to even, signs of zero and of small negatives stay.
  std::vector<double> edge = {0.0,    -0.0,        0.125,  0.375,   -0.375,   2.5,   3.5,
                              -2.5,   1e-12,       -1e-12, 0.99995, -0.00005, 1e11,  0x1p40,
                              0x1p53, 1.7e15,      1e300,  -1e300,  5e-324,   0.5,   1.5,
                              std::numeric_limits<double>::infinity(),
                              std::numeric_limits<double>::quiet_NaN()};
  for (double v : edge)
    for (int d = 0; d <= 10; ++d) {
      const auto [fast, exact] = both(v, d);
      INFO(v << " with " << d << " decimals");
      CHECK(fast == exact);
    }
  // Random magnitudes from 1e-9 to 1e13; quarters of integers over 10^d
  // (within a rounding of a tie); k / 2^(d+1), exact ties for odd k.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> exponent(-9.0, 13.0), unit(-1.0, 1.0);
  std::uniform_int_distribution<int> decimals(0, 9), quarters(-4000, 4000);
  int mismatches = 0;
  std::string first_mismatch;
  for (int i = 0; i < 400000; ++i) {
    const int d = decimals(rng);
    const double v = i % 4 == 0   ? quarters(rng) / 4.0 / std::pow(10.0, d)
                     : i % 4 == 1 ? std::ldexp(quarters(rng), -(d + 1))
                                  : unit(rng) * std::pow(10.0, exponent(rng));
    const auto [fast, exact] = both(v, d);
    if (fast != exact && mismatches++ == 0) first_mismatch = fast + " != " + exact;
  }
  INFO(first_mismatch);
  CHECK(mismatches == 0);
}

TEST_CASE("JsonWriter writes each number as to_chars does, alone and as a point's triple",
          "[codec][numbers]") {
  // The oracle: fixed decimals where they fit in 64 characters, else the shortest form
  // (what the writer has always written), null for what JSON cannot hold.
  const auto expected = [](double v, int decimals) -> std::string {
    if (!std::isfinite(v)) return "null";
    char b[64];
    auto r = std::to_chars(b, b + sizeof b, v, std::chars_format::fixed, decimals);
    if (r.ec != std::errc()) r = std::to_chars(b, b + sizeof b, v);
    return std::string(b, r.ptr);
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> exponent(-9.0, 60.0), unit(-1.0, 1.0);
  std::vector<double> values = {0.0, -0.0, 0.375, -1e-9, 1e50, -1e59, 1e300,
                                std::numeric_limits<double>::quiet_NaN(),
                                std::numeric_limits<double>::infinity()};
  for (int i = 0; i < 3000; ++i) values.push_back(unit(rng) * std::pow(10.0, exponent(rng)));
  std::string out, reference;
  for (const int decimals : {4, 7}) {
    for (std::size_t i = 0; i + 2 < values.size(); i += 3) {
      const double a = values[i], b = values[i + 1], c = values[i + 2];
      {
        JsonWriter w(out, decimals);
        w.begin_map(2);
        w.key("p");
        w.number_triple(a, b, c);
        w.key("q");
        w.begin_array(2);
        w.number(a);
        w.number_triple(b, c, a);
        w.end_array();
        w.end_map();
      }
      const auto e = [&](double v) { return expected(v, decimals); };
      reference = "{\"p\":[" + e(a) + "," + e(b) + "," + e(c) + "],\"q\":[" + e(a) + ",[" +
                  e(b) + "," + e(c) + "," + e(a) + "]]}";
      CAPTURE(a, b, c, decimals);
      REQUIRE(out == reference);
    }
  }
}

TEST_CASE("JsonWriter's text reads back as what was written, across many growths of its buffer",
          "[codec][json]") {
  // The writer writes through a cursor and grows its buffer a chunk at a time: documents of
  // every size up to many chunks, strings longer than a chunk with every kind of escape,
  // written into a buffer that kept a larger or smaller document's capacity.
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> kind(0, 6), length(0, 3000), byte(1, 127), count(0, 400);
  std::string out;
  for (int doc = 0; doc < 60; ++doc) {
    json expected = json::object();
    {
      JsonWriter w(out, 4);
      const int n = count(rng);
      w.begin_map(static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) {
        std::string key = "k" + std::to_string(i);
        if (i % 7 == 0) key += "\"\\\n\x01";
        w.key(key);
        switch (kind(rng)) {
          case 0: {
            std::string text(static_cast<std::size_t>(length(rng)), ' ');
            for (char& c : text) c = static_cast<char>(byte(rng));
            w.string(text);
            expected[key] = text;
            break;
          }
          case 1:
            w.uint(rng());
            expected[key] = nullptr;  // compared below as an unsigned
            break;
          case 2: {
            const double v = std::ldexp(static_cast<double>(rng() % 2000001) - 1e6, -4);  // exact in 4 decimals
            w.number_triple(v, -v, 2 * v);
            expected[key] = json::array({v, -v, 2 * v});
            break;
          }
          case 3:
            w.null();
            expected[key] = nullptr;
            break;
          case 4:
            w.boolean(i % 2 == 0);
            expected[key] = i % 2 == 0;
            break;
          case 5: {
            w.begin_array(3);
            w.begin_array(0);
            w.end_array();
            w.begin_map(0);
            w.end_map();
            w.number(0.5);
            w.end_array();
            expected[key] = json::array({json::array(), json::object(), 0.5});
            break;
          }
          default:
            w.number(1.25, 2);
            expected[key] = 1.25;
        }
      }
      w.end_map();
    }  // the writer cuts the buffer to what it wrote here
    INFO("document " << doc << ", " << out.size() << " characters");
    const json got = json::parse(out);  // throws (and fails) on any text out of place
    REQUIRE(got.size() == expected.size());
    for (auto it = expected.begin(); it != expected.end(); ++it) {
      INFO("key " << it.key());
      REQUIRE(got.contains(it.key()));
      if (it->is_null() && got[it.key()].is_number_unsigned()) continue;  // the uint case
      CHECK(got[it.key()] == *it);
    }
  }
}

TEST_CASE("The JSON reader accepts exactly what nlohmann::json accepts", "[codec][json]") {
  wire::JsonSaxReader reader;
  AcceptAll all;
  auto agree = [&](const std::string& text) {
    const bool ours = reader.parse(text, all);
    const bool theirs = json::accept(text);
    CAPTURE(text, reader.error());
    CHECK(ours == theirs);
  };
  // Corners of the grammar.
  for (const char* t : {"{}",
                        "[]",
                        "0",
                        "-0",
                        "1.5e3",
                        "1E+2",
                        "-1e-2",
                        "01",
                        "1.",
                        ".5",
                        "+1",
                        "-",
                        "1e",
                        "1e+",
                        "NaN",
                        "Infinity",
                        "-Infinity",
                        "1e400",
                        "-1e400",
                        "1e-400",
                        "18446744073709551616",
                        "-9223372036854775809",
                        "true",
                        "tru",
                        "nul",
                        "\"a\"",
                        "\"\\u00e9\\ud83d\\ude00\"",
                        "\"\\ud83d\"",
                        "\"\\ude00\"",
                        "\"\\ud83dx\"",
                        "\"\\x\"",
                        "\"\\u12\"",
                        "\"tab\there\"",
                        "\"\xc3\xa9\"",
                        "\"\xc3\"",
                        "\"\xed\xa0\x80\"",
                        "\"\xf4\x90\x80\x80\"",
                        "\"\xe0\x80\xaf\"",
                        "\xef\xbb\xbf{}",
                        "{\"a\":1,}",
                        "[1,]",
                        "[1 2]",
                        "{\"a\" 1}",
                        "{1:2}",
                        "{\"a\":1}}",
                        " [ ] ",
                        "[[[[[]]]]]",
                        "{\"a\":[1,{\"b\":null}]}",
                        "",
                        " ",
                        "\"unterminated",
                        "[\"\\/\\b\\f\\n\\r\\t\"]"})
    agree(t);
  // Mutations of a real marker frame: flips, insertions, deletions, truncations.
  const std::vector<Eigen::Vector3d> p = {{0.1, -0.2, 0.3}, {1.0, 2.0, 3.0}, {-0.5, 0.25, 9.0}};
  std::string frame;
  const double t = 0.25;
  encode_marker_frame(7, &t, kNames, p, std::vector<std::uint8_t>{1, 0, 1}, "mm",
                      PayloadEncoding::json, frame);
  std::mt19937 rng(11);
  const std::string alphabet = "{}[]:,\" \\-+.eE0123456789tfnulx\x01\xc3\xa9\xff";
  for (int i = 0; i < 3000; ++i) {
    std::string m = frame;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits && !m.empty(); ++e) {
      const std::size_t at = rng() % m.size();
      switch (rng() % 4) {
        case 0:
          m[at] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          m.insert(at, 1, alphabet[rng() % alphabet.size()]);
          break;
        case 2:
          m.erase(at, 1);
          break;
        default:
          m.resize(at);
          break;
      }
    }
    agree(m);
  }
}

TEST_CASE("safe_text keeps printable UTF-8 and escapes everything else, within its capacity",
          "[codec][safe_text]") {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"plain R.ASIS", "plain R.ASIS"},
      {"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80", "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"},
      {"markers\xff", "markers\\xff"},
      {std::string("nul\0tab\tesc\x1b[31m del\x7f", 21), "nul\\x00tab\\x09esc\\x1b[31m del\\x7f"},
      {"c1 \xc2\x85 nbsp \xc2\xa0", "c1 \\xc2\\x85 nbsp \xc2\xa0"},
      {"overlong \xc0\xaf \xe0\x80\xaf", "overlong \\xc0\\xaf \\xe0\\x80\\xaf"},
      {"surrogate \xed\xa0\x80", "surrogate \\xed\\xa0\\x80"},
      {"too high \xf4\x90\x80\x80", "too high \\xf4\\x90\\x80\\x80"},
      {"cut \xe2\x82", "cut \\xe2\\x82"},
      {"stray \x80\xbf", "stray \\x80\\xbf"},
      {"back\\slash \"quoted\"", "back\\slash \"quoted\""},
  };
  for (const auto& [in, expected] : cases) {
    CAPTURE(in);
    CHECK(wire::safe_text(in) == expected);
    CHECK(wire::safe_text(wire::safe_text(in)) == expected);  // idempotent
  }
  // Bounded: cut at a character boundary, never inside an escape or a sequence.
  const std::string long_text = std::string(300, 'a') + "\xff" + "\xc3\xa9";
  const std::string cut = wire::safe_text(long_text, 64);
  CHECK(cut.size() <= 64);
  CHECK(cut == std::string(61, 'a') + "...");
  CHECK(wire::safe_text(std::string(10, '\x01'), 12) == "\\x01\\x01...");
  CHECK(wire::safe_text("\xc3\xa9\xc3\xa9\xc3\xa9", 6) == "\xc3\xa9\xc3\xa9\xc3\xa9");
  CHECK(wire::safe_text("\xc3\xa9\xc3\xa9\xc3\xa9", 5) == "\xc3\xa9...");
  CHECK(wire::safe_text("abcdef", 6) == "abcdef");  // exactly fits: no ellipsis
  // Any bytes at all come out as valid UTF-8 without control characters.
  std::mt19937 rng(17);
  for (int i = 0; i < 2000; ++i) {
    std::string bytes(rng() % 80, '\0');
    for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
    const std::size_t capacity = 4 + rng() % 100;
    const std::string out = wire::safe_text(bytes, capacity);
    CAPTURE(bytes, capacity);
    REQUIRE(out.size() <= capacity);
    for (char c : out) REQUIRE((static_cast<unsigned char>(c) >= 0x20 && c != 0x7f));
    json j;
    REQUIRE_NOTHROW(j = json::parse("\"" + std::string(out.size(), ' ') + "\""));
    std::string quoted = "\"";
    for (char c : out) quoted += c == '"' || c == '\\' ? std::string("\\") + c : std::string(1, c);
    REQUIRE_NOTHROW(j = json::parse(quoted + "\""));  // nlohmann checks UTF-8
    REQUIRE(j.get<std::string>() == out);
  }
}

TEST_CASE("Markers beyond the plausible range or at exactly (0, 0, 0) are occlusions, counted",
          "[codec]") {
  MarkerFrame f;
  std::string err;
  {
    MarkerDecoder d(kNames, 1e-3, 1 << 20);  // defaults: 100 m, zero is missing
    f = d.make_frame();
    REQUIRE(d.decode(bytes(R"({"frame": 1, "markers": {"A": [1e160, 0, 0], "B": [0, 0, 0],
                                "C": [99999, -99999, 1]}})"),
                     f, err));
    CHECK(f.visible == std::vector<std::uint8_t>{0, 0, 1});
    CHECK(f.rejected_count == 1);
    CHECK(f.zero_count == 1);
    // The range is in metres, whatever the frame's units.
    REQUIRE(d.decode(bytes(R"({"frame": 2, "units": "m", "markers": {"A": [100.5, 0, 1],
                                "B": [-0.0, 0.0, -0.0], "C": [-100, 5e-324, 1]}})"),
                     f, err));
    CHECK(f.visible == std::vector<std::uint8_t>{0, 0, 1});
    CHECK(f.rejected_count == 1);
    CHECK(f.zero_count == 1);
    // A new frame starts its counts afresh.
    REQUIRE(d.decode(bytes(R"({"frame": 3, "markers": {"A": [1, 2, 3]}})"), f, err));
    CHECK(f.rejected_count == 0);
    CHECK(f.zero_count == 0);
  }
  {
    MarkerDecoder d(kNames, 1e-3, 1 << 20, wire::PlausibleMarkers{1.0, false});
    f = d.make_frame();
    REQUIRE(d.decode(bytes(R"({"frame": 1, "markers": {"A": [1001, 0, 0], "B": [0, 0, 0],
                                "C": [999, 0, 0]}})"),
                     f, err));
    CHECK(f.visible == std::vector<std::uint8_t>{0, 1, 1});
    CHECK(f.rejected_count == 1);
    CHECK(f.zero_count == 0);
  }
}

TEST_CASE("Orientations: bad quaternions are occlusions, unknown sensors ignored, both counted",
          "[codec][sensors]") {
  const std::vector<std::string> sensors = {"S0", "S1", "S2", "S3", "S4", "S5", "S6"};
  MarkerDecoder d(kNames, 1e-3, 1 << 20, {}, sensors);
  MarkerFrame f = d.make_frame();
  std::string err;
  const double h = std::sqrt(0.5);
  // S0 good (rounded to 3 digits: within the tolerance), S1 zero, S2 not unit,
  // S3 three numbers, S4 five, S5 null, S6 absent; two unknown names.
  const std::string p = R"({"frame": 3, "markers": {"A": [1, 2, 3]}, "orientations": {
      "S0": [0.707, 0.707, 0, 0], "S1": [0, 0, 0, 0], "S2": [2, 0, 0, 0], "S3": [1, 0, 0],
      "S4": [1, 0, 0, 0, 0], "S5": null, "X": [1, 0, 0, 0], "Y": null}})";
  REQUIRE(d.decode(bytes(p), f, err));
  CHECK(f.sensor_visible == std::vector<std::uint8_t>{1, 0, 0, 0, 0, 0, 0});
  CHECK(f.q_sensor[0].angularDistance(Eigen::Quaterniond(h, h, 0, 0)) < 1e-3);
  CHECK(f.q_sensor[0].norm() == Approx(1.0).margin(1e-12));
  CHECK(f.rejected_orientations == 4);
  CHECK(f.unknown_sensor_count == 2);
  CHECK(f.unknown_sensors_listed == 2);
  CHECK(f.unknown_sensor_names[0] == "X");
  CHECK(f.visible == std::vector<std::uint8_t>{1, 0, 0});
  // NaN and infinity (MessagePack can carry them) are occlusions too.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const json m = {{"frame", 4},
                  {"markers", json::object()},
                  {"orientations",
                   {{"S0", {nan, 0, 0, 1}}, {"S1", {std::numeric_limits<double>::infinity(), 0, 0, 0}},
                    {"S2", {1, 0, 0, 0}}}}};
  REQUIRE(d.decode(bytes(msgpack(m)), f, err));
  CHECK(f.sensor_visible == std::vector<std::uint8_t>{0, 0, 1, 0, 0, 0, 0});
  CHECK(f.rejected_orientations == 2);
  // A component that is not a number, or orientations that are not an object, are errors.
  CHECK_FALSE(d.decode(bytes(R"({"frame": 5, "orientations": {"S0": [1, "a", 0, 0]}})"), f, err));
  CHECK_THAT(err, Catch::Contains("S0"));
  CHECK_FALSE(d.decode(bytes(R"({"frame": 5, "orientations": [1, 0, 0, 0]})"), f, err));
  CHECK_THAT(err, Catch::Contains("orientations"));
  // What encode_marker_frame writes decodes back.
  const std::vector<Eigen::Quaterniond> q(sensors.size(), Eigen::Quaterniond(h, 0, h, 0));
  std::vector<std::uint8_t> seen(sensors.size(), 1);
  seen[2] = 0;
  const SensorSamples samples{sensors, q, seen};
  const std::vector<Eigen::Vector3d> p_m(kNames.size(), Eigen::Vector3d(0.1, 0.2, 0.3));
  const std::vector<std::uint8_t> visible(kNames.size(), 1);
  std::string out;
  for (auto enc : {PayloadEncoding::json, PayloadEncoding::msgpack}) {
    encode_marker_frame(9, nullptr, kNames, p_m, visible, "mm", enc, out, nullptr, &samples);
    REQUIRE(d.decode(bytes(out), f, err));
    CHECK(f.sensor_visible == seen);
    CHECK(f.q_sensor[0].angularDistance(q[0]) < 1e-8);
    CHECK(f.rejected_orientations == 0);
  }
}

TEST_CASE("ASCII case folding: any case of a name compares equal, other bytes as they are",
          "[common]") {
  CHECK(ascii_lower("LocalHost.TRC") == "localhost.trc");
  CHECK(ascii_lower("R_ASIS-2") == "r_asis-2");
  CHECK(ascii_lower("\xc3\x89t\xc3\xa9") == "\xc3\x89t\xc3\xa9");  // UTF-8 bytes kept
  CHECK(iequals("LOCALHOST", "localhost"));
  CHECK(iequals("", ""));
  CHECK_FALSE(iequals("localhost", "localhost."));
  CHECK_FALSE(iequals("all", "alm"));
}
