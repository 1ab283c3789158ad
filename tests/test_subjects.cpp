// Several subjects tracked by one daemon (docs/multi-subject.md): config,
// routing by `Subject:Marker` names and by a frame's "subject", a pose per
// subject on pose/NAME, appearing and disappearing subjects, topic selection
// by subscription. Over real (inproc) ZeroMQ sockets; every wait is bounded.
#include <catch2/catch.hpp>
#include <chrono>
#include <fstream>
#include <functional>
#include <map>
#include <set>

#include "config/config_error.hpp"
#include "config/resources.hpp"
#include "daemon_thread.hpp"
#include "log_capture.hpp"
#include "socket_client.hpp"
#include "subjects_fixture.hpp"
#include "transport/name_mismatch.hpp"

using namespace fabrik;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

zmq::context_t& zmq_context() {
  static zmq::context_t context;
  return context;
}

DaemonConfig on_inproc(DaemonConfig c, const std::string& tag) {
  c.input = {"inproc://subjects-in-" + tag, SocketMode::bind};
  c.output = {"inproc://subjects-out-" + tag, SocketMode::bind};
  c.stats_interval_s = 0.05;
  spdlog::set_level(spdlog::level::err);
  return c;
}

// The markers of subjects `names` (subject k at subject_offset_m(k)), named NAME:Marker.
json both_markers(const DaemonConfig& c, SyntheticMotion& motion, double t_s,
                  const std::vector<std::string>& names, const std::vector<int>& present) {
  json markers = json::object();
  for (int k : present)
    markers = test::subject_markers(c.subjects[k].tracker, motion, t_s, test::subject_offset_m(k),
                                    names[k] + ":", markers);
  return markers;
}

// Sends frames with Alice's markers until her pose comes back, then drains.
// Returns the next frame number to use.
std::uint64_t handshake(test::SocketClient& client, const DaemonConfig& c, SyntheticMotion& motion) {
  for (int i = 0; i < 600; ++i) {
    client.send(json{{"frame", 1000000 + i},
                     {"markers", test::subject_markers(c.subjects[0].tracker, motion, 0.0,
                                                       test::subject_offset_m(0),
                                                       c.subjects[0].name + ":")}}
                    .dump());
    const std::string topic = "pose/" + c.subjects[0].name;
    if (const auto pose = client.receive(topic, 50ms)) {
      // The answers to probes still in flight: up to the last one sent.
      const std::uint64_t last = 1000000 + static_cast<std::uint64_t>(i);
      if ((*pose)["frame"] != last)
        REQUIRE(client.receive_until(
            topic, [last](const json& p) { return p["frame"] == last; }, 5s));
      return 2000000;
    }
  }
  FAIL("no pose/" << c.subjects[0].name << " came back in 600 probes");
  return 0;
}

// Waits (bounded) until the daemon has counted `frames_in` frames.
bool counted(const wire::Daemon& d, std::uint64_t frames_in) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < deadline) {
    if (d.counters().frames_in >= frames_in) return true;
    std::this_thread::yield();
  }
  return false;
}

// Alice and Bob (the built-in full-body model each) in a daemon on a thread,
// a client connected both ways and past its handshake, the motion that makes
// their markers. `extra`: more top-level config keys.
struct AliceAndBob {
  AliceAndBob(const std::string& tag, const json& extra = json::object())
      : d(zmq_context(), on_inproc(load_daemon_config_file(dir.write(names, extra)), tag)),
        c(d.daemon.config()),
        client(zmq_context(), d.daemon.input_endpoint(), d.daemon.output_endpoint()),
        motion(*c.subjects[0].tracker.model, MotionSettings{}),
        first(handshake(client, c, motion)) {}
  test::SubjectsDir dir;
  const std::vector<std::string> names{"Alice", "Bob"};
  test::DaemonThread d;
  const DaemonConfig& c;
  test::SocketClient client;
  SyntheticMotion motion;
  const std::uint64_t first;
};

