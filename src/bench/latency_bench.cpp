#include "latency_bench.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <zmq.hpp>

#include "bridges/natnet_sim_server.hpp"
#include "bridges/qtm/sim_server.hpp"
#include "config/daemon_config.hpp"
#include "config/json_reader.hpp"
#include "config/lab_axes_json.hpp"
#include "config/pose_content.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/daemon.hpp"
#include "transport/marker_codec.hpp"
#include "zmq_floor.hpp"

namespace fabrik::bench {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

// The topic of `--view`'s view.
constexpr const char* kViewTopic = "bench";

// Issue 22's goals against the floor: the daemon's p50 at most this far
// above the floor's p50, its p99 at most this far above the floor's p99.
constexpr double kGoalP50Us = 15.0;
constexpr double kGoalP99Us = 50.0;

// The frame number of a pose, without decoding the rest of it.
bool pose_frame(const zmq::message_t& m, std::uint64_t& frame) {
  const std::optional<std::uint64_t> f =
      frame_number({static_cast<const std::uint8_t*>(m.data()), m.size()});
  if (f) frame = *f;
  return f.has_value();
}

// The bench's side of a daemon or of the floor: a PUB on its marker input,
// a SUB on its poses.
struct Peer {
  zmq::socket_t pub, sub;
  zmq::message_t topic, body;
  // Where the daemon's stats messages go while measuring (subscribe to "stats" first);
  // null: dropped.
  std::vector<std::string>* stats = nullptr;

