// The simulated QTM and Motive servers (`fabrik sim qtm|natnet`) into a real
// daemon over loopback, the vendor clients doing the decoding: subject01_walk1
// gives the poses the same frames give on the ZeroMQ input (the must-show of
// the vendor sources); labels changed mid-stream and a server restart show in
// the poses and the stats.
#include <catch2/catch.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <map>
#include <optional>
#include <thread>

#include "bridges/natnet_sim_server.hpp"
#include "bridges/qtm/sim_server.hpp"
#include "config/daemon_config.hpp"
#include "daemon_thread.hpp"
#include "eval/subject.hpp"
#include "io/marker_trial.hpp"
#include "log_capture.hpp"
#include "socket_client.hpp"
#include "synth/synthetic_motion.hpp"
#include "tools/sim.hpp"
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

// A simulated QTM on loopback, on any free pair of ports.
qtm::QtmSimServer::Options any_free_ports() {
  qtm::QtmSimServer::Options o;
  o.base_port = 0;
  return o;
}

// A simulated server serving on a thread of its own until the script ends.
template <class Server>
struct ServerThread {
  explicit ServerThread(Server& s) : server(s), thread([this](std::stop_token stop) { server.run(stop); }) {}
  Server& server;
  std::jthread thread;
};

// Poses and the last stats from a daemon's output until done(pose) holds for
// a pose or `timeout` passes.
struct Collected {
  std::vector<json> poses;
  json stats;
};
template <class Done>
Collected collect(test::SocketClient& client, Done done, std::chrono::milliseconds timeout) {
  Collected c;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    auto m = client.receive_any(std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now()));
    if (!m) break;
    if (m->first == "stats") c.stats = m->second;
    if (m->first != "pose") continue;
    c.poses.push_back(std::move(m->second));
    if (done(c.poses.back())) break;
  }
  return c;
}

// A value as the protocol carries it: through a 32-bit float in memory (GCC
// may drop a double -> float -> double round trip held in registers).
double through_float(double v) {
  volatile float f = static_cast<float>(v);
  return static_cast<double>(f);
}

enum class Protocol { qtm, natnet };

// The recording index a server's frame number stands for: QTM numbers from 1,
// the Motive simulator from 0 (as its frame counter does).
std::int64_t index_of(Protocol p, std::uint64_t frame) {
  return static_cast<std::int64_t>(frame) - (p == Protocol::qtm ? 1 : 0);
}

// What the protocol hands the daemon for a recording position (mm): QTM sends
// float mm, NatNet float metres (the simulator rotates +y up to Motive's +y up:
// no rotation for a TRC).
Eigen::Vector3d as_carried_mm(Protocol p, const Eigen::Vector3d& p_mm) {
  Eigen::Vector3d r;
  for (int a = 0; a < 3; ++a)
    r[a] = p == Protocol::qtm ? through_float(p_mm[a]) : through_float(p_mm[a] / 1000.0) * 1000.0;
  return r;
}

// The ZeroMQ frame with the same number, time and (carried) positions.
// The frame's time as the protocol carries it (the pose prints it rounded,
// and the tracker's gap filling reads it): QTM stamps whole microseconds,
// Motive's timestamp is a double.
double carried_time_s(Protocol p, const bridges::SimRecording& rec, std::uint64_t frame) {
  const auto g = static_cast<double>(index_of(p, frame));
  return p == Protocol::qtm ? static_cast<double>(std::llround(g * 1e6 / rec.rate_hz)) * 1e-6 : g / rec.rate_hz;
}

// The markers in the server's order (nlohmann::json would sort them).
nlohmann::ordered_json zmq_frame(Protocol p, const bridges::SimRecording& rec, std::uint64_t frame, double time_s,
                                 bool carried) {
  const std::int64_t g = index_of(p, frame);
  const auto& row = rec.p_mm[static_cast<std::size_t>(g) % rec.p_mm.size()];
  nlohmann::ordered_json markers = nlohmann::ordered_json::object();
  for (std::size_t m = 0; m < rec.names.size(); ++m) {
    if (!row[m].allFinite()) {
      markers[rec.names[m]] = nullptr;
      continue;
    }
    const Eigen::Vector3d v = carried ? as_carried_mm(p, row[m]) : row[m];
    markers[rec.names[m]] = {v.x(), v.y(), v.z()};
  }
  return {{"frame", frame}, {"time", time_s}, {"units", "mm"}, {"markers", markers}};
}

