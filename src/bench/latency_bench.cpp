#include "latency_bench.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>
#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/daemon.hpp"
#include "transport/marker_codec.hpp"

namespace fabrik::bench {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

// The frame number of a pose without decoding all of it: the encoder writes
// "frame" first (JSON: {"frame":N; MessagePack: map, "frame", uint).
bool pose_frame(const zmq::message_t& m, std::uint64_t& frame) {
  const auto* b = static_cast<const std::uint8_t*>(m.data());
  const std::size_t n = m.size();
  constexpr std::string_view json_prefix = "{\"frame\":";
  if (n > json_prefix.size() &&
      std::string_view(reinterpret_cast<const char*>(b), json_prefix.size()) == json_prefix) {
    const char* p = reinterpret_cast<const char*>(b) + json_prefix.size();
    return std::from_chars(p, reinterpret_cast<const char*>(b) + n, frame).ec == std::errc();
  }
  if (n > 16 && b[1] == 0xa5 && std::memcmp(b + 2, "frame", 5) == 0) {
    if (b[7] < 0x80) return frame = b[7], true;
    if (b[7] != 0xcf) return false;
    frame = 0;
    for (int i = 0; i < 8; ++i) frame = (frame << 8) | b[8 + i];
    return true;
  }
  return false;
}

json run_one(const LatencyOptions& o, const std::string& transport) {
  DaemonConfig config = default_daemon_config();
  std::filesystem::path ipc_base;
  if (transport == "tcp") {
    config.input = {"tcp://127.0.0.1:*", SocketMode::bind};
    config.output = {"tcp://127.0.0.1:*", SocketMode::bind};
  } else if (transport == "ipc") {
    ipc_base =
        std::filesystem::temp_directory_path() / ("fabrik-bench-" + std::to_string(getpid()));
    config.input = {"ipc://" + ipc_base.string() + "-in", SocketMode::bind};
    config.output = {"ipc://" + ipc_base.string() + "-out", SocketMode::bind};
  } else {
    throw std::invalid_argument("unknown transport '" + transport + "' (use tcp or ipc)");
  }
  config.output_encoding = o.encoding == "msgpack" ? Encoding::msgpack : Encoding::json;
  const wire::PayloadEncoding in_encoding =
      o.encoding == "msgpack" ? wire::PayloadEncoding::msgpack : wire::PayloadEncoding::json;

  // Marker frames of one second of synthetic motion, encoded on the fly.
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

  zmq::context_t daemon_context(1), client_context(1);
  wire::Daemon daemon(daemon_context, config);
  wire::DaemonControl control;
  std::thread daemon_thread([&] { daemon.run(control); });

  zmq::socket_t pub(client_context, zmq::socket_type::pub),
      sub(client_context, zmq::socket_type::sub);
  pub.set(zmq::sockopt::linger, 0);
  sub.set(zmq::sockopt::linger, 0);
  sub.set(zmq::sockopt::subscribe, "pose");
  sub.set(zmq::sockopt::rcvhwm, 0);
  pub.connect(daemon.input_endpoint());
  sub.connect(daemon.output_endpoint());

  std::string payload;
  auto send = [&](std::uint64_t frame, int i) {
    const double t_s = static_cast<double>(frame) / o.rate_hz;
    const wire::SensorSamples sensors{sensor_names, frames_q[i % cycle], q_visible};
    wire::encode_marker_frame(frame, &t_s, names,
                              std::span<const Eigen::Vector3d>(frames_m[i % cycle]).first(names.size()),
                              visible, "mm", in_encoding, payload, nullptr,
                              with_sensors ? &sensors : nullptr);
    pub.send(zmq::buffer(std::string_view("markers")), zmq::send_flags::sndmore);
    pub.send(zmq::buffer(payload));
  };
  zmq::message_t topic, body;
  auto receive = [&](int timeout_ms, std::uint64_t& frame) {
    zmq::pollitem_t items[] = {{sub.handle(), 0, ZMQ_POLLIN, 0}};
    if (zmq::poll(items, 1, std::chrono::milliseconds(timeout_ms)) <= 0) return false;
    (void)sub.recv(topic);
    if (!topic.more()) return false;
    (void)sub.recv(body);
    return pose_frame(body, frame);
  };

  // Connect both ways before measuring: probe until a pose comes back, then
  // let the probes in flight drain.
  std::uint64_t frame = 0;
  bool connected = false;
  for (int i = 0; i < 400 && !connected; ++i) {
    send(static_cast<std::uint64_t>(i), i);
    connected = receive(25, frame);
  }
  if (!connected) throw std::runtime_error("no pose came back over " + transport);
  while (receive(200, frame)) {
  }

  const wire::DaemonCounters before = daemon.counters();
  const int n = static_cast<int>(o.rate_hz * o.seconds);
  const std::uint64_t first = 1000000;
  std::vector<Clock::time_point> sent_at(n), received_at(n);
  std::vector<std::uint8_t> got(n, 0);
  std::atomic<bool> sending_done{false};
  std::thread sender([&] {
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.rate_hz));
    const Clock::time_point start = Clock::now() + std::chrono::milliseconds(10);
    for (int i = 0; i < n; ++i) {
      std::this_thread::sleep_until(start + i * period);  // deadlines: no drift
      sent_at[i] = Clock::now();
      send(first + static_cast<std::uint64_t>(i), i);
    }
    sending_done = true;
  });
  int received = 0, stray = 0;
  for (;;) {
    std::uint64_t f = 0;
    if (receive(sending_done ? 500 : 1000, f)) {
      const Clock::time_point now = Clock::now();
      if (f >= first && f < first + static_cast<std::uint64_t>(n) && !got[f - first]) {
        got[f - first] = 1;
        received_at[f - first] = now;
        if (++received == n) break;
      } else {
        ++stray;
      }
    } else if (sending_done) {
      break;  // nothing for half a second after the last frame: the rest is lost
    }
  }
  sender.join();
  control.stop = true;
  daemon_thread.join();
  const wire::DaemonCounters after = daemon.counters();
  if (!ipc_base.empty()) {
    std::filesystem::remove(ipc_base.string() + "-in");
    std::filesystem::remove(ipc_base.string() + "-out");
  }

  std::vector<double> latency_us;
  latency_us.reserve(n);
  for (int i = 0; i < n; ++i)
    if (got[i])
      latency_us.push_back(
          std::chrono::duration<double, std::micro>(received_at[i] - sent_at[i]).count());
  return {{"transport", transport},
          {"frames_sent", n},
          {"poses_received", received},
          {"lost", n - received},
          {"daemon_frames_dropped", after.frames_dropped - before.frames_dropped},
          {"daemon_decode_errors", after.decode_errors - before.decode_errors},
          {"latency_us",
           {{"p50", quantile(latency_us, 0.5)},
            {"p99", quantile(latency_us, 0.99)},
            {"max", quantile(latency_us, 1.0)}}}};
}

}  // namespace