  Peer(zmq::context_t& context, const std::string& input, const std::string& output,
       const char* subscribe_to = "pose")
      : pub(context, zmq::socket_type::pub), sub(context, zmq::socket_type::sub) {
    pub.set(zmq::sockopt::linger, 0);
    sub.set(zmq::sockopt::linger, 0);
    sub.set(zmq::sockopt::subscribe, subscribe_to);
    sub.set(zmq::sockopt::rcvhwm, 0);
    pub.connect(input);
    sub.connect(output);
  }
  Peer(zmq::context_t& context, wire::Daemon& daemon, const char* subscribe_to = "pose")
      : Peer(context, daemon.input_endpoint(), daemon.output_endpoint(), subscribe_to) {}
  void send(const std::string& payload) {
    pub.send(zmq::buffer(std::string_view("markers")), zmq::send_flags::sndmore);
    pub.send(zmq::buffer(payload));
  }
  // A pose within timeout_ms: true with its frame number.
  bool receive(int timeout_ms, std::uint64_t& frame) {
    zmq::pollitem_t items[] = {{sub.handle(), 0, ZMQ_POLLIN, 0}};
    if (zmq::poll(items, 1, std::chrono::milliseconds(timeout_ms)) <= 0) return false;
    return read(frame);
  }
  // A pose that has arrived (the socket polled readable): true with its frame number.
  bool read(std::uint64_t& frame) {
    if (!sub.recv(topic, zmq::recv_flags::dontwait) || !topic.more()) return false;
    (void)sub.recv(body);
    if (topic.to_string_view() == "stats") {
      if (stats) stats->push_back(body_text());
      return false;
    }
    return pose_frame(body, frame);
  }
  std::string body_text() const { return {static_cast<const char*>(body.data()), body.size()}; }
};

// The daemon's loop on a thread, stopped and joined however the scope ends.
struct DaemonThread {
  wire::DaemonControl control;
  std::thread thread;
  explicit DaemonThread(wire::Daemon& daemon) : thread([this, &daemon] { daemon.run(control); }) {}
  ~DaemonThread() {
    control.stop = true;
    if (thread.joinable()) thread.join();
  }
};

// ipc endpoints' files, removed however the scope ends.
struct IpcFiles {
  std::vector<std::filesystem::path> paths;
  ~IpcFiles() {
    std::error_code ignored;
    for (const auto& p : paths) std::filesystem::remove(p, ignored);
  }
};

// p50, p90, p99 and max of one input's frames; sent[i] unset: not sent.
json input_figures(const std::vector<Clock::time_point>& sent_at,
                   const std::vector<std::uint8_t>& sent,
                   const std::vector<Clock::time_point>& received_at,
                   const std::vector<std::uint8_t>& received) {
  std::vector<double> latency_us;
  int n_sent = 0;
  for (std::size_t i = 0; i < sent.size(); ++i) {
    if (!sent[i]) continue;
    ++n_sent;
    if (received[i])
      latency_us.push_back(
          std::chrono::duration<double, std::micro>(received_at[i] - sent_at[i]).count());
  }
  const int n_received = static_cast<int>(latency_us.size());
  return {{"frames_sent", n_sent},
          {"poses_received", n_received},
          {"lost", n_sent - n_received},
          {"latency_us",
           {{"p50", quantile(latency_us, 0.5)},
            {"p90", quantile(latency_us, 0.9)},
            {"p99", quantile(latency_us, 0.99)},
            {"max", quantile(latency_us, 1.0)}}}};
}

// Who gets the k-th frame of a run: blocks of `block` frames, daemon and
// floor in turn as D F F D D F F D ..., so each goes first as often and
// a drift in the machine's state falls on both alike.
struct Slot {
  int path;   // kDaemon or kFloor
  int index;  // the path's own frame count
};
constexpr int kDaemon = 0, kFloor = 1;
std::vector<Slot> alternate_blocks(int n, int block) {
  std::vector<Slot> schedule;
  schedule.reserve(2 * static_cast<std::size_t>(n));
  int next[2] = {0, 0};
  for (int b = 0; next[kDaemon] < n || next[kFloor] < n; ++b) {
    int path = (b % 4 == 0 || b % 4 == 3) ? kDaemon : kFloor;
    if (next[path] >= n) path = 1 - path;
    for (int k = 0; k < block && next[path] < n; ++k) schedule.push_back({path, next[path]++});
  }
  return schedule;
}

// One transport: the daemon and the floor (zmq_floor.hpp), both up for the
// whole run, fed the same marker frames at `rate_hz` in alternating blocks.
// Latency: from just before the source's send (the frame already encoded)
// to the subscriber's receive of its pose, matched by frame number.
json run_one(const LatencyOptions& o, DaemonConfig config, const std::string& transport) {
  std::string floor_in, floor_out;
  IpcFiles ipc_files;
  if (transport == "tcp") {
    config.input = {"tcp://127.0.0.1:*", SocketMode::bind};
    config.output = {"tcp://127.0.0.1:*", SocketMode::bind};
    floor_in = floor_out = "tcp://127.0.0.1:*";
  } else if (transport == "ipc") {
    const std::string base =
        (std::filesystem::temp_directory_path() / ("fabrik-bench-" + std::to_string(getpid())))
            .string();
    for (const char* end : {"-in", "-out", "-floor-in", "-floor-out"})
      ipc_files.paths.emplace_back(base + end);
    config.input = {"ipc://" + base + "-in", SocketMode::bind};
    config.output = {"ipc://" + base + "-out", SocketMode::bind};
    floor_in = "ipc://" + base + "-floor-in";
    floor_out = "ipc://" + base + "-floor-out";
  } else {
    throw std::invalid_argument("unknown transport '" + transport + "' (use tcp or ipc)");
  }
  config.source = {};  // the ZeroMQ input alone
  // A few stats intervals within the run, for the daemon's own stages (1 s, the default,
  // from 4 s a path up).
  config.stats_interval_s = std::clamp(o.seconds / 4.0, 0.01, 1.0);
  config.output_encoding = o.encoding == "msgpack" ? Encoding::msgpack : Encoding::json;
  const wire::PayloadEncoding in_encoding =
      o.encoding == "msgpack" ? wire::PayloadEncoding::msgpack : wire::PayloadEncoding::json;
  const char* topic = o.view_parts.empty() ? "pose" : kViewTopic;
  if (!o.view_parts.empty()) {
    json names = json::array();
    for (const std::string& n : o.view_parts)
      if (n != "none") names.push_back(n);
    PoseViewConfig view;
    view.topic = kViewTopic;
    view.content = read_pose_content(JsonReader(names, "--view"));
    view.encoding = config.output_encoding;
    view.units = config.output_units;
    config.output_views = {view};
  }

  // Marker frames of one second of synthetic motion of the config's model.
  const Model& model = *config.tracker.model;
  std::vector<std::string> names;
  std::vector<int> points;
  for (const MarkerTarget& t : config.tracker.markers)
    names.push_back(t.marker), points.push_back(t.point);
  const int cycle = std::max(1, static_cast<int>(o.rate_hz));
  std::vector<std::vector<Eigen::Vector3d>> frames_m(cycle,
                                                     std::vector<Eigen::Vector3d>(names.size()));
  {
    SyntheticMotion motion(model, MotionSettings{});
    Posture p = Posture::rest(model);
    for (int i = 0; i < cycle; ++i) {
      motion.posture_at(i / o.rate_hz, p);
      motion.sample(p, points, 0.5e-3, frames_m[i]);
    }
  }
  // Orientation sensors: one per segment, mounted as the segment's frame, in
  // a sensors' world that is the model's; they read the truth's rotations.
  if (o.orientations != "none" && o.orientations != "mixed" && o.orientations != "only")
    throw std::invalid_argument("unknown orientations mode '" + o.orientations +
                                "' (use none, mixed or only)");
  const bool with_sensors = o.orientations != "none";
  std::vector<std::string> sensor_names;
  std::vector<std::vector<Eigen::Quaterniond>> frames_q(cycle);
  if (with_sensors) {
    for (int s = 0; s < static_cast<int>(model.segments.size()); ++s) {
      sensor_names.push_back(model.segments[s].name + "_imu");
      config.tracker.sensors.sensors.push_back({sensor_names.back(), s, 0, 1.0});
    }
    SyntheticMotion motion(model, MotionSettings{});
    Posture p = Posture::rest(model);
    for (int i = 0; i < cycle; ++i) {
      motion.posture_at(i / o.rate_hz, p);
      for (const SegmentPose& pose : p.segments) frames_q[i].push_back(pose.q_world);
    }
  }
  if (o.orientations == "only") names.clear();
  const std::vector<std::uint8_t> visible(names.size(), 1);
  const std::vector<std::uint8_t> q_visible(sensor_names.size(), 1);

  // Frame `frame`, at step i of the motion, into `payload`. The second of
  // motion is played forward and back, so the markers never jump (a jump
  // would cost the daemon a cold solve, which is not what is measured).
  std::string payload;
  auto encode = [&](std::uint64_t frame, int i) {
    const int k = cycle > 1 ? i % (2 * cycle - 2) : 0;
    const int at = k < cycle ? k : 2 * cycle - 2 - k;
    const double t_s = static_cast<double>(i) / o.rate_hz;
    const wire::SensorSamples sensors{sensor_names, frames_q[at], q_visible};
    wire::encode_marker_frame(
        frame, &t_s, names, std::span<const Eigen::Vector3d>(frames_m[at]).first(names.size()),
        visible, "mm", in_encoding, payload, nullptr, with_sensors ? &sensors : nullptr);
  };
  // Connected both ways: probe until a pose comes back, then let the probes
  // in flight drain.
  auto connect = [&](Peer& peer, const std::string& what) {
    std::uint64_t frame = 0;
    bool connected = false;
    for (int i = 0; i < 400 && !connected; ++i) {
      encode(static_cast<std::uint64_t>(i), i);
      peer.send(payload);
      connected = peer.receive(25, frame);
    }
    if (!connected)
      throw std::runtime_error("no pose came back from " + what + " over " + transport);
    while (peer.receive(200, frame)) {
    }
  };

  zmq::context_t daemon_context(1), client_context(1);
  wire::Daemon daemon(daemon_context, config);
  DaemonThread daemon_thread(daemon);
  Peer daemon_peer(client_context, daemon, topic);
  connect(daemon_peer, "the daemon");
  // The floor answers with a pose of the daemon's, renumbered.
  ZmqFloor floor(config, floor_in, floor_out, daemon_peer.body_text());
  Peer floor_peer(client_context, floor.input_endpoint(), floor.output_endpoint());
  daemon_peer.sub.set(zmq::sockopt::subscribe, "stats");
  connect(floor_peer, "the floor");
  std::vector<std::string> stats_bodies;
  daemon_peer.stats = &stats_bodies;

  const wire::DaemonCounters before = daemon.counters();
  const std::uint64_t floor_before = floor.answered();
  const int n = std::max(1, static_cast<int>(std::lround(o.rate_hz * o.seconds)));  // per path
  const int block = std::clamp(static_cast<int>(std::lround(o.rate_hz * o.block_seconds)), 1, n);
  const std::vector<Slot> schedule = alternate_blocks(n, block);
  const std::uint64_t first = 1000000;
  Peer* peers[2] = {&daemon_peer, &floor_peer};
  std::vector<Clock::time_point> sent_at[2], received_at[2];
  std::vector<std::uint8_t> sent[2], got[2];
  for (int p : {kDaemon, kFloor}) {
    sent_at[p].resize(n), received_at[p].resize(n);
    sent[p].assign(n, 0), got[p].assign(n, 0);
  }
  double marker_bytes = 0.0, pose_bytes = 0.0;  // sums
  std::atomic<bool> sending_done{false};
  std::thread sender([&] {
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.rate_hz));
    const Clock::time_point start = Clock::now() + std::chrono::milliseconds(10);
    for (std::size_t k = 0; k < schedule.size(); ++k) {
      const Slot s = schedule[k];
      encode(first + static_cast<std::uint64_t>(s.index), s.index);  // not the pipeline's cost
      std::this_thread::sleep_until(start + static_cast<int>(k) * period);  // deadlines: no drift
      sent_at[s.path][s.index] = Clock::now();
      sent[s.path][s.index] = 1;
      peers[s.path]->send(payload);
      marker_bytes += static_cast<double>(payload.size());
    }
    sending_done = true;
  });
  int received = 0;
  zmq::pollitem_t items[] = {{daemon_peer.sub.handle(), 0, ZMQ_POLLIN, 0},
                             {floor_peer.sub.handle(), 0, ZMQ_POLLIN, 0}};
  // No frame for half a second once sending is done: the rest is lost.
  QuietDeadline quiet(std::chrono::milliseconds(500));
  while (received < 2 * n) {
    if (sending_done) quiet.sending_done(Clock::now());
    if (quiet.expired(Clock::now())) break;
    if (zmq::poll(items, 2, std::chrono::milliseconds(100)) <= 0) continue;
    for (int p : {kDaemon, kFloor}) {
      std::uint64_t f = 0;
      if (!(items[p].revents & ZMQ_POLLIN) || !peers[p]->read(f)) continue;
      const Clock::time_point now = Clock::now();
      if (f < first || f >= first + static_cast<std::uint64_t>(n) || got[p][f - first]) continue;
      got[p][f - first] = 1;
      received_at[p][f - first] = now;
      ++received;
      quiet.frame(now);
      if (p == kDaemon) pose_bytes += static_cast<double>(peers[p]->body.size());
    }
  }
  sender.join();
  daemon_peer.stats = nullptr;
  const wire::DaemonCounters after = daemon.counters();
  const json stages = daemon_stages(stats_bodies, o.encoding);

  json d = input_figures(sent_at[kDaemon], sent[kDaemon], received_at[kDaemon], got[kDaemon]);
  json f = input_figures(sent_at[kFloor], sent[kFloor], received_at[kFloor], got[kFloor]);
  const int d_received = d["poses_received"].get<int>();
  d["pose_bytes_mean"] = d_received > 0 ? pose_bytes / d_received : 0.0;
  d["frames_dropped"] = after.frames_dropped - before.frames_dropped;
  d["decode_errors"] = after.decode_errors - before.decode_errors;
  d["poor_frames"] = after.poor_frames - before.poor_frames;
  d["unknown_markers"] = after.unknown_markers - before.unknown_markers;
  f["pose_bytes"] = floor.pose_bytes();
  f["answered"] = floor.answered() - floor_before;
  const double p50_us = d["latency_us"]["p50"].get<double>() - f["latency_us"]["p50"].get<double>();
  const double p99_us = d["latency_us"]["p99"].get<double>() - f["latency_us"]["p99"].get<double>();
  const bool measured = d_received > 0 && f["poses_received"].get<int>() > 0;
  return {{"transport", transport},
          {"frames_each", n},
          {"block_frames", block},
          {"marker_frame_bytes_mean", marker_bytes / static_cast<double>(schedule.size())},
          {"daemon", d},
          {"floor", f},
          {"daemon_minus_floor_us", {{"p50", p50_us}, {"p99", p99_us}}},
          {"daemon_stages_us", stages},
          {"goals",
           {{"p50_within_us", kGoalP50Us},
            {"p99_within_us", kGoalP99Us},
            {"p50_met", measured && p50_us <= kGoalP50Us},
            {"p99_met", measured && p99_us <= kGoalP99Us}}}};
}
// One daemon with two inputs: its ZeroMQ SUB (tcp loopback) and a vendor
// source, a simulated QTM or NatNet server on loopback that fabrikd's own
// client (make_source_client) connects to and decodes. The inputs take
// turns: each frame the server writes is followed, half a period later, by
// one on the ZeroMQ input, so both see the same machine and daemon load
// and never queue behind each other. Latency: from the moment the encoded
// frame was handed over (just before the server's send to the socket, via
// on_frame_sent; just before the PUB's send) to the subscriber's receive
// of its pose, matched by frame number.
json run_source(const LatencyOptions& o, DaemonConfig config, const std::string& source) {
  if (source != "qtm" && source != "natnet")
    throw std::invalid_argument("unknown source '" + source + "' (use qtm or natnet)");
  config.source = {};  // the simulated server's, below
  config.input = {"tcp://127.0.0.1:*", SocketMode::bind};
  config.output = {"tcp://127.0.0.1:*", SocketMode::bind};
  config.output_encoding = o.encoding == "msgpack" ? Encoding::msgpack : Encoding::json;
  const wire::PayloadEncoding in_encoding =
      o.encoding == "msgpack" ? wire::PayloadEncoding::msgpack : wire::PayloadEncoding::json;
  const double each_hz = o.source_rate_hz / 2.0;  // per input
  if (!(each_hz > 0.0)) throw std::invalid_argument("the source rate must be positive");

  // One second of synthetic motion at twice the per-input rate: the server
  // serves the even steps, the ZeroMQ input the odd ones, so the daemon's
  // tracker sees one motion with time going forward.
  const Model& model = *config.tracker.model;
  std::vector<std::string> names;
  std::vector<int> points;
  for (const MarkerTarget& t : config.tracker.markers)
    names.push_back(t.marker), points.push_back(t.point);
  const int cycle = std::max(1, static_cast<int>(std::lround(each_hz)));  // frames per input
  std::vector<std::vector<Eigen::Vector3d>> steps_m(2 * cycle,
                                                    std::vector<Eigen::Vector3d>(names.size()));
  {
    SyntheticMotion motion(model, MotionSettings{});
    Posture p = Posture::rest(model);
    for (int k = 0; k < 2 * cycle; ++k) {
      motion.posture_at(k / (2.0 * each_hz), p);
      motion.sample(p, points, 0.5e-3, steps_m[k]);
    }
  }
  bridges::SimRecording recording;
  recording.rate_hz = each_hz;
  recording.names = names;
  recording.up = signed_axis_name(model.lab_axes.up_lab);  // the motion is in the lab's axes
  for (int i = 0; i < cycle; ++i) {
    recording.p_mm.emplace_back();
    for (const Eigen::Vector3d& p_m : steps_m[2 * i]) recording.p_mm.back().push_back(p_m * 1000.0);
  }
  bridges::SimScript script;
  script.loop = true;

  // Frames the server handed to the OS while measuring, for the sender.
  struct Handed {
    std::uint64_t frame;
    Clock::time_point at;
  };
  std::mutex handed_mutex;
  std::condition_variable handed_cv;
  std::deque<Handed> handed;
  bool measuring = false;
  auto on_frame_sent = [&](std::uint64_t frame, Clock::time_point send_start) {
    std::lock_guard lock(handed_mutex);
    if (!measuring) return;
    handed.push_back({frame, send_start});
    handed_cv.notify_one();
  };

  // The server, and the source config that points the daemon at it. QTM
  // numbers frames from 1 (index + 1), NatNet from 0.
  std::unique_ptr<qtm::QtmSimServer> qtm_server;
  std::unique_ptr<bridges::NatNetSimServer> natnet_server;
  std::uint64_t first_frame_number = 0;
  config.source.host = "127.0.0.1";
  if (source == "qtm") {
    qtm::QtmSimServer::Options so;
    so.bind_address = "127.0.0.1";
    so.base_port = 0;
    so.on_frame_sent = on_frame_sent;
    qtm_server = std::make_unique<qtm::QtmSimServer>(recording, script, so);
    config.source.kind = SourceKind::qtm;
    config.source.port = qtm_server->port_little_endian();
    first_frame_number = 1;
  } else {
    bridges::NatNetSimServer::Options so;
    so.bind_address = "127.0.0.1";
    so.command_port = 0;
    so.data_port = 0;
    so.multicast = false;  // unicast: loopback need not carry multicast
    so.on_frame_sent = on_frame_sent;
    natnet_server = std::make_unique<bridges::NatNetSimServer>(recording, script, so);
    config.source.kind = SourceKind::natnet;
    config.source.port = natnet_server->command_port();
    config.source.data_port = natnet_server->data_port();
    config.source.multicast = false;
    config.source.local_interface = "127.0.0.1";
  }
  config.source.url = source + "://127.0.0.1:" + std::to_string(config.source.port);

  zmq::context_t daemon_context(1), client_context(1);
  wire::Daemon daemon(daemon_context, config);
  wire::DaemonControl control;
  std::thread daemon_thread([&] { daemon.run(control); });
  std::jthread server_thread([&](std::stop_token stop) {
    if (qtm_server) qtm_server->run(stop);
    else natnet_server->run(stop);
  });

  Peer peer(client_context, daemon);

  // ZeroMQ frames are numbered far above any the server reaches in a run,
  // so a pose's frame number says which input it came from.
  constexpr std::uint64_t kZmqFirst = std::uint64_t{1} << 40;
  constexpr std::uint64_t kZmqProbe = std::uint64_t{1} << 41;
  std::string payload;
  const std::vector<std::uint8_t> visible(names.size(), 1);
  // Encodes, then returns the moment just before the send: like the
  // server's send_start, the frame's encoding is not the transport's cost.
  auto send = [&](std::uint64_t frame, std::uint64_t step) {
    const double t_s = static_cast<double>(step) / (2.0 * each_hz);
    wire::encode_marker_frame(frame, &t_s, names, steps_m[step % steps_m.size()], visible, "mm",
                              in_encoding, payload);
    const Clock::time_point send_start = Clock::now();
    peer.send(payload);
    return send_start;
  };
  auto receive = [&](int timeout_ms, std::uint64_t& frame) { return peer.receive(timeout_ms, frame); };
  // The daemon's loop first: a server gone under a running client is logged as a lost connection.
  auto stop_all = [&] {
    control.stop = true;
    daemon_thread.join();
    server_thread.request_stop();
    if (server_thread.joinable()) server_thread.join();
  };

  // Both inputs connected: probe the ZeroMQ input until a pose of a probe
  // comes back, and wait for a pose of a server's frame (the client's
  // handshake and its backoff take a while), within 15 s.
  bool zmq_up = false, source_up = false;
  const Clock::time_point connect_deadline = Clock::now() + std::chrono::seconds(15);
  for (std::uint64_t i = 0; !(zmq_up && source_up) && Clock::now() < connect_deadline; ++i) {
    if (!zmq_up) (void)send(kZmqProbe + i, 0);
    std::uint64_t f = 0;
    if (receive(25, f)) (f >= kZmqFirst ? zmq_up : source_up) = true;
  }
  if (!(zmq_up && source_up)) {
    const std::string error = daemon.counters().frames_in ? "" : " (no frame reached the daemon)";
    stop_all();
    throw std::runtime_error(std::string("no pose came back from ") +
                             (zmq_up ? source : "the ZeroMQ input") + error);
  }
  // Let the probes' poses in flight arrive (they are told apart by number).
  for (const Clock::time_point settle = Clock::now() + std::chrono::milliseconds(200);
       Clock::now() < settle;) {
    std::uint64_t f = 0;
    (void)receive(10, f);
  }

  const wire::DaemonCounters before = daemon.counters();
  const int n = std::max(1, static_cast<int>(std::lround(each_hz * o.seconds)));  // per input
  std::vector<Clock::time_point> source_sent_at(n), zmq_sent_at(n), source_received_at(n),
      zmq_received_at(n);
  std::vector<std::uint8_t> source_sent(n, 0), zmq_sent(n, 0), source_got(n, 0), zmq_got(n, 0);
  // Source poses by frame number: the window's first number is known to the
  // sender only once the server has written that frame.
  std::unordered_map<std::uint64_t, Clock::time_point> source_poses;
  source_poses.reserve(2 * static_cast<std::size_t>(n) + 64);
  std::atomic<std::uint64_t> window_first{std::numeric_limits<std::uint64_t>::max()};
  std::atomic<bool> sending_done{false};
  {
    std::lock_guard lock(handed_mutex);
    measuring = true;
  }
  std::thread sender([&] {
    const auto half_period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(0.5 / each_hz));
    for (int k = 0; k < n; ++k) {
      Handed h;
      {
        std::unique_lock lock(handed_mutex);
        // The server stalled for a second: stop; what is missing counts as lost.
        if (!handed_cv.wait_for(lock, std::chrono::seconds(1), [&] { return !handed.empty(); }))
          break;
        h = handed.front();
        handed.pop_front();
      }
      if (k == 0) window_first = h.frame;
      const std::uint64_t i = h.frame - window_first;  // the server numbers consecutively
      if (i >= static_cast<std::uint64_t>(n)) break;
      source_sent_at[i] = h.at;
      source_sent[i] = 1;
      std::this_thread::sleep_until(h.at + half_period);  // midway to the server's next frame
      const std::uint64_t step = 2 * (h.frame - first_frame_number) + 1;
      zmq_sent_at[k] = send(kZmqFirst + static_cast<std::uint64_t>(k), step);
      zmq_sent[k] = 1;
    }
    {
      std::lock_guard lock(handed_mutex);
      measuring = false;
    }
    sending_done = true;
  });
  int zmq_received = 0;
  auto source_complete = [&] {
    const std::uint64_t first = window_first;
    for (int i = 0; i < n; ++i)
      if (!source_poses.contains(first + static_cast<std::uint64_t>(i))) return false;
    return true;
  };
  // Receive until every pose of both windows is in, or until a second after
  // the last send (the rest is lost). The server keeps streaming, so poses
  // keep coming: the wait is not extended per frame.
  QuietDeadline give_up(std::chrono::seconds(1));
  while (!give_up.expired(Clock::now())) {
    std::uint64_t f = 0;
    if (receive(20, f)) {
      const Clock::time_point now = Clock::now();
      if (f >= kZmqFirst) {
        const std::uint64_t k = f - kZmqFirst;
        if (k < static_cast<std::uint64_t>(n) && !zmq_got[k]) {
          zmq_got[k] = 1;
          zmq_received_at[k] = now;
          ++zmq_received;
        }
      } else {
        source_poses.emplace(f, now);
      }
    }
    if (sending_done) {
      give_up.sending_done(Clock::now());
      if (zmq_received == n && source_complete()) break;
    }
  }
  sender.join();
  stop_all();
  const wire::DaemonCounters after = daemon.counters();

  if (window_first != std::numeric_limits<std::uint64_t>::max())
    for (int i = 0; i < n; ++i)
      if (const auto it = source_poses.find(window_first + static_cast<std::uint64_t>(i));
          it != source_poses.end()) {
        source_got[i] = 1;
        source_received_at[i] = it->second;
      }
  json zmq = input_figures(zmq_sent_at, zmq_sent, zmq_received_at, zmq_got);
  json src = input_figures(source_sent_at, source_sent, source_received_at, source_got);
  const double zmq_p50_us = zmq["latency_us"]["p50"].get<double>();
  const double source_p50_us = src["latency_us"]["p50"].get<double>();
  zmq["input"] = "zmq";
  src["input"] = source;
  return {{"source", source},
          {"zmq_transport", "tcp"},
          {"rate_hz_per_input", each_hz},
          {"inputs", json::array({zmq, src})},
          {"source_p50_over_zmq_p50", source_p50_us / zmq_p50_us},
          {"source_p50_minus_zmq_p50_us", source_p50_us - zmq_p50_us},
          {"source_p50_within_50_us", source_p50_us - zmq_p50_us <= 50.0},
          {"daemon_frames_dropped", after.frames_dropped - before.frames_dropped},
          {"daemon_decode_errors", after.decode_errors - before.decode_errors},
          {"daemon_unknown_markers", after.unknown_markers - before.unknown_markers},
          {"daemon_poor_frames", after.poor_frames - before.poor_frames}};
}

}  // namespace