double distance_mm(const json& a, const json& b) {
  const Eigen::Vector3d x(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
  const Eigen::Vector3d y(b[0].get<double>(), b[1].get<double>(), b[2].get<double>());
  return (x - y).norm();
}

}  // namespace

TEST_CASE("A daemon config lists subjects, each from its own calibrated config", "[subjects]") {
  test::SubjectsDir dir;
  const DaemonConfig c = load_daemon_config_file(dir.write({"Alice", "Bob"}, {{"subject_timeout_s", 0.25}}));
  REQUIRE(c.subjects.size() == 2);
  CHECK(c.subjects[0].name == "Alice");
  CHECK(c.subjects[1].name == "Bob");
  CHECK(c.subject_timeout_s == 0.25);
  const DaemonConfig one = default_daemon_config();
  CHECK(one.subjects.empty());
  CHECK(c.subjects[1].tracker.markers.size() == one.tracker.markers.size());
  CHECK(DaemonConfig{}.subject_timeout_s == 0.5);  // the documented default
  // Names that cannot be a topic suffix or a marker prefix, twice the same, and
  // tracking parts at the top level are refused.
  for (const json& bad :
       {json{{"subjects", {{{"name", "A:B"}, {"config", "Alice.json"}}}}},
        json{{"subjects", {{{"name", "A/B"}, {"config", "Alice.json"}}}}},
        json{{"subjects", {{{"name", "Alice"}, {"config", "Alice.json"}},
                           {{"name", "Alice"}, {"config", "Alice.json"}}}}},
        json{{"subjects", json::array()}},
        json{{"model", "models/fullbody.json"}},
        json{{"subjects", {{{"name", "Eve"}, {"config", "missing.json"}}}}}}) {
    CAPTURE(bad.dump());
    CHECK_THROWS_AS(load_daemon_config_file(dir.write({"Alice"}, bad)), ConfigError);
  }
  // Names that start alike: a subscriber of pose/Alice would receive pose/Alice2 too.
  for (const auto& [first, second] : {std::pair{"Alice", "Alice2"}, std::pair{"P12", "P1"}}) {
    CAPTURE(first, second);
    CHECK_THROWS_WITH(
        load_daemon_config_file(dir.write({first, second})),
        Catch::Contains(std::string("subjects '") + first + "' and '" + second +
                        "' start alike: a subscriber of pose/" +
                        (std::string(first).size() < std::string(second).size() ? first : second) +
                        " would receive both subjects' poses") &&
            Catch::Contains("not the start of another's"));
  }
}

