#include "subjects_bench.hpp"

#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <stdexcept>
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

// `count` subjects S1..Sn, each the subject config `one` describes.
DaemonConfig subjects_config(const DaemonConfig& one, int count) {
  DaemonConfig c = one;
  c.subjects.clear();
  for (int k = 0; k < count; ++k)
    c.subjects.push_back({"S" + std::to_string(k + 1), one.file, one.tracker, one.sensors});
  c.input = {"tcp://127.0.0.1:*", SocketMode::bind};
  c.output = {"tcp://127.0.0.1:*", SocketMode::bind};
  c.max_backlog_frames = 16;
  return c;
}

// Every subject's markers at time t_s (subject k 2 m along x, its motion
// 0.37 s ahead of the one before), names Sk:Marker, as one frame.
class Frames {
 public:
  Frames(const DaemonConfig& c) : setup_(c.subjects.front().tracker), motion_(*setup_.model, {}) {
    for (const SubjectConfig& s : c.subjects)
      for (const MarkerTarget& m : setup_.markers) {
        names_.push_back(s.name + ":" + m.marker);
        points_.push_back(m.point);
      }
    p_m_.resize(names_.size());
    visible_.assign(names_.size(), 1);
    posture_ = Posture::rest(*setup_.model);
  }
  const std::string& at(std::uint64_t frame, double t_s) {
    const std::size_t per = setup_.markers.size();
    for (std::size_t k = 0; k * per < names_.size(); ++k) {
      motion_.posture_at(t_s + 0.37 * static_cast<double>(k), posture_);
      for (std::size_t i = 0; i < per; ++i)
        p_m_[k * per + i] = posture_.point_world_m(*setup_.model, points_[k * per + i]) +
                            Eigen::Vector3d(2.0 * static_cast<double>(k), 0, 0);
    }
    wire::encode_marker_frame(frame, &t_s, names_, p_m_, visible_, "mm", wire::PayloadEncoding::json,
                              out_);
    return out_;
  }

 private:
  const TrackerSetup& setup_;
  SyntheticMotion motion_;
  Posture posture_;
  std::vector<std::string> names_;
  std::vector<int> points_;
  std::vector<Eigen::Vector3d> p_m_;
  std::vector<std::uint8_t> visible_;
  std::string out_;
};

void send(zmq::socket_t& pub, const std::string& payload) {
  pub.send(zmq::buffer(std::string_view("markers")), zmq::send_flags::sndmore);
  pub.send(zmq::buffer(payload));
}