json daemon_stages(const std::vector<std::string>& bodies, const std::string& encoding) {
  std::array<std::vector<double>, 4> p50;
  const char* names[] = {"decode", "solve", "encode", "send"};
  for (const std::string& b : bodies) {
    const json stats = encoding == "msgpack" ? json::from_msgpack(b, true, false)
                                             : json::parse(b, nullptr, false);
    // The interval's p50 of a stage; NaN where the stats do not hold one.
    const auto stage_p50 = [&](const char* name) {
      const json* q = &stats;
      for (const char* key : {"stages_us", name, "p50"}) {
        if (!q->is_object() || !q->contains(key)) return std::nan("");
        q = &(*q)[key];
      }
      return q->is_number() ? q->get<double>() : std::nan("");
    };
    std::array<double, 4> v;
    for (std::size_t k = 0; k < v.size(); ++k) v[k] = stage_p50(names[k]);
    const bool finite = std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
    if (!finite || !(v[1] > 0.0)) continue;
    for (std::size_t k = 0; k < v.size(); ++k) p50[k].push_back(v[k]);
  }
  json out = {{"intervals", p50[0].size()}};
  double sum = 0.0;
  for (std::size_t k = 0; k < p50.size(); ++k) {
    const double v = p50[k].empty() ? 0.0 : quantile(p50[k], 0.5);
    out[names[k]] = v;
    if (k < 3) sum += v;
  }
  out["decode_solve_encode"] = sum;
  return out;
}