TEST_CASE("Behind a vendor source, every subject is in one lab's axes", "[subjects][lab_axes]") {
  // The source's frames are turned into the first subject's lab axes: a subject calibrated
  // with Z up beside one with Y up got positions in a frame it does not use, without a word.
  test::SubjectsDir dir;
  json z_up = json::parse(*embedded_config("models/fullbody.json"));
  z_up["lab_axes"] = {{"up", "+z"}, {"forward", "+x"}};
  const std::string daemon = dir.write({"Alice", "Bob"});  // both Y up, the model's own
  dir.write_file("Bob.json", {{"format", "fabrikd-config/1"}, {"model", z_up}});
  const json source = {{"source", "qtm://127.0.0.1"}};
  const json config = json::parse(std::ifstream(daemon));
  json with_source = config;
  with_source["input"] = source;
  const std::string error = [&] {
    try {
      load_daemon_config(with_source.dump(), daemon);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  }();
  CHECK_THAT(error, Catch::Contains("at /subjects/1/config: subject Bob's lab axes "
                                    "{\"up\":\"+z\",\"forward\":\"+x\"}") &&
                        Catch::Contains("are not subject Alice's") &&
                        Catch::Contains("Fix: calibrate every subject in the lab's axes"));
  // Without a source the frames come in the lab's own axes: each subject's angles are its own.
  CHECK(load_daemon_config(config.dump(), daemon).subjects.size() == 2);
  // Both in Z up: one lab.
  dir.write_file("Alice.json", {{"format", "fabrikd-config/1"}, {"model", z_up}});
  CHECK(load_daemon_config(with_source.dump(), daemon).source.kind == SourceKind::qtm);
}

// `fabrik calibrate` of a Vicon C3D names the targets as the file does, `Subject:Marker`;
// routed to a subject, the stream's names arrive without the prefix. Such a config as a
// subject's once tracked nothing (every name unknown, no warning).
TEST_CASE("A subject's config calibrated from Subject:Marker names tracks that subject's markers",
          "[subjects]") {
  test::SubjectsDir dir;
  const TrackerSetup& bare = default_daemon_config().tracker;
  // The default config's targets, each named PREFIX + marker (levels and weights as they are).
  const auto prefixed_config = [&](const std::string& prefix, const std::string& also) {
    json markers = json::object();
    for (const MarkerTarget& t : bare.markers)
      markers[prefix + t.marker] = {{"point", bare.model->points[t.point].name},
                                    {"level", t.level},
                                    {"weight", t.weight}};
    if (!also.empty()) {  // a marker of no model point's name, twice: prefixed and bare
      markers[prefix + also] = {{"point", "LASI"}};
      markers[also] = {{"point", "RASI"}};
    }
    return json{{"format", "fabrikd-config/1"},
                {"model", "models/fullbody.json"},
                {"targets", {{"markers", markers}}}};
  };
  dir.write_file("Alice.json", prefixed_config("Alice:", ""));
  dir.write_file("Bob.json", prefixed_config("Alice:", ""));  // another subject's names
  const DaemonConfig c = load_daemon_config_file(dir.write_file(
      "two.json", json{{"format", "fabrikd-config/1"},
                       {"subjects", {{{"name", "Alice"}, {"config", "Alice.json"}},
                                     {{"name", "Bob"}, {"config", "Bob.json"}}}}}));
  REQUIRE(c.subjects.size() == 2);
  // As the stream's Alice:X reaches her: X, on the same point, at the same level.
  const auto by_name = [](const std::vector<MarkerTarget>& targets) {
    std::map<std::string, std::pair<int, int>> m;
    for (const MarkerTarget& t : targets) m[t.marker] = {t.point, t.level};
    return m;
  };
  REQUIRE(c.subjects[0].tracker.markers.size() == bare.markers.size());
  CHECK(by_name(c.subjects[0].tracker.markers) == by_name(bare.markers));
  // Only the subject's own prefix goes: Bob's config named after Alice stays as written.
  for (const MarkerTarget& t : c.subjects[1].tracker.markers) CHECK(t.marker.starts_with("Alice:"));
  // Two targets that would share a name: refused, naming both.
  dir.write_file("Alice.json", prefixed_config("Alice:", "PELVIS_PLATE"));
  try {
    load_daemon_config_file(dir.write_file(
        "one.json", json{{"format", "fabrikd-config/1"},
                         {"subjects", {{{"name", "Alice"}, {"config", "Alice.json"}}}}}));
    FAIL("a config with Alice:PELVIS_PLATE and PELVIS_PLATE was taken");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("'Alice:PELVIS_PLATE' and 'PELVIS_PLATE'"));
  }
  // Listed as 'alice' while its targets are 'Alice:X' (a config calibrated from the stream):
  // the stream's names would reach no subject, and are refused at load, naming the fix.
  dir.write_file("Alice.json", prefixed_config("Alice:", ""));
  try {
    load_daemon_config_file(dir.write_file(
        "lower.json", json{{"format", "fabrikd-config/1"},
                           {"subjects", {{{"name", "alice"}, {"config", "Alice.json"}}}}}));
    FAIL("subject 'alice' with targets 'Alice:X' was taken");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("subject 'alice' has targets named 'Alice:") &&
                             Catch::Contains("names are case-sensitive") &&
                             Catch::Contains("name the subject 'Alice'"));
  }
}

