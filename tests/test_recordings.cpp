// Real recordings through the daemon: Vicon.c3d (43 upper-body markers with
// real occlusions, 580 frames) streamed frame by frame over real sockets.
// Skips with a message when ../shared/data is absent.
#include <catch2/catch.hpp>
#include <filesystem>
#include <thread>

#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "daemon_thread.hpp"
#include "io/marker_trial.hpp"
#include "model_message.hpp"
#include "socket_client.hpp"
#include "transport/daemon.hpp"
#include "transport/marker_codec.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

// A shipped template calibrated on `trial` (as `fabrik calibrate` writes it),
// loaded as a daemon config named `name`, on inproc endpoints of `tag`.
DaemonConfig calibrated(const std::string& template_name, const io::MarkerTrial& trial,
                        const std::string& trial_path, const std::string& name,
                        const std::string& tag, const calib::CalibrateOptions& window = {}) {
  const calib::CalibTemplate tmpl =
      calib::load_template_file(FABRIK_SOURCE_DIR "/config/templates/" + template_name);
  const calib::CalibrationResult cal = calib::calibrate(tmpl, trial, trial_path, window);
  DaemonConfig config = load_daemon_config(cal.config.dump(), name);
  config.input = {"inproc://" + tag + "-in", SocketMode::bind};
  config.output = {"inproc://" + tag + "-out", SocketMode::bind};
  spdlog::set_level(spdlog::level::err);
  return config;
}

}  // namespace

TEST_CASE("Vicon.c3d with its real gaps streams through fabrikd without losing a frame",
          "[daemon][data]") {
  const std::string path = FABRIK_SHARED_DATA_DIR "/Vicon.c3d";
  if (!std::filesystem::exists(path)) {
    WARN("skipped: " << path << " is absent (the shared real-data folder is not beside the repo)");
    return;
  }
  const io::MarkerTrial trial = io::read_c3d(path);
  calib::CalibrateOptions window;
  window.first_frame = trial.first_frame;
  window.frames = 20;  // the subject stands still at the start, every marker visible
  const DaemonConfig config = calibrated("vicon_upper_body.json", trial, path,
                                         "<calibrated from Vicon.c3d>", "vicon", window);

  zmq::context_t context;
  wire::Daemon daemon(context, config);
  wire::DaemonControl control;
  std::thread thread([&] { daemon.run(control); });
  struct Join {
    wire::DaemonControl& c;
    std::thread& t;
    ~Join() {
      c.stop = true;
      t.join();
    }
  } join{control, thread};

  test::SocketClient client(context, daemon.input_endpoint(), daemon.output_endpoint());
  client.handshake();
  const auto errors_before = daemon.counters();

  // Every label of the file goes out as recorded (the 8 box markers are unknown to the model).
  std::vector<std::string> labels = trial.labels;
  std::vector<std::uint8_t> visible(labels.size());
  std::vector<Eigen::Vector3d> p(labels.size());
  std::string payload;
  std::size_t occluded_samples = 0, max_occluded = 0;
  double max_jump_mm = 0.0;
  json previous;
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    for (std::size_t m = 0; m < labels.size(); ++m) {
      p[m] = trial.at(f, m);
      visible[m] = p[m].allFinite() ? 1 : 0;
    }
    const double t = trial.time_s(f);
    wire::encode_marker_frame(f, &t, labels, p, visible, "mm", wire::PayloadEncoding::msgpack,
                              payload);
    client.send(payload);
    const auto pose = client.receive("pose");
    REQUIRE(pose);
    REQUIRE((*pose)["frame"] == f);
    // The occluded list is exactly the model's markers missing in this frame.
    std::size_t missing = 0;
    for (const MarkerTarget& mt : config.tracker.markers) {
      const int col = trial.find(mt.marker);
      REQUIRE(col >= 0);
      const bool gone = !trial.at(f, col).allFinite();
      missing += gone ? 1 : 0;
      const auto& occ = (*pose)["occluded"];
      CHECK((std::find(occ.begin(), occ.end(), mt.marker) != occ.end()) == gone);
      // Predicted (or fitted) positions are always there, and move smoothly:
      // a gap-filled marker does not jump at 100 Hz.
      const json& q = (*pose)["markers"][mt.marker];
      REQUIRE(q.is_array());
      if (!previous.is_null()) {
        double d2 = 0;
        for (int k = 0; k < 3; ++k)
          d2 += std::pow(q[k].get<double>() - previous["markers"][mt.marker][k].get<double>(), 2);
        if (gone) max_jump_mm = std::max(max_jump_mm, std::sqrt(d2));
      }
    }
    occluded_samples += missing;
    max_occluded = std::max(max_occluded, missing);
    CHECK((*pose)["residual"]["count"] == config.tracker.markers.size() - missing);
    previous = *pose;
  }
  const wire::DaemonCounters c = daemon.counters();
  CHECK(c.frames_out - errors_before.frames_out == trial.frames());
  CHECK(c.frames_dropped == errors_before.frames_dropped);
  CHECK(c.decode_errors == errors_before.decode_errors);
  CHECK(c.unknown_markers - errors_before.unknown_markers == 8 * trial.frames());
  CHECK(occluded_samples > 200);  // the file's real gaps on the subject's markers
  CHECK(max_jump_mm < 40.0);      // mm per frame for a gap-filled marker
  WARN("Vicon.c3d: "
       << trial.frames() << " frames, " << occluded_samples << " occluded samples predicted, up to "
       << max_occluded
       << " markers missing in a frame; largest frame-to-frame step of a predicted marker "
       << max_jump_mm << " mm");
}