json run_latency(const LatencyOptions& o) {
  spdlog::set_level(spdlog::level::warn);
  const DaemonConfig config =
      o.config.empty() ? default_daemon_config() : load_daemon_config_file(o.config);
  const Model& m = *config.tracker.model;
  json out = {{"benchmark", "latency"},
              {"rate_hz", o.rate_hz},
              {"seconds", o.seconds},
              {"block_seconds", o.block_seconds},
              {"encoding", o.encoding},
              {"orientations", o.orientations},
              {"subscribed_to", o.view_parts.empty() ? json("pose") : json{{"view", o.view_parts}}},
              {"config", o.config.empty() ? "built-in default (config/default.json)" : o.config},
              {"model",
               {{"name", m.name},
                {"markers", config.tracker.markers.size()},
                {"segments", m.segments.size()}}},
              {"measured",
               "marker frame sent by the source (already encoded) -> pose received by the "
               "subscriber, one process, steady clock; the daemon and the floor (a bare ZeroMQ "
               "echo: same sockets and options, same marker frames, answers the daemon's pose "
               "size) alternate in blocks"},
              {"runs", json::array()}};
  if (!o.sources.empty()) {
    // A source comparison replaces the transport runs: one daemon per source.
    out["rate_hz"] = o.source_rate_hz;
    out["measured"] =
        "encoded frame handed over (just before the ZeroMQ send, or the simulated server's "
        "TCP/UDP send) -> pose "
        "received by the subscriber, one daemon fed by both inputs alternately, one process, "
        "steady clock";
    out.erase("block_seconds");
    out["source_runs"] = json::array();
    for (const std::string& s : o.sources) out["source_runs"].push_back(run_source(o, config, s));
    return out;
  }
  for (const std::string& t : o.transports) out["runs"].push_back(run_one(o, config, t));
  return out;
}