// A subject whose config shares no name with its markers, in frames that also carry another
// process's subject: the daemon judged "only another subject's markers" from the 8 unknown names
// it lists for the log, all Carol's here, and raised no mismatch. It counts every name now.
TEST_CASE("A subject's markers none of its config names are a mismatch beside another's",
          "[subjects][daemon]") {
  test::SubjectsDir dir;
  const std::string path = dir.write({"Alice", "Zoe"});
  json zed = json::object();  // Zoe's config names her targets after someone else
  const TrackerSetup& bare = default_daemon_config().tracker;
  for (const MarkerTarget& t : bare.markers)
    zed["Zed:" + t.marker] = {{"point", bare.model->points[t.point].name}};
  dir.write_file("Zoe.json", json{{"format", "fabrikd-config/1"},
                                  {"model", "models/fullbody.json"},
                                  {"targets", {{"markers", zed}}}});
  test::DaemonThread d(zmq_context(), on_inproc(load_daemon_config_file(path), "misnamed"));
  const DaemonConfig& c = d.daemon.config();
  test::SocketClient client(zmq_context(), d.daemon.input_endpoint(), d.daemon.output_endpoint());
  SyntheticMotion motion(*c.subjects[0].tracker.model, MotionSettings{});
  std::uint64_t frame = handshake(client, c, motion);
  const wire::DaemonCounters before = d.daemon.counters();
  const int frames = 2 * wire::NameMismatchWatch::kFramesInARow;
  for (int i = 0; i < frames; ++i) {
    // Carol's names sort before Zoe's: the first 8 unknown names are hers.
    json markers = test::subject_markers(bare, motion, i * 0.01, test::subject_offset_m(2), "Carol:");
    markers = test::subject_markers(bare, motion, i * 0.01, test::subject_offset_m(1), "Zoe:", markers);
    client.send(json{{"frame", ++frame}, {"markers", markers}}.dump());
    // Paced: each frame decoded (its unknown names counted) before the next, as a burst
    // beyond the backlog would be dropped undecoded.
    const std::uint64_t unknown = before.unknown_markers + (i + 1) * markers.size();
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (d.daemon.counters().unknown_markers < unknown &&
           std::chrono::steady_clock::now() < deadline)
      std::this_thread::yield();
    REQUIRE(d.daemon.counters().unknown_markers == unknown);
  }
  const wire::DaemonCounters after = d.daemon.counters();
  CHECK(after.unmatched_frames - before.unmatched_frames == static_cast<std::uint64_t>(frames));
  CHECK(after.config_mismatch);
}

TEST_CASE("Markers named Subject:Marker reach that subject's tracker and pose/NAME",
          "[subjects][daemon]") {
  AliceAndBob two("prefix");
  auto [d, c, client, motion, names] = std::tie(two.d, two.c, two.client, two.motion, two.names);
  const std::uint64_t first = two.first;
  const int n = 40;
  for (int i = 0; i < n; ++i) {
    const std::uint64_t frame = first + static_cast<std::uint64_t>(i);
    const json markers = both_markers(c, motion, i * 0.01, names, {0, 1});
    client.send(json{{"frame", frame}, {"time", i * 0.01}, {"markers", markers}}.dump());
    std::map<std::string, json> poses;
    const auto until = std::chrono::steady_clock::now() + 5s;
    while (poses.size() < 2 && std::chrono::steady_clock::now() < until) {
      auto m = client.receive_any(5s);
      REQUIRE(m);
      if (m->first.starts_with("pose")) poses[m->first] = m->second;
    }
    REQUIRE(poses.count("pose/Alice"));
    REQUIRE(poses.count("pose/Bob"));
    for (const std::string& name : names) {
      const json& pose = poses["pose/" + name];
      CHECK(pose["subject"] == name);
      CHECK(pose["frame"] == frame);
      CHECK(pose["occluded"].empty());
      // Each pose fits its own subject's markers (2 m apart): routing, not a mix.
      CHECK(distance_mm(pose["markers"]["LASI"], markers[name + ":LASI"]) < 5.0);
    }
  }
  const auto s = d.daemon.subject_counters();
  REQUIRE(s.size() == 2);
  CHECK(s[0].frames_out >= static_cast<std::uint64_t>(n));
  CHECK(s[1].frames_out >= static_cast<std::uint64_t>(n));
  CHECK(d.daemon.counters().unknown_markers == 0);
}