json run_latency(const LatencyOptions& o) {
  spdlog::set_level(spdlog::level::warn);
  json out = {{"benchmark", "latency"},
              {"rate_hz", o.rate_hz},
              {"seconds", o.seconds},
              {"encoding", o.encoding},
              {"orientations", o.orientations},
              {"model", "models/fullbody.json (45 markers, 15 segments)"},
              {"measured",
               "marker frame sent by the source -> pose received by the subscriber, one process, "
               "steady clock"},
              {"runs", json::array()}};
  for (const std::string& t : o.transports) out["runs"].push_back(run_one(o, t));
  return out;
}

std::string latency_table(const json& r) {
  std::string s;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "End-to-end latency: %g Hz for %g s, %s, full-body model (%s)\n",
                r["rate_hz"].get<double>(), r["seconds"].get<double>(),
                r["encoding"].get<std::string>().c_str(),
                r["orientations"] == "mixed"  ? "45 markers and 15 orientation sensors"
                : r["orientations"] == "only" ? "15 orientation sensors, no markers"
                                              : "45 markers");
  s += buf;
  s += "  transport     sent   received   lost  dropped   p50 us   p99 us   max us\n";
  for (const json& run : r["runs"]) {
    std::snprintf(
        buf, sizeof buf, "  %-9s %8d %10d %6d %8llu %8.1f %8.1f %8.1f\n",
        run["transport"].get<std::string>().c_str(), run["frames_sent"].get<int>(),
        run["poses_received"].get<int>(), run["lost"].get<int>(),
        static_cast<unsigned long long>(run["daemon_frames_dropped"].get<std::uint64_t>()),
        run["latency_us"]["p50"].get<double>(), run["latency_us"]["p99"].get<double>(),
        run["latency_us"]["max"].get<double>());
    s += buf;
  }
  return s;
}

}  // namespace fabrik::bench
