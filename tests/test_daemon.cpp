// The daemon loop over real ZeroMQ sockets (inproc and loopback tcp with
// ports chosen by the system), running on its own thread.
#include <catch2/catch.hpp>
#include <thread>

#include "config/daemon_config.hpp"
#include "socket_client.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/daemon.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

// A daemon on a thread, stopped and joined on destruction.
struct RunningDaemon {
  RunningDaemon(zmq::context_t& context, DaemonConfig config)
      : daemon(context, std::move(config)), thread([this] { daemon.run(control); }) {}
  ~RunningDaemon() {
    control.stop = true;
    thread.join();
  }
  wire::Daemon daemon;
  wire::DaemonControl control;
  std::thread thread;
};

DaemonConfig config_on(const std::string& input, const std::string& output) {
  DaemonConfig c = default_daemon_config();
  c.input = {input, SocketMode::bind};
  c.output = {output, SocketMode::bind};
  c.stats_interval_s = 0.05;
  spdlog::set_level(spdlog::level::err);
  return c;
}

// Marker positions (mm, JSON) of the synthetic motion at time t, with some markers left out.
json markers_at(const DaemonConfig& c, SyntheticMotion& motion, double t_s,
                const std::vector<std::string>& hidden = {}) {
  const Model& m = *c.tracker.model;
  Posture p = Posture::rest(m);
  motion.posture_at(t_s, p);
  json out = json::object();
  for (const MarkerTarget& t : c.tracker.markers) {
    if (std::find(hidden.begin(), hidden.end(), t.marker) != hidden.end()) continue;
    const Eigen::Vector3d x = p.point_world_m(m, t.point) * 1e3;
    out[t.marker] = {x.x(), x.y(), x.z()};
  }
  return out;
}

}  // namespace

TEST_CASE("N frames in give N poses out with matching frame numbers, inproc and tcp", "[daemon]") {
  zmq::context_t context;
  for (auto [in, out] : {std::pair{"inproc://markers-a", "inproc://poses-a"},
                         std::pair{"tcp://127.0.0.1:*", "tcp://127.0.0.1:*"}}) {
    RunningDaemon d(context, config_on(in, out));
    test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
    const std::uint64_t first = client.handshake();
    MotionSettings ms;
    SyntheticMotion motion(*d.daemon.config().tracker.model, ms);
    const int n = 200;
    for (int i = 0; i < n; ++i) {
      const std::uint64_t frame = first + static_cast<std::uint64_t>(i);
      client.send(json{{"frame", frame},
                       {"time", i * 0.01},
                       {"markers", markers_at(d.daemon.config(), motion, i * 0.01)}}
                      .dump());
      const auto pose = client.receive("pose");
      REQUIRE(pose);
      CHECK((*pose)["frame"] == frame);
      CHECK((*pose)["occluded"].empty());
      CHECK((*pose)["residual"]["rms"].get<double>() < 1.0);  // mm: noise-free motion
    }
    const wire::DaemonCounters c = d.daemon.counters();
    CHECK(c.decode_errors == 0);
    CHECK(c.frames_out == c.frames_in);
  }
}

TEST_CASE("Occluded markers are listed and predicted by the model", "[daemon]") {
  zmq::context_t context;
  RunningDaemon d(context, config_on("inproc://markers-b", "inproc://poses-b"));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  const std::uint64_t first = client.handshake();
  const DaemonConfig& c = d.daemon.config();
  MotionSettings ms;
  SyntheticMotion motion(*c.tracker.model, ms);
  SyntheticMotion truth_motion(*c.tracker.model, ms);
  const std::vector<std::string> hidden = {"RKNE", "LWRA", "RFHD"};
  for (int i = 0; i < 100; ++i) {
    const double t = i * 0.01;
    json m = markers_at(c, motion, t, i < 20 ? std::vector<std::string>{} : hidden);
    if (i >= 20) m["RKNE"] = nullptr;  // null and absent both mean occluded
    client.send(json{{"frame", first + i}, {"time", t}, {"markers", m}}.dump());
    const auto pose = client.receive("pose");
    REQUIRE(pose);
    if (i < 20) continue;
    CHECK((*pose)["occluded"].size() == hidden.size());
    for (const std::string& name : hidden) {
      CHECK(std::find((*pose)["occluded"].begin(), (*pose)["occluded"].end(), name) !=
            (*pose)["occluded"].end());
      const json truth = markers_at(c, truth_motion, t)[name];
      const json predicted = (*pose)["markers"][name];
      double d2 = 0;
      for (int k = 0; k < 3; ++k)
        d2 += std::pow(predicted[k].get<double>() - truth[k].get<double>(), 2);
      CAPTURE(name, i);
      CHECK(std::sqrt(d2) < 5.0);  // mm: the rest of the segment holds it in place
    }
    CHECK((*pose)["residual"]["count"] == c.tracker.markers.size() - hidden.size());
  }
}