TEST_CASE("A frame's subject field gives its bare names to that subject only", "[subjects][daemon]") {
  const test::LogCapture log;  // before the daemon: outlives it
  AliceAndBob two("field");
  spdlog::default_logger()->set_level(spdlog::level::warn);  // on_inproc's err hides warnings
  auto [d, c, client, motion, names] = std::tie(two.d, two.c, two.client, two.motion, two.names);
  const std::uint64_t first = two.first;
  const auto before = d.daemon.subject_counters();
  const std::uint64_t frames_in = d.daemon.counters().frames_in;
  const json bob = test::subject_markers(c.subjects[1].tracker, motion, 0.0, test::subject_offset_m(1), "");
  client.send(json{{"frame", first}, {"subject", "Bob"}, {"markers", bob}}.dump());
  const auto pose = client.receive("pose/Bob", 5s);
  REQUIRE(pose);
  CHECK((*pose)["subject"] == "Bob");
  CHECK(distance_mm((*pose)["markers"]["LASI"], bob["LASI"]) < 5.0);
  // A subject the config does not list: counted, no pose.
  client.send(json{{"frame", first + 1}, {"subject", "Carol"}, {"markers", bob}}.dump());
  REQUIRE(counted(d.daemon, frames_in + 2));
  const auto after = d.daemon.subject_counters();
  CHECK(after[1].frames_out == before[1].frames_out + 1);
  CHECK(after[0].frames_out == before[0].frames_out);  // Alice's tracker did not see Bob
  CHECK(d.daemon.counters().other_subject_frames == 1);
  CHECK(d.daemon.counters().unknown_markers == 0);
  // Said, as a prefix's unknown subject is (a spelling, "alice" for "Alice", is the usual cause).
  CHECK_THAT(log.find("warning", "frames for subject 'Carol' are not answered"),
             Catch::Contains("not one of the config's 2 subjects"));
}