TEST_CASE(
    "gait2354 calibrated on subject01_static: the model message names exactly what its poses "
    "name, with the joints' ranges (skipped without ../shared/data)",
    "[daemon][model][data]") {
  const std::string static_path = FABRIK_SHARED_DATA_DIR "/subject01_static.trc";
  const std::string walk_path = FABRIK_SHARED_DATA_DIR "/subject01_walk1.trc";
  if (!std::filesystem::exists(static_path) || !std::filesystem::exists(walk_path)) {
    WARN("skipped: " << static_path << " or " << walk_path << " is absent");
    return;
  }
  const DaemonConfig config = calibrated("gait2354.json", io::read_trial(static_path), static_path,
                                         "<calibrated gait2354>", "gait2354");
  zmq::context_t context;
  test::DaemonThread d(context, config);
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  const auto model = client.receive("model");  // on subscribing to everything
  REQUIRE(model);
  CHECK((*model)["config"] == "<calibrated gait2354>");
  // A frame of the walk as recorded, and its pose.
  const io::MarkerTrial walk = io::read_trial(walk_path);
  std::vector<std::uint8_t> visible(walk.labels.size());
  std::vector<Eigen::Vector3d> p(walk.labels.size());
  for (std::size_t m = 0; m < walk.labels.size(); ++m) {
    p[m] = walk.at(0, m);
    visible[m] = p[m].allFinite() ? 1 : 0;
  }
  std::string payload;
  const double t = walk.time_s(0);
  wire::encode_marker_frame(0, &t, walk.labels, p, visible, "mm", wire::PayloadEncoding::json,
                            payload);
  client.handshake();
  client.send(payload);
  std::optional<json> pose;
  for (pose = client.receive("pose"); pose && (*pose)["frame"] != 0;
       pose = client.receive("pose")) {
  }
  REQUIRE(pose);
  test::check_model_matches_pose(*model, *pose);
  // Every joint of the template is limited: a coordinate that is one joint's angle has its
  // range; one across two joints (lumbar over the abdomen, arm over the clavicle) has none.
  int ranged = 0;
  std::string unranged;
  for (const json& c : (*model)["coordinates"]) {
    if (c["min_deg"].is_number() && c["min_deg"].get<double>() < c["max_deg"].get<double>())
      ++ranged;
    else
      unranged += " " + c["name"].get<std::string>();
  }
  INFO("coordinates without a range:" << unranged);
  CHECK(ranged >= 17);
  CHECK(unranged.find("knee_angle_r") == std::string::npos);
  CHECK(unranged.find("lumbar_extension") != std::string::npos);
  WARN("gait2354 model message: " << (*model)["joints"].size() << " joints, "
                                  << (*model)["bones"].size() << " bones, "
                                  << (*model)["markers"].size() << " markers, " << ranged
                                  << " ranged coordinates; without a range:" << unranged);
}