namespace {

std::string model_text(const json& r) {
  const json& m = r["model"];
  const auto markers = m["markers"].get<std::size_t>(), segments = m["segments"].get<std::size_t>();
  const std::string name = m["name"].get<std::string>();
  if (r["orientations"] == "mixed")
    return name + " (" + std::to_string(markers) + " markers and " + std::to_string(segments) +
           " orientation sensors)";
  if (r["orientations"] == "only")
    return name + " (" + std::to_string(segments) + " orientation sensors, no markers)";
  return name + " (" + std::to_string(markers) + " markers, " + std::to_string(segments) +
         " segments)";
}

}  // namespace

std::string latency_table(const json& r) {
  std::string s;
  char buf[640];
  if (r.contains("source_runs")) {
    for (const json& run : r["source_runs"]) {
      std::snprintf(buf, sizeof buf,
                    "Source vs ZeroMQ input: one daemon, %g Hz on each input alternately, %g s, "
                    "%s ZeroMQ frames and poses, %s\n",
                    run["rate_hz_per_input"].get<double>(), r["seconds"].get<double>(),
                    r["encoding"].get<std::string>().c_str(), model_text(r).c_str());
      s += buf;
      s += "  input        sent   received   lost   p50 us   p90 us   p99 us   max us\n";
      for (const json& in : run["inputs"]) {
        const json& l = in["latency_us"];
        std::snprintf(buf, sizeof buf, "  %-9s %7d %10d %6d %8.1f %8.1f %8.1f %8.1f\n",
                      (in["input"] == "zmq" ? std::string("zmq tcp") : in["input"].get<std::string>())
                          .c_str(),
                      in["frames_sent"].get<int>(), in["poses_received"].get<int>(),
                      in["lost"].get<int>(), l["p50"].get<double>(), l["p90"].get<double>(),
                      l["p99"].get<double>(), l["max"].get<double>());
        s += buf;
      }
      std::snprintf(buf, sizeof buf,
                    "  %s p50 - zmq p50: %+.1f us (ratio %.2f; %s 50 us); daemon dropped %llu, "
                    "poor fits %llu\n",
                    run["source"].get<std::string>().c_str(),
                    run["source_p50_minus_zmq_p50_us"].get<double>(),
                    run["source_p50_over_zmq_p50"].get<double>(),
                    run["source_p50_within_50_us"].get<bool>() ? "within" : "NOT within",
                    static_cast<unsigned long long>(run["daemon_frames_dropped"].get<std::uint64_t>()),
                    static_cast<unsigned long long>(run["daemon_poor_frames"].get<std::uint64_t>()));
      s += buf;
    }
    return s;
  }
  std::snprintf(buf, sizeof buf,
                "End-to-end latency against the ZeroMQ floor: %g Hz, %g s each, %s, %s;\n"
                "  config %s; daemon and floor alternate in %g s blocks; subscribed to %s\n",
                r["rate_hz"].get<double>(), r["seconds"].get<double>(),
                r["encoding"].get<std::string>().c_str(), model_text(r).c_str(),
                r["config"].get<std::string>().c_str(), r["block_seconds"].get<double>(),
                r["subscribed_to"].is_string()
                    ? "pose"
                    : ("a view of " + r["subscribed_to"]["view"].dump() + " alone (no full pose made)")
                          .c_str());
  s += buf;
  s += "  transport  path      sent  received  lost  dropped   p50 us   p99 us   max us  bytes "
       "in/out\n";
  for (const json& run : r["runs"]) {
    const json& d = run["daemon"];
    const json& f = run["floor"];
    auto row = [&](const char* transport, const char* path, const json& x, double out_bytes,
                   std::uint64_t dropped) {
      std::snprintf(buf, sizeof buf,
                    "  %-9s  %-6s %7d %9d %5d %8llu %8.1f %8.1f %8.1f  %.0f/%.0f\n", transport,
                    path, x["frames_sent"].get<int>(), x["poses_received"].get<int>(),
                    x["lost"].get<int>(), static_cast<unsigned long long>(dropped),
                    x["latency_us"]["p50"].get<double>(), x["latency_us"]["p99"].get<double>(),
                    x["latency_us"]["max"].get<double>(),
                    run["marker_frame_bytes_mean"].get<double>(), out_bytes);
      s += buf;
    };
    row(run["transport"].get<std::string>().c_str(), "daemon", d,
        d["pose_bytes_mean"].get<double>(), d["frames_dropped"].get<std::uint64_t>());
    row("", "floor", f, f["pose_bytes"].get<double>(), 0);
    const json& diff = run["daemon_minus_floor_us"];
    const json& goals = run["goals"];
    std::snprintf(buf, sizeof buf,
                  "  %-9s  daemon - floor:                  %+8.1f %+8.1f   goals (<= %g, <= %g "
                  "us): p50 %s, p99 %s\n",
                  "", diff["p50"].get<double>(), diff["p99"].get<double>(),
                  goals["p50_within_us"].get<double>(), goals["p99_within_us"].get<double>(),
                  goals["p50_met"].get<bool>() ? "met" : "NOT met",
                  goals["p99_met"].get<bool>() ? "met" : "NOT met");
    s += buf;
    const json& st = run["daemon_stages_us"];
    if (st["intervals"].get<int>() > 0) {
      std::snprintf(buf, sizeof buf,
                    "  %-9s  the daemon's own stages (its stats, p50 us): decode %.1f, solve %.1f, "
                    "encode %.1f, send %.1f; the gap's p50 less decode + solve + encode: %+.1f\n",
                    "", st["decode"].get<double>(), st["solve"].get<double>(),
                    st["encode"].get<double>(), st["send"].get<double>(),
                    diff["p50"].get<double>() - st["decode_solve_encode"].get<double>());
      s += buf;
    }
  }
  return s;
}

}  // namespace fabrik::bench
