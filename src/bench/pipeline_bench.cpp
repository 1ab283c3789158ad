#include "pipeline_bench.hpp"

#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "stats.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/daemon.hpp"
#include "transport/marker_codec.hpp"
#include "wake_probe.hpp"

namespace fabrik::bench {

namespace {

using nlohmann::json;

constexpr int kWarmUpFrames = 200;  // buffers grown, caches and the subscriber's connection warm
constexpr int kPoseTimeoutMs = 1000;

// One config's daemon, its subscriber and its marker frames.
struct StageRun {
  std::string name;
  std::shared_ptr<const Model> model;  // outlives `motion`, which refers to it
  std::unique_ptr<wire::Daemon> daemon;
  zmq::socket_t sub;
  std::string ipc_base;  // removed at the end (ipc only)
  std::vector<std::string> names;
  std::vector<int> points;
  std::unique_ptr<SyntheticMotion> motion;
  Posture truth;
  std::vector<Eigen::Vector3d> p_m;
  std::vector<std::uint8_t> visible;
  std::string payload;
  zmq::message_t topic, pose;
  std::array<std::vector<double>, 4> us;  // per stage, in wire::Stage order
  std::vector<double> around_us;
  std::vector<double> solver_us, tracker_rest_us, iterations;  // the solve stage, split
  std::size_t pose_bytes = 0;
  int lost = 0;
};

// The daemon and its subscriber have contexts (I/O threads) of their own, as
// fabrikd and its clients in their own processes.
std::unique_ptr<StageRun> make_run(zmq::context_t& daemon_context, zmq::context_t& client_context,
                                   DaemonConfig config, std::string name, const PipelineOptions& o,
                                   int k) {
  auto run = std::make_unique<StageRun>();
  run->name = std::move(name);
  config.input = {"inproc://fabrik-bench-pipeline-in-" + std::to_string(k), SocketMode::bind};
  if (o.transport == "tcp") {
    config.output = {"tcp://127.0.0.1:*", SocketMode::bind};
  } else if (o.transport == "ipc") {
    run->ipc_base = (std::filesystem::temp_directory_path() /
                     ("fabrik-bench-pipeline-" + std::to_string(getpid()) + "-" +
                      std::to_string(k)))
                        .string();
    config.output = {"ipc://" + run->ipc_base, SocketMode::bind};
  } else {
    throw std::invalid_argument("unknown transport '" + o.transport + "' (use tcp or ipc)");
  }
  config.output_encoding = o.encoding == "msgpack" ? Encoding::msgpack : Encoding::json;
  if (!o.pose_content.empty()) {
    json names = json::array();
    for (const std::string& n : o.pose_content)
      if (n != "none") names.push_back(n);
    config.output_pose_content = read_pose_content(JsonReader(names, "--pose-content"));
  }
  run->model = config.tracker.model;
  for (const MarkerTarget& t : config.tracker.markers)
    run->names.push_back(t.marker), run->points.push_back(t.point);
  run->motion = std::make_unique<SyntheticMotion>(*run->model, MotionSettings{});
  run->truth = Posture::rest(*run->model);
  run->p_m.resize(run->names.size());
  run->visible.assign(run->names.size(), 1);
  run->payload.reserve(1 << 16);
  run->daemon = std::make_unique<wire::Daemon>(daemon_context, std::move(config));
  run->sub = zmq::socket_t(client_context, zmq::socket_type::sub);
  run->sub.set(zmq::sockopt::linger, 0);
  run->sub.set(zmq::sockopt::rcvhwm, 0);
  run->sub.set(zmq::sockopt::subscribe, "pose");
  run->sub.connect(run->daemon->output_endpoint());
  return run;
}

// Frame f of the run's motion, as a source would send it (not timed).
void make_payload(StageRun& r, std::uint64_t f, const PipelineOptions& o) {
  const double t_s = static_cast<double>(f) / o.rate_hz;
  r.motion->posture_at(t_s, r.truth);
  r.motion->sample(r.truth, r.points, 0.5e-3, r.p_m);
  wire::encode_marker_frame(f, &t_s, r.names, r.p_m, r.visible, "mm",
                            o.encoding == "msgpack" ? wire::PayloadEncoding::msgpack
                                                    : wire::PayloadEncoding::json,
                            r.payload);
}

bool receive_pose(StageRun& r, int timeout_ms) {
  zmq::pollitem_t items[] = {{r.sub.handle(), 0, ZMQ_POLLIN, 0}};
  if (zmq::poll(items, 1, std::chrono::milliseconds(timeout_ms)) <= 0) return false;
  (void)r.sub.recv(r.topic);
  if (!r.topic.more()) return false;
  (void)r.sub.recv(r.pose);
  r.pose_bytes = r.pose.size();
  return true;
}

wire::FrameStages serve(StageRun& r) {
  return r.daemon->serve_payload(
      {reinterpret_cast<const std::uint8_t*>(r.payload.data()), r.payload.size()});
}

json quantiles(const std::vector<double>& v) {
  return {{"p50", quantile(v, 0.5)}, {"p99", quantile(v, 0.99)}, {"mean", mean(v)}};
}

}  // namespace

json run_pipeline(const PipelineOptions& o) {
  if (o.encoding != "json" && o.encoding != "msgpack")
    throw std::invalid_argument("unknown encoding '" + o.encoding + "' (use json or msgpack)");
  zmq::context_t daemon_context(1), client_context(1);
  std::vector<std::unique_ptr<StageRun>> runs;
  runs.push_back(make_run(daemon_context, client_context, default_daemon_config(), "default", o, 0));
  for (const std::string& file : o.configs)
    runs.push_back(make_run(daemon_context, client_context, load_daemon_config_file(file), file, o,
                            static_cast<int>(runs.size())));

  // Until the subscriber's subscription has reached the daemon, poses are
  // published to no one: serve frames until one comes back.
  std::uint64_t frame = 0;
  for (auto& r : runs) {
    bool connected = false;
    for (int i = 0; i < 400 && !connected; ++i) {
      make_payload(*r, frame++, o);
      serve(*r);
      connected = receive_pose(*r, 10);
    }
    if (!connected) throw std::runtime_error("no pose came back to the subscriber of " + r->name);
    while (receive_pose(*r, 50)) {
    }
  }
  // One wake-up sampled per round of frames, in the same run: the machine's
  // price for what each send does once (ZeroMQ waking its idle I/O thread).
  WakeProbe probe;
  std::vector<double> wake_sleeping_us, write_alone_us;
  int wake_samples_dropped = 0;  // the sleeper had not taken the previous wake within 10 ms
  const int total = kWarmUpFrames + o.frames;
  for (int i = 0; i < total; ++i, ++frame) {
    // Alternate which model goes first: neither always follows the other.
    for (std::size_t j = 0; j < runs.size(); ++j) {
      StageRun& r = *runs[(j + static_cast<std::size_t>(i)) % runs.size()];
      make_payload(r, frame, o);
      const wire::FrameStages s = serve(r);
      const bool got = receive_pose(r, kPoseTimeoutMs);
      if (i < kWarmUpFrames) continue;
      if (!got || s[wire::Stage::solve] == 0.0) {
        ++r.lost;  // not served, or its pose not delivered: no figure
        continue;
      }
      for (std::size_t k = 0; k < r.us.size(); ++k) r.us[k].push_back(s.us[k]);
      r.around_us.push_back(s.around_solve_us());
      r.solver_us.push_back(s.solver_us);
      r.tracker_rest_us.push_back(s[wire::Stage::solve] - s.solver_us);
      r.iterations.push_back(s.iterations);
    }
    if (i < kWarmUpFrames) continue;
    if (const double us = probe.wake_sleeping_us(); us >= 0.0)
      wake_sleeping_us.push_back(us);
    else
      ++wake_samples_dropped;
    write_alone_us.push_back(probe.write_alone_us());
  }

  json models = json::array();
  for (auto& r : runs) {
    json stages;
    for (std::size_t k = 0; k < r->us.size(); ++k) stages[wire::kStageNames[k]] = quantiles(r->us[k]);
    const double solve_p50 = quantile(r->us[1], 0.5);
    models.push_back({{"name", r->name},
                      {"markers", r->names.size()},
                      {"marker_payload_bytes", r->payload.size()},
                      {"pose_bytes", r->pose_bytes},
                      {"frames", r->us[0].size()},
                      {"lost", r->lost},
                      {"stages_us", stages},
                      {"around_solve_us", quantiles(r->around_us)},
                      {"solver_us", quantiles(r->solver_us)},
                      {"tracker_besides_solver_us", quantiles(r->tracker_rest_us)},
                      {"iterations", quantiles(r->iterations)},
                      {"around_over_solve_p50",
                       solve_p50 > 0 ? quantile(r->around_us, 0.5) / solve_p50 : 0.0}});
    r->sub.close();
    r->daemon.reset();
    if (!r->ipc_base.empty()) std::filesystem::remove(r->ipc_base);
  }
  return {{"frames", o.frames},
          {"rate_hz", o.rate_hz},
          {"transport", o.transport},
          {"encoding", o.encoding},
          {"pose_content", o.pose_content.empty() ? json("each config's") : json(o.pose_content)},
          {"models", models},
          {"wake_us",
           {{"sleeping_thread", quantiles(wake_sleeping_us)},
            {"write_alone", quantiles(write_alone_us)},
            {"sleeping_thread_samples", wake_sleeping_us.size()},
            {"sleeping_thread_samples_dropped", wake_samples_dropped}}}};
}

std::string pipeline_table(const json& r) {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof line,
                "fabrik bench pipeline: the daemon's frame path in-process, %d frames per model "
                "(one at a time, models interleaved), %s markers in, %s poses out over %s to a "
                "subscriber\nper frame, microseconds: p50 (p99); around solve = decode + encode "
                "+ send, per frame; pose content: %s\n\n",
                r["frames"].get<int>(), r["encoding"].get<std::string>().c_str(),
                r["encoding"].get<std::string>().c_str(),
                r["transport"].get<std::string>().c_str(), r["pose_content"].dump().c_str());
  out += line;
  std::snprintf(line, sizeof line, "%-28s %7s %7s %7s  %-14s %-14s %-14s %-14s %-14s %s\n",
                "model", "markers", "in B", "pose B", "decode", "solve", "encode", "send",
                "around solve", "around/solve");
  out += line;
  const auto cell = [](const json& q) {
    char c[32];
    std::snprintf(c, sizeof c, "%.1f (%.1f)", q["p50"].get<double>(), q["p99"].get<double>());
    return std::string(c);
  };
  for (const json& m : r["models"]) {
    std::string name = m["name"].get<std::string>();
    if (name.size() > 28) name = "..." + name.substr(name.size() - 25);
    const json& s = m["stages_us"];
    std::snprintf(line, sizeof line, "%-28s %7d %7d %7d  %-14s %-14s %-14s %-14s %-14s %.2f\n",
                  name.c_str(), m["markers"].get<int>(), m["marker_payload_bytes"].get<int>(),
                  m["pose_bytes"].get<int>(), cell(s["decode"]).c_str(), cell(s["solve"]).c_str(),
                  cell(s["encode"]).c_str(), cell(s["send"]).c_str(),
                  cell(m["around_solve_us"]).c_str(), m["around_over_solve_p50"].get<double>());
    out += line;
    std::snprintf(line, sizeof line,
                  "  of solve: the solver %s, %.1f iterations a frame (p99 %.0f); the tracker "
                  "besides %s\n",
                  cell(m["solver_us"]).c_str(), m["iterations"]["mean"].get<double>(),
                  m["iterations"]["p99"].get<double>(),
                  cell(m["tracker_besides_solver_us"]).c_str());
    out += line;
    if (m["lost"].get<int>() > 0) {
      std::snprintf(line, sizeof line, "  (%d frames without a pose left out)\n",
                    m["lost"].get<int>());
      out += line;
    }
  }
  const json& wake = r["wake_us"];
  std::snprintf(line, sizeof line,
                "\nthis machine, between the frames: an eventfd write that wakes a thread asleep "
                "in epoll_wait (as each send wakes ZeroMQ's idle I/O thread) takes the writer %s; "
                "the same write with no thread waiting %s\n",
                cell(wake["sleeping_thread"]).c_str(), cell(wake["write_alone"]).c_str());
  out += line;
  return out;
}

}  // namespace fabrik::bench