TEST_CASE(
    "Each unknown subject of a frame is logged, however many markers the one before has, "
    "and a name that is a listed subject's but for case says so",
    "[subjects][daemon]") {
  const test::LogCapture log;  // before the daemon: outlives it
  AliceAndBob two("unknown-subjects");
  spdlog::default_logger()->set_level(spdlog::level::warn);  // on_inproc's err hides warnings
  auto [d, c, client, motion, names] = std::tie(two.d, two.c, two.client, two.motion, two.names);
  const TrackerSetup& bare = default_daemon_config().tracker;
  // Carol's names sort first (upper case before lower), more of them than the 8 listed.
  json markers = both_markers(c, motion, 0.0, names, {0, 1});
  markers = test::subject_markers(bare, motion, 0.0, test::subject_offset_m(2), "Carol:", markers);
  markers = test::subject_markers(bare, motion, 0.0, test::subject_offset_m(3), "alice:", markers);
  REQUIRE(markers.size() > 3 * 8);
  client.send(json{{"frame", two.first + 1}, {"markers", markers}}.dump());
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (log.find("warning", "subject 'alice'").empty() &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::yield();
  CHECK_THAT(log.find("warning", "subject 'Carol'"),
             Catch::Contains("is not in the config: ignored"));
  CHECK_THAT(log.find("warning", "subject 'alice'"),
             Catch::Contains("is not in the config: ignored (reported once; the config has "
                             "'Alice': names are case-sensitive)"));
  CHECK(log.find("warning", "marker 'alice:").empty());  // a subject's, not a marker's
}

// Sends 80 frames (t = 10 s + 10 ms a frame) of Alice's markers and Bob's,
// `bob(i, markers)` changing frame i's (e.g. taking Bob's out); returns the
// frames Bob got a pose for.
std::set<int> bob_pose_frames(AliceAndBob& two, const std::function<void(int, json&)>& bob) {
  auto [c, client, motion, first, names] =
      std::tie(two.c, two.client, two.motion, two.first, two.names);
  std::set<int> bob_frames;
  for (int i = 0; i < 80; ++i) {
    const double t = 10.0 + i * 0.01;  // after the handshake's receive-clock times
    json markers = both_markers(c, motion, t, names, {0, 1});
    bob(i, markers);
    client.send(json{{"frame", first + i}, {"time", t}, {"markers", markers}}.dump());
    // Subjects are served in the config's order: Bob's pose of a frame
    // follows Alice's, so reading up to Alice's pose of this frame collects
    // Bob's of the frame before.
    for (const auto until = std::chrono::steady_clock::now() + 5s;;) {
      REQUIRE(std::chrono::steady_clock::now() < until);
      auto m = client.receive_any(5s);
      REQUIRE(m);
      if (m->first == "pose/Bob") bob_frames.insert(static_cast<int>(m->second["frame"].get<std::uint64_t>() - first));
      if (m->first == "pose/Alice" && m->second["frame"] == first + i) break;
    }
  }
  // Bob's pose of the last frame follows Alice's.
  if (client.receive_until("pose/Bob", [&, last = first + 79](const json& p) { return p["frame"] == last; }, 5s))
    bob_frames.insert(79);
  return bob_frames;
}

// Bob seen in frames 0-19 and 60-79 only (t = 10.00 + 0.01 i), timeout 0.1 s:
// tracked through the occlusion while t - 10.19 <= 0.1 (frames 20..29),
// absent from frame 30, back at 60.
std::set<int> bob_expected_frames() {
  std::set<int> expected;
  for (int i = 0; i < 80; ++i)
    if (i < 30 || i >= 60) expected.insert(i);
  return expected;
}

bool bob_unseen(int i) {
  return i >= 20 && i < 60;
}

TEST_CASE("A subject unseen for subject_timeout_s gets no poses and comes back cold",
          "[subjects][daemon]") {
  AliceAndBob two("timeout", {{"subject_timeout_s", 0.1}});
  auto& d = two.d;
  auto& client = two.client;
  // The handshake's frames have no time (the daemon's clock since its start,
  // well under 10 s): the jump to 10 s below is a gap, so Alice starts cold too.
  const auto start = d.daemon.subject_counters();
  const std::set<int> bob_frames = bob_pose_frames(two, [](int i, json& markers) {
    if (!bob_unseen(i)) return;
    for (auto it = markers.begin(); it != markers.end();)
      it = it.key().starts_with("Bob:") ? markers.erase(it) : std::next(it);
  });
  CHECK(bob_frames == bob_expected_frames());
  const auto s = d.daemon.subject_counters();
  CHECK(s[1].departures - start[1].departures == 1);
  CHECK(s[1].appearances - start[1].appearances == 2);  // cold at the start and on return
  CHECK(s[1].present);
  CHECK(s[0].departures - start[0].departures == 1);  // the jump to t = 10 s, nothing else
  CHECK(s[0].appearances - start[0].appearances == 1);
  const auto stats = client.stats_until([](const json& j) { return j.contains("subjects"); });
  REQUIRE(stats);
  CHECK((*stats)["subjects"]["Bob"]["present"] == true);
  CHECK((*stats)["subjects"]["Bob"]["departures"].get<int>() >= 1);
  CHECK((*stats)["other_subject_frames"] == 0);
}

TEST_CASE("A subject whose markers are all under the confidence threshold is unseen",
          "[subjects][daemon]") {
  // The tracker occludes a marker under confidence.threshold (0.3); one that
  // comes with 0.1 does not keep its subject present either.
  AliceAndBob two("confidence", {{"subject_timeout_s", 0.1}});
  const auto start = two.d.daemon.subject_counters();
  const std::set<int> bob_frames = bob_pose_frames(two, [](int i, json& markers) {
    if (!bob_unseen(i)) return;
    for (auto it = markers.begin(); it != markers.end(); ++it)
      if (it.key().starts_with("Bob:")) it.value().push_back(0.1);
  });
  CHECK(bob_frames == bob_expected_frames());
  const auto s = two.d.daemon.subject_counters();
  CHECK(s[1].departures - start[1].departures == 1);
  CHECK(s[1].appearances - start[1].appearances == 2);
  CHECK(s[1].present);
}

TEST_CASE("A subscriber selects one subject by topic prefix, other topics are refused",
          "[subjects][daemon]") {
  AliceAndBob two("topics");
  auto [d, c, client, motion, names] = std::tie(two.d, two.c, two.client, two.motion, two.names);
  std::uint64_t frame = two.first;
  const auto subscriber = [&](const std::string& prefix) {
    zmq::socket_t s(zmq_context(), zmq::socket_type::sub);
    s.set(zmq::sockopt::linger, 0);
    s.set(zmq::sockopt::subscribe, prefix);
    s.connect(two.d.daemon.output_endpoint());
    return s;
  };
  zmq::socket_t bob_only = subscriber("pose/Bob"), all_poses = subscriber("pose"),
                alice_model = subscriber("model/Alice");
  // Until each has a message (subscriptions propagate asynchronously).
  const auto topics_of = [](zmq::socket_t& s, std::set<std::string>& topics) {
    zmq::message_t t, p;
    while (s.recv(t, zmq::recv_flags::dontwait)) {
      topics.insert(std::string(t.to_string_view()));
      while (t.more() && s.recv(p, zmq::recv_flags::dontwait) && p.more()) {
      }
    }
  };
  std::set<std::string> bob_topics, all_topics, model_topics;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while ((all_topics.size() < 2 || bob_topics.empty() || model_topics.empty()) &&
         std::chrono::steady_clock::now() < deadline) {
    client.send(json{{"frame", frame++}, {"markers", both_markers(c, motion, 0.0, names, {0, 1})}}.dump());
    client.receive("pose/Alice", 1s);  // paces the frames
    topics_of(bob_only, bob_topics);
    topics_of(all_poses, all_topics);
    topics_of(alice_model, model_topics);
  }
  CHECK(bob_topics == std::set<std::string>{"pose/Bob"});
  CHECK(all_topics == std::set<std::string>{"pose/Alice", "pose/Bob"});
  CHECK(model_topics == std::set<std::string>{"model/Alice"});
  // Subscriptions that match no published topic are refused.
  CHECK(wire::subscribes_to_our_topics("pose/B", std::vector<std::string>{"pose/Bob"}));
  CHECK_FALSE(wire::subscribes_to_our_topics("pose/Carol", std::vector<std::string>{"pose/Bob"}));
  CHECK_FALSE(wire::subscribes_to_our_topics("pose/Bob"));  // without subjects: refused
  const std::uint64_t refused = d.daemon.counters().subscriptions_refused;
  zmq::socket_t carol = subscriber("pose/Carol");
  const auto until = std::chrono::steady_clock::now() + 5s;
  while (d.daemon.counters().subscriptions_refused == refused && std::chrono::steady_clock::now() < until)
    std::this_thread::yield();
  CHECK(d.daemon.counters().subscriptions_refused == refused + 1);
}

TEST_CASE("A config without subjects publishes as before: topic pose, no subject key",
          "[subjects][daemon]") {
  DaemonConfig config = on_inproc(default_daemon_config(), "single");
  test::DaemonThread d(zmq_context(), config);
  test::SocketClient client(zmq_context(), d.daemon.input_endpoint(), d.daemon.output_endpoint());
  const std::uint64_t first = client.handshake();
  MotionSettings ms;
  SyntheticMotion motion(*config.tracker.model, ms);
  const json markers = test::subject_markers(config.tracker, motion, 0.0, Eigen::Vector3d::Zero(), "");
  // A "subject" in a frame is an addition a single-subject daemon ignores.
  client.send(json{{"frame", first}, {"subject", "Alice"}, {"markers", markers}}.dump());
  const auto pose = client.pose_of(first);
  REQUIRE(pose);
  CHECK_FALSE(pose->contains("subject"));
  CHECK(d.daemon.subject_counters().empty());
  CHECK(d.daemon.counters().other_subject_frames == 0);
}