nlohmann::json run_count(const DaemonConfig& one, int count, const SubjectsOptions& o) {
  zmq::context_t context;
  wire::Daemon daemon(context, subjects_config(one, count));
  wire::DaemonControl control;
  std::thread loop([&] { daemon.run(control); });
  struct Stop {
    wire::DaemonControl& control;
    std::thread& loop;
    ~Stop() {
      control.stop = true;
      loop.join();
    }
  } stop{control, loop};
  zmq::socket_t pub(context, zmq::socket_type::pub), sub(context, zmq::socket_type::sub);
  pub.set(zmq::sockopt::linger, 0);
  sub.set(zmq::sockopt::linger, 0);
  const std::string last = "pose/S" + std::to_string(count);
  sub.set(zmq::sockopt::subscribe, last);  // the last subject's poses only
  pub.connect(daemon.input_endpoint());
  sub.connect(daemon.output_endpoint());
  Frames frames(daemon.config());
  const auto receive = [&](std::chrono::milliseconds timeout, std::uint64_t& frame) {
    zmq::pollitem_t items[] = {{sub.handle(), 0, ZMQ_POLLIN, 0}};
    if (zmq::poll(items, 1, timeout) <= 0) return false;
    zmq::message_t t, p;
    (void)sub.recv(t);
    if (!t.more() || !sub.recv(p)) return false;
    const std::string_view s = p.to_string_view();  // {"frame":N,...
    frame = 0;
    for (std::size_t i = 9; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i)
      frame = frame * 10 + static_cast<std::uint64_t>(s[i] - '0');
    return true;
  };
  // Handshake: probes until the last subject's pose comes back.
  bool joined = false;
  std::uint64_t got = 0;
  for (int i = 0; i < 600 && !joined; ++i) {
    send(pub, frames.at(1000000 + static_cast<std::uint64_t>(i), i * 0.001));
    joined = receive(std::chrono::milliseconds(50), got);
  }
  if (!joined) throw std::runtime_error("bench subjects: no pose came back from the daemon");
  while (receive(std::chrono::milliseconds(200), got)) {
  }
  const auto before = daemon.counters();
  const int n = static_cast<int>(o.rate_hz * o.seconds);
  std::vector<Clock::time_point> sent(static_cast<std::size_t>(n));
  std::vector<double> latency_us;
  latency_us.reserve(sent.size());
  std::atomic<int> sent_count{0};
  std::thread source([&] {
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / o.rate_hz));
    const Clock::time_point start = Clock::now();
    for (int i = 0; i < n; ++i) {
      std::this_thread::sleep_until(start + i * period);
      const std::string& payload = frames.at(static_cast<std::uint64_t>(i), 1.0 + i / o.rate_hz);
      sent[static_cast<std::size_t>(i)] = Clock::now();
      sent_count.store(i + 1, std::memory_order_release);
      send(pub, payload);
    }
  });
  // Until the last frame's pose, or 1 s without a pose after the source is done.
  for (;;) {
    if (!receive(std::chrono::milliseconds(1000), got)) {
      if (sent_count.load() == n) break;
      continue;
    }
    const Clock::time_point now = Clock::now();
    if (got < static_cast<std::uint64_t>(sent_count.load(std::memory_order_acquire)))
      latency_us.push_back(std::chrono::duration<double, std::micro>(now - sent[got]).count());
    if (got + 1 == static_cast<std::uint64_t>(n)) break;
  }
  source.join();
  const auto after = daemon.counters();
  nlohmann::json r;
  r["subjects"] = count;
  r["frames"] = n;
  r["answered"] = latency_us.size();
  r["unanswered"] = n - static_cast<int>(latency_us.size());
  r["daemon_frames_dropped"] = after.frames_dropped - before.frames_dropped;
  r["p50_us"] = quantile(latency_us, 0.5);
  r["p99_us"] = quantile(latency_us, 0.99);
  r["max_us"] = quantile(latency_us, 1.0);
  r["budget_us"] = 1e6 / o.rate_hz;
  return r;
}

}  // namespace

nlohmann::json run_subjects(const SubjectsOptions& o) {
  spdlog::set_level(spdlog::level::warn);
  const DaemonConfig one = o.config.empty() ? default_daemon_config() : load_daemon_config_file(o.config);
  if (!one.subjects.empty())
    throw std::runtime_error("bench subjects: --config names one subject's config, not a list");
  nlohmann::json result;
  result["rate_hz"] = o.rate_hz;
  result["seconds"] = o.seconds;
  result["markers_per_subject"] = one.tracker.markers.size();
  result["config"] = o.config.empty() ? "<embedded>/default.json" : o.config;
  result["hardware_threads"] = std::thread::hardware_concurrency();
  for (int count : o.counts) result["runs"].push_back(run_count(one, count, o));
  return result;
}

std::string subjects_table(const nlohmann::json& r) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line,
                "%d markers per subject at %.0f Hz (budget %.0f us), %.0f s per count, "
                "frame sent -> last subject's pose received (loopback tcp)\n",
                r["markers_per_subject"].get<int>(), r["rate_hz"].get<double>(),
                1e6 / r["rate_hz"].get<double>(), r["seconds"].get<double>());
  out += line;
  out += "subjects  frames  unanswered  dropped   p50 us   p99 us   max us  p50/p50(1)\n";
  const double base = r["runs"][0]["p50_us"].get<double>();
  for (const auto& run : r["runs"]) {
    std::snprintf(line, sizeof line, "%8d  %6d  %10d  %7d  %7.0f  %7.0f  %7.0f  %10.2f\n",
                  run["subjects"].get<int>(), run["frames"].get<int>(),
                  run["unanswered"].get<int>(), run["daemon_frames_dropped"].get<int>(),
                  run["p50_us"].get<double>(), run["p99_us"].get<double>(),
                  run["max_us"].get<double>(), run["p50_us"].get<double>() / base);
    out += line;
  }
  return out;
}

}  // namespace fabrik::bench