// Whether every one of the recording's `frames` has been posed at least once,
// fed the poses one by one.
struct Coverage {
  Protocol p;
  std::vector<bool> seen;
  std::size_t covered = 0;
  bool operator()(const json& pose) {
    const auto index =
        static_cast<std::size_t>(index_of(p, pose["frame"].get<std::uint64_t>())) % seen.size();
    if (!seen[index]) ++covered;
    seen[index] = true;
    return covered == seen.size();
  }
};

struct Comparison {
  std::size_t frames = 0, covered = 0;
  double joints_mm = 0, markers_mm = 0, time_s = 0;
  bool same_occluded = true;
};

// Runs `rec` through the simulated server of `p` into a daemon of `config`,
// looping through the file until every recording frame has been posed once
// (a loaded host may lose a frame in one pass: UDP, or a daemon behind its
// source), then the same frames, in the same order, over ZeroMQ into a
// second daemon; compares pose by pose.
// `reference_rec`: the recording whose frames the reference daemon gets over ZeroMQ (by
// default the one served).
Comparison through_simulator(Protocol p, const DaemonConfig& config,
                             const bridges::SimRecording& rec, bool carried_reference,
                             const bridges::SimRecording* reference_rec = nullptr) {
  zmq::context_t context;
  bridges::SimScript script;
  script.loop = true;
  // Bounded, so that a source that never covers the file ends the test.
  script.max_frames = 20 * static_cast<std::int64_t>(rec.p_mm.size());
  script.rate_scale = 3.0;
  // Held back while the daemon connects: frames served before it streams are
  // lost to it, and the test needs every recording frame posed once.
  script.pauses.push_back({0, 0.3});
  DaemonConfig with_source = on_inproc(config, p == Protocol::qtm ? "qtm-walk" : "natnet-walk");
  // A daemon behind its source (a sanitizer build, a loaded host) answers every frame late
  // instead of superseding the waiting ones: the passes then only have to make up for UDP.
  with_source.max_backlog_frames = 10000;
  std::unique_ptr<qtm::QtmSimServer> qtm_server;
  std::unique_ptr<bridges::NatNetSimServer> natnet_server;
  if (p == Protocol::qtm) {
    qtm_server = std::make_unique<qtm::QtmSimServer>(rec, script, any_free_ports());
    with_source.source = source_of(R"({"source": "qtm://127.0.0.1:)" +
                                   std::to_string(qtm_server->port_little_endian()) + "\"}");
  } else {
    bridges::NatNetSimServer::Options o;
    o.command_port = 0;
    o.data_port = 0;
    o.multicast = false;  // unicast: parallel tests do not share a group and port
    natnet_server = std::make_unique<bridges::NatNetSimServer>(rec, script, o);
    with_source.source = source_of(R"({"source": "natnet://127.0.0.1:)" +
                                   std::to_string(natnet_server->command_port()) +
                                   R"(", "source_options": {"natnet_data": "unicast"}})");
  }

  Collected got;
  {
    DaemonThread daemon(context, with_source);
    test::SocketClient client(context, "inproc://" + std::string(p == Protocol::qtm ? "qtm" : "natnet") + "-walk-markers",
                              "inproc://" + std::string(p == Protocol::qtm ? "qtm" : "natnet") + "-walk-poses");
    REQUIRE(client.receive("stats"));  // subscribed before the server streams
    std::optional<ServerThread<qtm::QtmSimServer>> qtm_thread;
    std::optional<ServerThread<bridges::NatNetSimServer>> natnet_thread;
    if (qtm_server) qtm_thread.emplace(*qtm_server);
    if (natnet_server) natnet_thread.emplace(*natnet_server);
    // (stats go on after the server's last frame: a source that never covers the file fails at the
    // timeout)
    got = collect(client, Coverage{p, std::vector<bool>(rec.p_mm.size(), false)}, 60s);
  }
  REQUIRE(!got.poses.empty());

  // The reference: the frames the source daemon posed, in its order, over ZeroMQ.
  Comparison c;
  DaemonThread reference(context, on_inproc(config, "reference"));
  test::SocketClient client(context, "inproc://reference-markers", "inproc://reference-poses");
  REQUIRE(client.receive("stats"));
  std::vector<bool> seen(rec.p_mm.size(), false);
  for (const json& pose : got.poses) {
    const auto frame = pose["frame"].get<std::uint64_t>();
    client.send(zmq_frame(p, reference_rec ? *reference_rec : rec, frame,
                          carried_time_s(p, rec, frame), carried_reference)
                    .dump());
    const auto ref = client.receive("pose");
    REQUIRE(ref);
    REQUIRE((*ref)["frame"] == pose["frame"]);
    ++c.frames;
    seen[static_cast<std::size_t>(index_of(p, frame)) % seen.size()] = true;
    c.time_s = std::max(c.time_s, std::abs(pose["time"].get<double>() -
                                           static_cast<double>(index_of(p, frame)) / rec.rate_hz));
    c.joints_mm = std::max(c.joints_mm, largest_difference(pose["joints"], (*ref)["joints"]));
    c.markers_mm = std::max(c.markers_mm, largest_difference(pose["markers"], (*ref)["markers"]));
    c.same_occluded = c.same_occluded && pose["occluded"] == (*ref)["occluded"];
  }
  for (const bool s : seen) c.covered += s ? 1 : 0;
  return c;
}