TEST_CASE("Every bad input is counted and the next valid frame is answered", "[daemon]") {
  zmq::context_t context;
  DaemonConfig cfg = config_on("tcp://127.0.0.1:*", "tcp://127.0.0.1:*");
  cfg.max_payload_bytes = 8192;
  RunningDaemon d(context, std::move(cfg));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  std::uint64_t frame = client.handshake();
  const auto errors_before = d.daemon.counters().decode_errors;
  std::string nested = R"({"frame": 1, "x": )";
  for (int i = 0; i < 10000; ++i) nested += "[";
  std::string random_bytes;
  std::mt19937 rng(3);
  for (int i = 0; i < 2000; ++i) random_bytes += static_cast<char>(rng() & 0xff);
  const std::vector<std::string> bad_payloads = {
      "{not json",
      R"({"frame": "one"})",
      R"({"markers": {}})",
      R"({"frame": 1, "markers": {"RASI": [1, NaN, 2]}})",
      R"({"frame": 1, "markers": {"RASI": [1, 2]}})",
      std::string(100000, '{'),
      nested,
      random_bytes,
      std::string("\xde\xff\xff", 3),
      std::string("\x81\xa5"
                  "frame\xc1",
                  8)};
  int sent_bad = 0;
  auto answer_next = [&] {
    client.send_frame(++frame);
    const auto pose = client.receive("pose");
    REQUIRE(pose);
    CHECK((*pose)["frame"] == frame);
  };
  for (const std::string& p : bad_payloads) {
    client.send(p);
    ++sent_bad;
    answer_next();
  }
  // Wrong numbers of message parts and a wrong topic on the markers prefix.
  client.send_parts({"markers"});
  answer_next();
  client.send_parts({"markers", json{{"frame", 5}}.dump(), "third"});
  answer_next();
  client.send(json{{"frame", 5}}.dump(), "markersX");
  answer_next();
  sent_bad += 3;
  CHECK(d.daemon.counters().decode_errors - errors_before == static_cast<std::uint64_t>(sent_bad));
  // Stats report the same count.
  for (;;) {
    const auto stats = client.receive("stats");
    REQUIRE(stats);
    if ((*stats)["decode_errors"].get<std::uint64_t>() - errors_before ==
        static_cast<std::uint64_t>(sent_bad)) {
      CHECK((*stats)["last_error"].is_string());
      break;
    }
  }
}

TEST_CASE("When input outpaces the solver the newest frame wins and the rest are counted",
          "[daemon]") {
  zmq::context_t context;
  RunningDaemon d(context, config_on("inproc://markers-c", "inproc://poses-c"));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  std::uint64_t frame = client.handshake();
  const wire::DaemonCounters before = d.daemon.counters();
  const int burst = 500;
  MotionSettings ms;
  SyntheticMotion motion(*d.daemon.config().tracker.model, ms);
  const std::string payload_markers = markers_at(d.daemon.config(), motion, 0.3).dump();
  for (int i = 0; i < burst; ++i)
    client.send(R"({"frame": )" + std::to_string(++frame) + R"(, "markers": )" + payload_markers +
                "}");
  // The last frame of the burst is always answered.
  std::uint64_t last = 0;
  int poses = 0;
  while (last != frame) {
    const auto pose = client.receive("pose");
    REQUIRE(pose);
    last = (*pose)["frame"].get<std::uint64_t>();
    ++poses;
  }
  const wire::DaemonCounters after = d.daemon.counters();
  CHECK(after.frames_in - before.frames_in == burst);
  CHECK(after.frames_out - before.frames_out == static_cast<std::uint64_t>(poses));
  CHECK((after.frames_out - before.frames_out) + (after.frames_dropped - before.frames_dropped) ==
        burst);
}

TEST_CASE("Stats arrive every interval with the contract's fields", "[daemon]") {
  zmq::context_t context;
  RunningDaemon d(context, config_on("inproc://markers-d", "inproc://poses-d"));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  client.handshake();
  client.send(json{{"frame", 1}, {"markers", {{"NOT_A_MARKER", {1, 2, 3}}}}}.dump());
  REQUIRE(client.receive("pose"));
  const auto stats = client.receive("stats");
  REQUIRE(stats);
  for (const char* key : {"uptime_s", "frames_in", "frames_out", "frames_dropped", "decode_errors",
                          "unknown_markers", "solve_us", "queue_latency_us"})
    CHECK(stats->contains(key));
  for (const char* key : {"p50", "p99", "max"}) CHECK((*stats)["solve_us"].contains(key));
  CHECK(d.daemon.counters().unknown_markers >= 1);
}

TEST_CASE("MessagePack output carries the same pose", "[daemon]") {
  zmq::context_t context;
  DaemonConfig cfg = config_on("inproc://markers-e", "inproc://poses-e");
  cfg.output_encoding = Encoding::msgpack;
  RunningDaemon d(context, std::move(cfg));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  const std::uint64_t frame = client.handshake();
  client.send_frame(frame, {{"RASI", {10, 950, 120}}});
  const auto pose = client.receive("pose");
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
  CHECK((*pose)["residual"]["worst"] == "RASI");
}

TEST_CASE("A subscriber that never reads does not block the daemon", "[daemon]") {
  zmq::context_t context;
  RunningDaemon d(context, config_on("tcp://127.0.0.1:*", "tcp://127.0.0.1:*"));
  // The stalled subscriber: tiny buffers, never reads.
  zmq::socket_t stalled(context, zmq::socket_type::sub);
  stalled.set(zmq::sockopt::rcvhwm, 1);
  stalled.set(zmq::sockopt::rcvbuf, 4096);
  stalled.set(zmq::sockopt::linger, 0);
  stalled.set(zmq::sockopt::subscribe, "");
  stalled.connect(d.daemon.output_endpoint());
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  std::uint64_t frame = client.handshake();
  MotionSettings ms;
  SyntheticMotion motion(*d.daemon.config().tracker.model, ms);
  const std::string markers = markers_at(d.daemon.config(), motion, 0.2).dump();
  // Far more pose bytes than the stalled subscriber's buffers hold (about 5 kB a pose).
  for (int i = 0; i < 3000; ++i) {
    client.send(R"({"frame": )" + std::to_string(++frame) + R"(, "markers": )" + markers + "}");
    const auto pose = client.receive("pose");
    REQUIRE(pose);
    REQUIRE((*pose)["frame"] == frame);
  }
  CHECK(d.daemon.counters().frames_dropped == 0);
}
