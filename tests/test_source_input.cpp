// A vendor source inside the daemon, with a scripted client standing in for
// QTM or NatNet: names, axes, units, frame numbers and times reach the pose
// as they would from the ZeroMQ input, and the source's connection shows in
// stats. The vendor clients themselves: test_qtm_client, test_natnet_client.
#include <catch2/catch.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <fstream>
#include <functional>
#include <future>
#include <mutex>
#include <set>
#include <thread>

#include "config/daemon_config.hpp"
#include "config/model_loader.hpp"
#include "config/resources.hpp"
#include "daemon_thread.hpp"
#include "socket_client.hpp"
#include "subjects_fixture.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/daemon.hpp"
#include "transport/source_frames.hpp"

using namespace fabrik;
using namespace std::chrono_literals;
using nlohmann::json;
using test::DaemonThread;
using test::largest_difference;
using test::on_inproc;
using test::source_of;

namespace {

// The default config behind a NatNet source (subject_prefix "*") on inproc, quiet.
DaemonConfig source_daemon_config(const std::string& tag) {
  DaemonConfig c = on_inproc(default_daemon_config(), tag);
  c.source = source_of(R"({"source": "natnet://127.0.0.1"})");
  c.log_level = "error";  // applied at a reload
  return c;
}

std::string config_error(const std::string& input_json) {
  try {
    (void)source_of(input_json);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// Stands in for a vendor client: announces its labels, hands over each
// frame once the test allows it (lock step: the daemon's overload rule would
// drop frames handed over faster than they are solved) and then idles until
// stopped, as a connected server would.
struct ScriptedServer {
  std::vector<std::string> labels;
  std::vector<std::vector<Eigen::Vector3d>> frames_mm;  // per frame, per label
  std::uint64_t first_frame = 1;
  double rate_hz = 100.0;
  std::mutex mutex;
  std::condition_variable_any released_cv;
  std::size_t allowed = 0;  // frames the client may hand over

  void allow(std::size_t frames) {
    std::lock_guard lock(mutex);
    allowed = frames;
    released_cv.notify_all();
  }
  wire::SourceClient client() {
    return [this](bridges::FrameSink& sink, bridges::SourceStatus& status, std::stop_token stop) {
      std::unique_lock lock(mutex);
      if (!released_cv.wait(lock, stop, [&] { return allowed > 0; })) return;
      status.connected("scripted server 1.0");
      sink.labels(labels);
      for (std::size_t i = 0; i < frames_mm.size(); ++i) {
        if (!released_cv.wait(lock, stop, [&] { return allowed > i; })) return;
        status.frame_delivered();  // as the vendor clients count: before the hand-over
        sink.frame(first_frame + i, static_cast<double>(i) / rate_hz, frames_mm[i]);
      }
      status.error("scripted server: end of the script");
      released_cv.wait(lock, stop, [] { return false; });
    };
  }
};

}  // namespace

TEST_CASE("Subject prefixes come off marker names as configured", "[source]") {
  CHECK(wire::strip_subject_prefix("Subject:LASI", "*") == "LASI");
  CHECK(wire::strip_subject_prefix("A:B:LASI", "*") == "LASI");
  CHECK(wire::strip_subject_prefix("LASI", "*") == "LASI");
  CHECK(wire::strip_subject_prefix("Subject:LASI", "") == "Subject:LASI");
  CHECK(wire::strip_subject_prefix("Subject01_LASI", "Subject01_") == "LASI");
  CHECK(wire::strip_subject_prefix("Other:LASI", "Subject:") == "Other:LASI");
  // A subject's name without its colon: the colon goes too (was ":LASI", matching nothing),
  // and a longer name that starts with it is another subject's.
  CHECK(wire::strip_subject_prefix("Subject:LASI", "Subject") == "LASI");
  CHECK(wire::strip_subject_prefix("Subject01:LASI", "Subject") == "Subject01:LASI");
  CHECK(wire::strip_subject_prefix("Subject", "Subject") == "Subject");
  CHECK(wire::strip_subject_prefix("s1-LASI", "s1-") == "LASI");
  CHECK(wire::strip_subject_prefix("Daphn\xc3\xa9:ASISl", "Daphn\xc3\xa9") == "ASISl");  // UTF-8
}

TEST_CASE("A server's axes rotate into the lab's: Motive's Y up into a Z-up lab", "[source]") {
  const LabAxes motive{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()};
  const LabAxes z_up{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX()};
  const Eigen::Matrix3d r = z_up.r_from(motive);
  // Forward stays x, Motive's up (y) becomes z, Motive's z (to the right of
  // forward in a Y-up right-handed frame... its -right) becomes -y.
  CHECK((r * Eigen::Vector3d(1, 2, 3) - Eigen::Vector3d(1, -3, 2)).norm() < 1e-12);
  CHECK(std::abs(r.determinant() - 1.0) < 1e-12);
  CHECK((z_up.r_from(z_up) - Eigen::Matrix3d::Identity()).norm() < 1e-12);
  // A lab with forward along y and a server with forward along x: a quarter turn about up.
  const LabAxes z_up_y_forward{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()};
  CHECK((z_up_y_forward.r_from(z_up) * Eigen::Vector3d(1, 0, 0) -
         Eigen::Vector3d(0, 1, 0)).norm() < 1e-12);
}

TEST_CASE("A server's stated up axis turns its frames where the config declares no axes",
          "[source][lab_axes]") {
  const std::vector<std::string> taken = {"LASI"};
  const Eigen::Vector3d p(1, 2, 3);
  wire::SourceFrames frames(source_of(R"({"source": "qtm://127.0.0.1"})"), LabAxes{}, taken);
  CHECK(frames.r_lab_server().isIdentity(0.0));
  CHECK(frames.server_up("+Y").empty());  // the lab's own: nothing to say, nothing turned
  CHECK(frames.r_lab_server().isIdentity(0.0));
  // QTM's Z up, forward the lab's +x: its left (+y) is the Y-up lab's -z (right is +z).
  CHECK_THAT(frames.server_up("+Z"), Catch::Contains("turned from up +z, forward +x"));
  CHECK((frames.r_lab_server() * p - Eigen::Vector3d(1, 3, -2)).norm() < 1e-12);
  CHECK(frames.server_up("+z").empty());  // said again: no second notice
  CHECK_THAT(frames.server_up("up"), Catch::Contains("not an axis"));
  CHECK(frames.r_lab_server().isIdentity(0.0));  // as the config says, not +z's left over
  frames.server_up("+Z");
  CHECK_THAT(frames.server_up("+Y"),
             Catch::Contains("is now +y") && Catch::Contains("taken as they come"));
  CHECK(frames.r_lab_server().isIdentity(0.0));
  // A lab whose forward is the server's up: forward from default_forward_lab (+x).
  wire::SourceFrames sideways(source_of(R"({"source": "qtm://127.0.0.1"})"),
                              LabAxes{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()}, taken);
  CHECK_THAT(sideways.server_up("-Z"), Catch::Contains("from up -z, forward +x"));
  CHECK((sideways.r_lab_server() * Eigen::Vector3d(0, 0, -1) - Eigen::Vector3d(0, 1, 0)).norm() <
        1e-12);
  // Axes the config declares are kept; a server that disagrees is named.
  wire::SourceFrames declared(
      source_of(R"({"source": "qtm://127.0.0.1", "source_options": {"axes": {"up": "+y"}}})"),
      LabAxes{}, taken);
  CHECK_THAT(declared.server_up("+Z"), Catch::Contains("source_options.axes says +y"));
  CHECK(declared.r_lab_server().isIdentity(0.0));
  CHECK(declared.server_up("+Y").empty());
}

TEST_CASE("Source URLs and options are read, and wrong ones refused with the fix", "[source]") {
  const SourceConfig qtm = source_of(R"({"source": "qtm://10.0.0.5"})");
  CHECK(qtm.kind == SourceKind::qtm);
  CHECK(qtm.host == "10.0.0.5");
  CHECK(qtm.port == 22223);
  const SourceConfig natnet = source_of(
      R"({"source": "natnet://motive.lab:1600", "source_options": {"natnet_data": "unicast",
          "subject_prefix": "", "axes": {"up": "+z"}}})");
  CHECK(natnet.kind == SourceKind::natnet);
  CHECK(natnet.host == "motive.lab");
  CHECK(natnet.port == 1600);
  CHECK_FALSE(natnet.multicast);
  CHECK(natnet.subject_prefix.empty());
  REQUIRE(natnet.axes);
  CHECK(natnet.axes->up_lab == Eigen::Vector3d::UnitZ());
  CHECK(natnet.axes->forward_lab == Eigen::Vector3d::UnitX());
  CHECK(source_of(R"({"source": "qtm://[::1]:22224"})").host == "::1");
  CHECK(source_of(R"({"source": "qtm://[::1]:22224"})").port == 22224);
  CHECK(source_of(R"({})").kind == SourceKind::none);

  CHECK_THAT(config_error(R"({"source": "vicon://host"})"), Catch::Contains("unknown source"));
  CHECK_THAT(config_error(R"({"source": "qtm://"})"), Catch::Contains("names no host"));
  CHECK_THAT(config_error(R"({"source": "qtm://host:0"})"), Catch::Contains("1..65535"));
  CHECK_THAT(config_error(R"({"source": "qtm://host:70000"})"), Catch::Contains("1..65535"));
  CHECK_THAT(config_error(R"({"source": "qtm://host:"})"), Catch::Contains("1..65535"));
  CHECK_THAT(config_error(R"({"source": "qtm:host"})"), Catch::Contains("not a source URL"));
  // NatNet's client is IPv4 only: an IPv6 literal once started, then failed every retry.
  CHECK_THAT(config_error(R"({"source": "natnet://[::1]"})"), Catch::Contains("IPv4 only"));
  CHECK_THAT(config_error(R"({"source": "natnet://[::1]:1510"})"), Catch::Contains("IPv4 only"));
  CHECK_THAT(config_error(R"({"source": "natnet://fe80::1"})"), Catch::Contains("IPv4 only"));
  // Without brackets an IPv6 address was split at its last ':' into a host and a port.
  CHECK_THAT(config_error(R"({"source": "qtm://fe80::1"})"), Catch::Contains("in brackets"));
  CHECK_THAT(config_error(R"({"source": "qtm://h", "source_options": {"natnet_data": "unicast"}})"),
             Catch::Contains("natnet:// sources only"));
  CHECK_THAT(config_error(R"({"source": "natnet://h", "source_options": {"frequency_divisor": 2}})"),
             Catch::Contains("qtm:// sources only"));
  CHECK_THAT(config_error(R"({"source_options": {}})"), Catch::Contains("without a source"));
  CHECK_THAT(config_error(R"({"source": "natnet://h", "source_options": {"axes": {"up": "x"}}})"),
             Catch::Contains("no forward axis"));
  // A unicast address as the group: the client's join failed at every retry.
  for (const char* group : {"10.0.0.5", "240.0.0.1", "223.255.255.255"}) {
    CAPTURE(group);
    CHECK_THAT(config_error(R"({"source": "natnet://h", "source_options": {"multicast_group": ")" +
                            std::string(group) + R"("}})"),
               Catch::Contains("at /input/source_options/multicast_group: '" + std::string(group) +
                               "' is not an IPv4 multicast group (224.0.0.0 to 239.255.255.255)"));
  }
  for (const char* group : {"239.001.1.1", "motive.lab", "", "239.255.42.99 "}) {
    CAPTURE(group);
    CHECK_THAT(config_error(R"({"source": "natnet://h", "source_options": {"multicast_group": ")" +
                            std::string(group) + R"("}})"),
               Catch::Contains("' is not a dotted IPv4 address (four numbers 0-255, no leading "
                               "zeros, no host name)"));
  }
  CHECK(source_of(R"({"source": "natnet://h", "source_options": {"multicast_group": "224.0.0.1"}})")
            .multicast_group == "224.0.0.1");
  // As the schema says: a group given is checked in unicast too.
  CHECK_THAT(
      config_error(R"({"source": "natnet://h", "source_options": {"multicast_group": "10.0.0.5",
                      "natnet_data": "unicast"}})"),
      Catch::Contains("is not an IPv4 multicast group"));
}

TEST_CASE(
    "A source's frames reach the pose like ZeroMQ frames: prefix stripped, axes rotated, "
    "frame and time carried, connection in stats",
    "[source][daemon]") {
  zmq::context_t context;
  spdlog::set_level(spdlog::level::err);
  DaemonConfig with_source = on_inproc(default_daemon_config(), "source");
  // A Z-up server whose forward is the lab's -x: a half turn about up from the lab.
  with_source.source = source_of(
      R"({"source": "natnet://127.0.0.1", "source_options": {"axes": {"up": "+z", "forward": "-x"}}})");
  const Model& model = *with_source.tracker.model;
  const LabAxes server{Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitX()};
  const Eigen::Matrix3d r_server_lab = model.lab_axes.r_from(server).transpose();
  REQUIRE((r_server_lab - Eigen::Matrix3d::Identity()).norm() > 1.0);  // the rotation matters

  // 60 frames of synthetic motion; marker 2 hidden in frames 20-29.
  ScriptedServer script;
  script.first_frame = 5000;
  std::vector<json> zmq_frames;
  MotionSettings ms;
  SyntheticMotion motion(model, ms);
  Posture posture = Posture::rest(model);
  const auto& targets = with_source.tracker.markers;
  for (const MarkerTarget& t : targets) script.labels.push_back("Subject7:" + t.marker);
  script.labels.push_back("Subject7:NOT_IN_MODEL");
  for (int i = 0; i < 60; ++i) {
    motion.posture_at(i / script.rate_hz, posture);
    std::vector<Eigen::Vector3d> server_mm;
    json markers = json::object();
    for (std::size_t k = 0; k < targets.size(); ++k) {
      const Eigen::Vector3d lab_mm = posture.point_world_m(model, targets[k].point) * 1e3;
      const bool hidden = k == 2 && i >= 20 && i < 30;
      server_mm.push_back(hidden ? Eigen::Vector3d::Constant(NAN) : Eigen::Vector3d(r_server_lab * lab_mm));
      markers[targets[k].marker] = hidden ? json(nullptr) : json{lab_mm.x(), lab_mm.y(), lab_mm.z()};
    }
    server_mm.push_back(Eigen::Vector3d(1, 2, 3));
    markers["NOT_IN_MODEL"] = {1, 2, 3};
    script.frames_mm.push_back(server_mm);
    zmq_frames.push_back(json{{"frame", script.first_frame + i},
                              {"time", i / script.rate_hz},
                              {"units", "mm"},
                              {"markers", markers}});
  }

  // The reference: the same frames on the ZeroMQ input of a daemon without a source.
  std::vector<json> reference;
  {
    DaemonThread d(context, on_inproc(default_daemon_config(), "reference"), {});
    test::SocketClient client(context, "inproc://reference-markers", "inproc://reference-poses");
    REQUIRE(client.receive("stats"));  // subscribed: nothing sent from now on is lost
    for (const json& f : zmq_frames) {
      client.send(f.dump());
      auto pose = client.receive("pose");
      REQUIRE(pose);
      reference.push_back(*pose);
    }
  }
  DaemonThread d(context, with_source, [&](const SourceConfig&) { return script.client(); });
  test::SocketClient client(context, "inproc://source-markers", "inproc://source-poses");
  const auto before = client.stats_until([](const json& s) { return s.contains("source"); });
  REQUIRE(before);
  CHECK((*before)["source"]["connected"] == false);
  CHECK((*before)["source"]["url"] == "natnet://127.0.0.1");
  for (std::size_t i = 0; i < reference.size(); ++i) {
    script.allow(i + 1);
    auto pose = client.receive("pose");
    REQUIRE(pose);
    INFO("frame " << i);
    CHECK((*pose)["frame"] == reference[i]["frame"]);
    CHECK((*pose)["time"] == reference[i]["time"]);
    CHECK((*pose)["occluded"] == reference[i]["occluded"]);
    CHECK(largest_difference((*pose)["joints"], reference[i]["joints"]) < 1e-6);  // mm
    CHECK(largest_difference((*pose)["markers"], reference[i]["markers"]) < 1e-6);
  }
  const auto after = client.stats_until([](const json& s) {
    return s["source"]["frames"] == 60 && !s["source"]["last_error"].is_null();
  });
  REQUIRE(after);
  const json& source = (*after)["source"];
  CHECK(source["connected"] == true);
  CHECK(source["server"] == "scripted server 1.0");
  CHECK(source["connections"] == 1);
  CHECK(source["reconnects"] == 0);
  CHECK(source["frames_dropped"] == 0);
  CHECK(source["last_error"] == "scripted server: end of the script");
  // The block is what proto/stats.schema.json says, key for key.
  std::ifstream schema_file(std::string(FABRIK_SOURCE_DIR) + "/proto/stats.schema.json");
  const json schema = json::parse(schema_file)["properties"]["source"];
  std::set<std::string> required, written, described;
  for (const json& k : schema["required"]) required.insert(k.get<std::string>());
  for (const auto& [k, v] : schema["properties"].items()) described.insert(k);
  for (const auto& [k, v] : source.items()) written.insert(k);
  CHECK(written == required);
  CHECK(written == described);
  CHECK((*after)["frames_out"] == 60);
  CHECK((*after)["unknown_markers"] == 60);
  CHECK((*after)["decode_errors"] == 0);
}

namespace {

// Alice and Bob (the built-in model each) behind a NatNet source at its default options, whose
// axes are the lab's (positions pass unrotated), on inproc endpoints named after `tag`.
DaemonConfig alice_and_bob_behind_a_source(test::SubjectsDir& dir, const std::string& tag) {
  DaemonConfig c =
      on_inproc(load_daemon_config_file(dir.write(
                    {"Alice", "Bob"}, json{{"input", {{"source", "natnet://127.0.0.1"}}}})),
                tag);
  c.source.axes = c.subjects.at(0).tracker.model->lab_axes;
  return c;
}

// One more frame of `markers` (name -> [x, y, z] mm) for the script; the first frame's names
// are its labels.
void add_frame(ScriptedServer& script, const json& markers) {
  std::vector<Eigen::Vector3d> frame_mm;
  for (const auto& [name, p] : markers.items()) {
    if (script.frames_mm.empty()) script.labels.push_back(name);
    frame_mm.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
  }
  script.frames_mm.push_back(frame_mm);
}

}  // namespace

TEST_CASE(
    "A server's Subject:Marker names the config takes whole stay whole: several subjects "
    "behind a source at its default subject_prefix get their poses",
    "[source][daemon][subjects]") {
  // With "*" every name lost its subject: Alice:LASI and Bob:LASI both came in as LASI,
  // which no subject of a multi-subject config takes (routing is by NAME:), so no
  // subject got a pose; a config calibrated from Daphnee:ASISl names matched nothing.
  wire::SourceFrames frames(source_of(R"({"source": "natnet://127.0.0.1"})"), LabAxes{},
                            {"Alice:LASI", "Bob:LASI", "Daphnee:ASISl", "LASI"});
  const std::vector<std::string> server = {"Alice:LASI", "Bob:LASI", "Carol:RASI", "Daphnee:ASISl",
                                           "Subject:RASI"};
  frames.labels(server);
  // Carol (another process's subject) stays whole: stripped, RASI is no name taken.
  CHECK(frames.names() == std::vector<std::string>{"Alice:LASI", "Bob:LASI", "Carol:RASI",
                                                   "Daphnee:ASISl", "Subject:RASI"});
  // A name stripped into one taken, once: the server's own LASI keeps it.
  frames.labels(std::vector<std::string>{"Subject:LASI", "LASI", "Other:LASI"});
  CHECK(frames.names() == std::vector<std::string>{"Subject:LASI", "LASI", "Other:LASI"});
  wire::SourceFrames bare(source_of(R"({"source": "natnet://127.0.0.1"})"), LabAxes{},
                          {"LASI", "RASI"});
  bare.labels(std::vector<std::string>{"Subject:LASI", "Subject:RASI", "Other:LASI", "Subject:X"});
  CHECK(bare.names() == std::vector<std::string>{"LASI", "RASI", "Other:LASI", "Subject:X"});
  // Names taken anew (a reload): the server's names read last are mapped again.
  bare.retake({"LASI", "X"});
  CHECK(bare.names() == std::vector<std::string>{"LASI", "Subject:RASI", "Other:LASI", "X"});

  zmq::context_t context;
  spdlog::set_level(spdlog::level::err);
  test::SubjectsDir dir;
  const DaemonConfig c = alice_and_bob_behind_a_source(dir, "subjects-source");
  REQUIRE(c.source.subject_prefix == "*");  // the default
  REQUIRE(c.subjects.size() == 2);
  ScriptedServer script;
  const std::vector<std::string> names = {"Alice", "Bob"};
  SyntheticMotion motion(*c.subjects[0].tracker.model, MotionSettings{});
  for (int i = 0; i < 5; ++i) {
    json markers = json::object();
    for (int k = 0; k < 2; ++k)
      markers = test::subject_markers(c.subjects[k].tracker, motion, i * 0.01,
                                      test::subject_offset_m(k), names[k] + ":", markers);
    add_frame(script, markers);
  }
  test::DaemonThread d(context, c, [&](const SourceConfig&) { return script.client(); });
  test::SocketClient client(context, c.input.address, c.output.address);
  REQUIRE(client.receive("stats"));  // subscribed: no pose from now on is lost
  script.allow(script.frames_mm.size());
  std::set<std::string> posed;
  const auto until = std::chrono::steady_clock::now() + 5s;
  while (posed.size() < 2 && std::chrono::steady_clock::now() < until)
    if (const auto m = client.receive_any(500ms); m && m->first.starts_with("pose/"))
      posed.insert(m->first);
  CHECK(posed == std::set<std::string>{"pose/Alice", "pose/Bob"});
  const auto stats = client.stats_until([](const json& s) { return s["frames_in"] == 5; });
  REQUIRE(stats);
  CHECK((*stats)["unknown_markers"] == 0);
}

TEST_CASE("Behind a source, another process's subject is another subject's, not a mismatch",
          "[source][daemon][subjects]") {
  // Stripped at "*", Carol:LASI came in as LASI: a marker Alice's and Bob's configs lack,
  // so a volume with only Carol in it raised the mismatch warning (docs/multi-subject.md,
  // the split).
  zmq::context_t context;
  spdlog::set_level(spdlog::level::err);
  test::SubjectsDir dir;
  const DaemonConfig c = alice_and_bob_behind_a_source(dir, "split-source");
  ScriptedServer script;
  SyntheticMotion motion(*c.subjects[0].tracker.model, MotionSettings{});
  for (int i = 0; i < 5; ++i)
    add_frame(script, test::subject_markers(c.subjects[0].tracker, motion, i * 0.01,
                                            test::subject_offset_m(2), "Carol:"));
  test::DaemonThread d(context, c, [&](const SourceConfig&) { return script.client(); });
  test::SocketClient client(context, c.input.address, c.output.address);
  REQUIRE(client.receive("stats"));
  script.allow(script.frames_mm.size());
  const auto stats = client.stats_until([](const json& s) { return s["frames_in"] == 5; });
  REQUIRE(stats);
  CHECK((*stats)["unmatched_frames"] == 0);
  CHECK((*stats)["unknown_markers"].get<int>() > 0);  // Carol's, counted as before
}

TEST_CASE(
    "A daemon built in code refuses subjects in two lab axes behind a source, as the "
    "loader does",
    "[source][daemon][subjects][lab_axes]") {
  zmq::context_t context;
  test::SubjectsDir dir;
  DaemonConfig c = alice_and_bob_behind_a_source(dir, "two-labs");
  json doc = json::parse(*embedded_config("models/fullbody.json"));
  doc["lab_axes"] = {{"up", "+z"}, {"forward", "+x"}};
  c.subjects[1].tracker.model = std::make_shared<const Model>(load_model(doc, "fullbody.json"));
  REQUIRE(source_lab_problem(c));
  CHECK(source_lab_problem(c)->subject == 1);
  CHECK_THROWS_WITH(wire::Daemon(context, c),
                    Catch::StartsWith("subject Bob's lab axes") &&
                        Catch::Contains(". Fix: calibrate every subject"));
  c.source = SourceConfig{};  // the ZeroMQ input: each subject's axes are its own
  CHECK_FALSE(source_lab_problem(c));
}

TEST_CASE(
    "A reload keeps a source whose options and lab axes are unchanged, and replaces it "
    "otherwise",
    "[source][daemon][reload]") {
  // Kept, the connection (and the server's frames) carry on across a reload of, say, the
  // solver's options; replaced, the old client is stopped and a new one reads the names anew.
  zmq::context_t context;
  spdlog::set_level(spdlog::level::err);
  const DaemonConfig base = source_daemon_config("reload-source");
  std::mutex next_mutex;
  DaemonConfig next = base;
  const auto load = [&]() -> DaemonConfig {
    std::lock_guard lock(next_mutex);
    return next;
  };
  std::atomic<int> clients{0};
  ScriptedServer idle;  // never allowed: each client waits until it is stopped
  DaemonThread d(
      context, base,
      [&](const SourceConfig&) {
        ++clients;
        return idle.client();
      },
      load);
  test::SocketClient client(context, base.input.address, base.output.address);
  REQUIRE(client.receive("stats"));
  REQUIRE(clients == 1);
  std::uint64_t reloads = 0;
  const auto reload_with = [&](const std::function<void(DaemonConfig&)>& change) {
    {
      std::lock_guard lock(next_mutex);
      next = base;
      change(next);
    }
    d.control.reload = true;
    ++reloads;
    const auto stats = client.stats_until([&](const json& s) { return s["reloads"] == reloads; });
    REQUIRE(stats);
    CHECK((*stats)["reload_errors"] == 0);
  };
  SECTION("kept: the solver's options changed, or nothing") {
    reload_with([](DaemonConfig& c) { c.tracker.solver.max_iterations += 1; });
    reload_with([](DaemonConfig&) {});
    CHECK(clients == 1);
  }
  SECTION("replaced: the source's options changed") {
    reload_with([](DaemonConfig& c) { c.source.subject_prefix = ""; });
    CHECK(clients == 2);
  }
  SECTION("kept: a name the daemon takes changed (mapped again on the client's thread)") {
    reload_with([](DaemonConfig& c) { c.tracker.markers.front().marker += "_renamed"; });
    CHECK(clients == 1);
  }
  SECTION("replaced: the lab's axes changed (the server's frames are rotated into them)") {
    const std::optional<std::string_view> text = embedded_config("models/fullbody.json");
    REQUIRE(text);
    json doc = json::parse(*text);
    doc["lab_axes"] = {{"up", "+z"}, {"forward", "+y"}};
    const auto z_up = std::make_shared<const Model>(load_model(doc, "fullbody.json"));
    REQUIRE_FALSE(z_up->lab_axes == base.tracker.model->lab_axes);
    reload_with([&](DaemonConfig& c) { c.tracker.model = z_up; });
    CHECK(clients == 2);
  }
}

TEST_CASE("A reload that renames a marker keeps the source's connection and takes the new name",
          "[source][daemon][reload]") {
  // A reconnect would leave a gap in the frames: the kept client maps the server's names
  // again itself, so a marker renamed to a server's name is seen from the next frame.
  zmq::context_t context;
  spdlog::set_level(spdlog::level::err);
  const DaemonConfig base = source_daemon_config("rename-source");
  const Model& model = *base.tracker.model;
  const std::string first = base.tracker.markers.front().marker;
  // The server names every marker Subject7:NAME, and has one more, NEW, where the first is.
  ScriptedServer script;
  for (const MarkerTarget& t : base.tracker.markers)
    script.labels.push_back("Subject7:" + t.marker);
  script.labels.push_back("Subject7:NEW");
  const Posture rest = Posture::rest(model);
  for (int i = 0; i < 3; ++i) {
    std::vector<Eigen::Vector3d> frame_mm;
    for (const MarkerTarget& t : base.tracker.markers)
      frame_mm.push_back(rest.point_world_m(model, t.point) * 1e3);
    frame_mm.push_back(frame_mm.front());
    script.frames_mm.push_back(frame_mm);
  }
  DaemonConfig renamed = base;
  renamed.tracker.markers.front().marker = "NEW";
  std::atomic<bool> use_renamed{false};
  std::atomic<int> clients{0};
  DaemonThread d(
      context, base,
      [&](const SourceConfig&) {
        ++clients;
        return script.client();
      },
      [&]() -> DaemonConfig { return use_renamed ? renamed : base; });
  test::SocketClient client(context, base.input.address, base.output.address);
  REQUIRE(client.receive("stats"));
  const auto occluded = [](const json& pose) {
    std::set<std::string> names;
    for (const json& n : pose["occluded"]) names.insert(n.get<std::string>());
    return names;
  };
  script.allow(1);
  const auto before = client.receive("pose");
  REQUIRE(before);
  CHECK(occluded(*before).empty());  // NEW is no name taken: Subject7:NEW stays whole, unknown
  use_renamed = true;
  d.control.reload = true;
  const auto reloaded = client.stats_until([](const json& s) { return s["reloads"] == 1; });
  REQUIRE(reloaded);
  CHECK((*reloaded)["reload_errors"] == 0);
  script.allow(2);
  const auto after = client.receive("pose");
  REQUIRE(after);
  CHECK((*after)["frame"] == 2);
  // Subject7:NEW is stripped into the name now taken: NEW is seen, not occluded.
  CHECK(occluded(*after).empty());
  CHECK(clients == 1);
  const auto stats = client.stats_until([](const json& s) { return s["source"]["frames"] == 2; });
  REQUIRE(stats);
  CHECK((*stats)["source"]["connections"] == 1);
}