struct Walk1 {
  bool present = false;
  std::string static_path, walk_path;
  Walk1() {
    const std::string dir = FABRIK_SHARED_DATA_DIR;
    static_path = dir + "/subject01_static.trc";
    walk_path = dir + "/subject01_walk1.trc";
    present = std::filesystem::exists(static_path) && std::filesystem::exists(walk_path);
    if (!present)
      WARN("SKIPPED: " << static_path << " or " << walk_path << " is absent (real data lives in ../shared/data)");
  }
};

}  // namespace

TEST_CASE("walk1 through the simulated QTM and Motive gives the poses of the same frames over ZeroMQ "
          "(skipped without ../shared/data)",
          "[source][daemon][data]") {
  spdlog::set_level(spdlog::level::err);
  const Walk1 walk1;
  if (!walk1.present) return;
  const DaemonConfig config = eval::calibrate_config(
      std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json", walk1.static_path);
  const bridges::SimRecording rec = tools::sim_recording(io::read_trial(walk1.walk_path), "");
  REQUIRE(rec.up == "+y");
  // A TRC is in the lab's axes; Motive's default (Y up, forward +x) must be
  // the calibrated lab's for the NatNet frames to need no rotation.
  const LabAxes motive{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()};
  REQUIRE(config.tracker.model->lab_axes.r_from(motive).isIdentity(0.0));

  for (const Protocol p : {Protocol::qtm, Protocol::natnet}) {
    INFO((p == Protocol::qtm ? "QTM" : "NatNet"));
    const Comparison c = through_simulator(p, config, rec, true);
    CHECK(c.covered == rec.p_mm.size());  // every frame of the file posed at least once
    CHECK(c.frames >= rec.p_mm.size());
    // The positions as the protocol carries them (float), the same frame and
    // time: the same pose, to rounding.
    CHECK(c.time_s < 1e-6);
    CHECK(c.joints_mm < 1e-6);
    CHECK(c.markers_mm < 1e-6);
    CHECK(c.same_occluded);
  }
}

namespace {

// A recording of the embedded default model's synthetic motion, in its lab axes.
bridges::SimRecording synthetic_recording(const DaemonConfig& config, int frames, double rate_hz) {
  const Model& model = *config.tracker.model;
  bridges::SimRecording rec;
  rec.rate_hz = rate_hz;
  rec.up = "+y";
  for (const MarkerTarget& t : config.tracker.markers) rec.names.push_back(t.marker);
  SyntheticMotion motion(model, MotionSettings{});
  Posture posture = Posture::rest(model);
  for (int i = 0; i < frames; ++i) {
    motion.posture_at(i / rate_hz, posture);
    std::vector<Eigen::Vector3d> row;
    for (const MarkerTarget& t : config.tracker.markers) row.push_back(posture.point_world_m(model, t.point) * 1e3);
    rec.p_mm.push_back(row);
  }
  return rec;
}

bool occluded(const json& pose, const std::string& marker) {
  for (const json& m : pose["occluded"])
    if (m == marker) return true;
  return false;
}

}  // namespace

TEST_CASE(
    "QTM's stated up axis is taken where the config declares none: a Z-up QTM lab "
    "gives a Y-up model the poses of its own axes",
    "[source][daemon][lab_axes]") {
  spdlog::set_level(spdlog::level::err);
  const DaemonConfig config = default_daemon_config();
  REQUIRE(config.tracker.model->lab_axes.up_lab == Eigen::Vector3d::UnitY());
  const bridges::SimRecording y_up = synthetic_recording(config, 200, 100.0);
  // The same motion as a Z-up QTM lab measures it (forward +x): lab (x, y, z) is QTM's (x, -z, y).
  bridges::SimRecording z_up = y_up;
  z_up.up = "+z";
  for (std::vector<Eigen::Vector3d>& row : z_up.p_mm)
    for (Eigen::Vector3d& p : row) p = Eigen::Vector3d(p.x(), -p.z(), p.y());
  const test::LogCapture log;  // before the daemon: outlives it
  const Comparison c = through_simulator(Protocol::qtm, config, z_up, true, &y_up);
  // Said once, where the user looks: the log.
  CHECK_THAT(log.find("warning", "the server's up axis is +z, the model's lab axes are +y up"),
             Catch::Contains("positions are turned from up +z, forward +x"));
  CHECK(c.covered == y_up.p_mm.size());
  CHECK(c.joints_mm < 1e-6);  // was hundreds of mm: the frames were taken unturned
  CHECK(c.markers_mm < 1e-6);
  CHECK(c.same_occluded);
}

TEST_CASE("Motive's axes, which NatNet does not state, are said in the log as assumed",
          "[source][daemon][lab_axes]") {
  // A Z-up Motive read as Y-up gave pelvis angles at gimbal lock with a "good" fit and no word.
  const DaemonConfig config = default_daemon_config();
  const bridges::SimRecording rec = synthetic_recording(config, 60, 100.0);
  const test::LogCapture log;  // before the daemon: outlives it
  const Comparison c = through_simulator(Protocol::natnet, config, rec, true, nullptr);
  CHECK(c.frames > 0);
  CHECK_THAT(log.find("info", "connected to Motive"),
             Catch::Contains("Motive's axes taken as its default, Y up and forward +x (NatNet "
                             "does not state them): if Motive streams Z up, set "
                             "source_options.axes"));
}

TEST_CASE("Labels changed mid-stream and a server restart: the renamed marker is occluded and unknown, "
          "the source reconnects and the frames go on",
          "[source][daemon]") {
  spdlog::set_level(spdlog::level::err);
  const DaemonConfig config = default_daemon_config();
  const bridges::SimRecording rec = synthetic_recording(config, 300, 100.0);
  const std::string renamed = rec.names.at(3);
  bridges::SimScript script;
  script.rate_scale = 2.0;
  script.pauses.push_back({0, 0.3});  // while the daemon connects (see above)
  script.renames.push_back({50, renamed, renamed + "_NEW"});
  script.restarts.push_back({100, 0.3});

  for (const Protocol p : {Protocol::qtm, Protocol::natnet}) {
    INFO((p == Protocol::qtm ? "QTM" : "NatNet"));
    zmq::context_t context;
    const std::string name = p == Protocol::qtm ? "qtm-script" : "natnet-script";
    DaemonConfig with_source = on_inproc(config, name);
    with_source.max_backlog_frames = 10000;  // late, not superseded, on a slow host (see above)
    // A short stall and backoff, so that the restart is seen and recovered from quickly.
    const std::string options =
        R"("connect_timeout_s": 1, "stall_timeout_s": 0.2, "reconnect_min_s": 0.05, "reconnect_max_s": 0.2)";
    std::unique_ptr<qtm::QtmSimServer> qtm_server;
    std::unique_ptr<bridges::NatNetSimServer> natnet_server;
    if (p == Protocol::qtm) {
      qtm_server = std::make_unique<qtm::QtmSimServer>(rec, script, any_free_ports());
      with_source.source = source_of(R"({"source": "qtm://127.0.0.1:)" +
                                     std::to_string(qtm_server->port_little_endian()) +
                                     R"(", "source_options": {)" + options + "}}");
    } else {
      bridges::NatNetSimServer::Options o;
      o.command_port = 0;
      o.data_port = 0;
      o.multicast = false;
      natnet_server = std::make_unique<bridges::NatNetSimServer>(rec, script, o);
      with_source.source = source_of(R"({"source": "natnet://127.0.0.1:)" +
                                     std::to_string(natnet_server->command_port()) +
                                     R"(", "source_options": {"natnet_data": "unicast", )" + options + "}}");
    }
    DaemonThread daemon(context, with_source);
    test::SocketClient client(context, "inproc://" + name + "-markers", "inproc://" + name + "-poses");
    REQUIRE(client.receive("stats"));
    std::optional<ServerThread<qtm::QtmSimServer>> qtm_thread;
    std::optional<ServerThread<bridges::NatNetSimServer>> natnet_thread;
    if (qtm_server) qtm_thread.emplace(*qtm_server);
    if (natnet_server) natnet_thread.emplace(*natnet_server);
    const std::uint64_t last = p == Protocol::qtm ? 300 : 299;
    const Collected got = collect(
        client, [last](const json& pose) { return pose["frame"] == last; }, 20s);
    REQUIRE(!got.poses.empty());
    CHECK(got.poses.back()["frame"] == last);

    // Before the rename the marker is measured; from shortly after it (the
    // labels are re-read on QTM's event / Motive's model change), before the
    // restart, it is occluded, and stays so across the restart. Properties of
    // the frames posed, not counts in windows of wall-clock time: a loaded
    // host connects late and reconnects slowly.
    std::optional<std::int64_t> first_renamed;  // the first frame posed with the marker occluded
    std::size_t measured_before = 0, occluded_before = 0, measured_after_renamed = 0,
                occluded_poses = 0, after_restart = 0;
    for (const json& pose : got.poses) {
      const std::int64_t g = index_of(p, pose["frame"].get<std::uint64_t>());
      const bool hidden = occluded(pose, renamed);
      if (g < 50) (hidden ? occluded_before : measured_before) += 1;
      if (hidden) {
        ++occluded_poses;
        if (!first_renamed) first_renamed = g;
      } else if (first_renamed) {
        ++measured_after_renamed;
      }
      if (g >= 150) ++after_restart;
    }
    CHECK(measured_before >= 1);
    CHECK(occluded_before == 0);
    REQUIRE(first_renamed);
    CHECK(*first_renamed >= 50);
    CHECK(*first_renamed < 100);  // the labels re-read in the stream, not at the reconnect
    CHECK(measured_after_renamed == 0);
    CHECK(after_restart >= 1);  // streaming resumed after the restart
    // The stats: two connections (one reconnect), the renamed marker unknown, no frame lost by
    // fabrikd.
    // A client counts a frame before handing it over (the client tests check it): stats sent
    // after the last pose count every frame posed. The wait bounds the reconnect's stats.
    const std::size_t posed = got.poses.size();
    const auto stats = client.stats_until(
        [posed](const json& s) {
          return s["source"]["reconnects"] >= 1 && s["source"]["frames"] >= posed;
        },
        5s);
    REQUIRE(stats);
    const json& source = (*stats)["source"];
    // (not `connected`: the server's script has ended by now, or is about to)
    CHECK(source["connections"] >= 2);
    CHECK(source["reconnects"] >= 1);
    CHECK(source["frames_dropped"] == 0);
    CHECK(source["frames"] >= got.poses.size());
    CHECK(source["frames"] <= rec.p_mm.size());  // each served frame counted once
    CHECK(source["last_error"].is_string());  // what the restart looked like to the client
    CHECK((*stats)["unknown_markers"] >=
          occluded_poses);  // each frame posed with the new name counted
    CHECK((*stats)["frames_dropped"] == 0);
    UNSCOPED_INFO("stats after the rename and restart: " << source.dump());
  }
}
