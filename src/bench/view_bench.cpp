#include "view_bench.hpp"

#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "config/daemon_config.hpp"
#include "stats.hpp"
#include "transport/pose_codec.hpp"
#include "view/view_server.hpp"
#include "view/ws_client.hpp"

namespace fabrik::bench {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

// The frame number of a view message, without decoding the rest.
bool message_frame(const std::string& text, std::uint64_t& frame) {
  if (text.compare(0, 16, R"({"topic":"pose",)") != 0) return false;
  const auto at = text.find("\"frame\":");
  if (at == std::string::npos) return false;
  const char* p = text.data() + at + 8;
  return std::from_chars(p, text.data() + text.size(), frame).ec == std::errc();
}

// A pose as fabrikd publishes it for the default config (JSON), frame numbers changed per send.
class PoseSource {
 public:
  PoseSource() : config_(default_daemon_config()), tracker_(config_.tracker) {
    const std::size_t n = config_.tracker.markers.size();
    std::vector<Eigen::Vector3d> measured(n);
    for (std::size_t i = 0; i < n; ++i)
      measured[i] = Eigen::Vector3d(0.02 * static_cast<double>(i % 7), 0.9 + 0.03 * static_cast<double>(i), 0.1);
    const std::vector<std::uint8_t> visible(n, 1);
    result_ = &tracker_.track(0.0, measured, visible);
    encoder_ = std::make_unique<wire::PoseEncoder>(tracker_, config_.output_units,
                                                   wire::PayloadEncoding::json);
  }
  const std::string& pose(std::uint64_t frame) {
    wire::PoseHeader h;
    h.frame = frame;
    h.has_time = true;
    h.time_s = static_cast<double>(frame) * 1e-3;
    encoder_->encode(h, *result_, out_);
    return out_;
  }

 private:
  DaemonConfig config_;
  Tracker tracker_;
  const TrackResult* result_ = nullptr;
  std::unique_ptr<wire::PoseEncoder> encoder_;
  std::string out_;
};

json run_once(const ViewBenchOptions& o, int clients, PoseSource& source) {
  constexpr std::size_t kRing = 1 << 16;
  std::vector<std::atomic<std::int64_t>> arrival(kRing);
  zmq::context_t context(1);
  zmq::socket_t pub(context, zmq::socket_type::pub);
  pub.set(zmq::sockopt::linger, 0);
  pub.bind("tcp://127.0.0.1:*");
  view::ViewOptions vo;
  vo.pose_endpoint = pub.get(zmq::sockopt::last_endpoint);
  vo.listen_port = 0;
  vo.rate_hz = o.rate_hz;
  vo.max_clients = std::max(16, clients);
  vo.web_root = FABRIK_VIEW_WEB_ROOT;
  vo.on_pose = [&](std::uint64_t frame) {
    arrival[frame % kRing].store(now_ns(), std::memory_order_relaxed);
  };
  view::ViewServer server(context, vo);
  server.start();

  std::atomic<bool> publishing{true};
  std::atomic<std::uint64_t> sent{0};
  std::thread publisher([&] {
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / o.input_hz));
    auto next = Clock::now();
    std::uint64_t frame = 0;
    while (publishing.load()) {
      const std::string& payload = source.pose(++frame);
      zmq::message_t parts[] = {zmq::message_t(std::string_view("pose")), zmq::message_t(payload)};
      zmq::send_multipart(pub, parts, zmq::send_flags::dontwait);
      sent.store(frame);
      next += period;
      std::this_thread::sleep_until(next);
    }
  });
  // The subscription settles before measuring.
  const auto settle = Clock::now() + std::chrono::seconds(5);
  while (server.counters().poses == 0 && Clock::now() < settle)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));

  std::vector<std::unique_ptr<view::client::WsClient>> ws;
  for (int i = 0; i < clients; ++i)
    ws.push_back(std::make_unique<view::client::WsClient>(server.port()));
  std::vector<std::vector<double>> latency_ms(clients);
  std::vector<std::uint64_t> received(clients, 0);
  std::atomic<bool> measuring{false};
  std::atomic<bool> reading{true};
  std::vector<std::thread> readers;
  for (int i = 0; i < clients; ++i)
    readers.emplace_back([&, i] {
      while (reading.load()) {
        const auto text = ws[i]->read(std::chrono::milliseconds(1000));
        if (!text) break;
        const std::int64_t t = now_ns();
        std::uint64_t frame = 0;
        if (!measuring.load() || !message_frame(*text, frame)) continue;
        ++received[i];
        const std::int64_t a = arrival[frame % kRing].load(std::memory_order_relaxed);
        if (a > 0) latency_ms[i].push_back(1e-6 * static_cast<double>(t - a));
      }
    });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // warm-up, clients connected
  const double cpu0_s = server.cpu_seconds();
  const std::uint64_t sent0 = sent.load();
  const auto t0 = Clock::now();
  measuring = true;
  std::this_thread::sleep_until(t0 + std::chrono::duration_cast<Clock::duration>(
                                         std::chrono::duration<double>(o.seconds)));
  measuring = false;
  const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const double cpu_s = server.cpu_seconds() - cpu0_s;
  const std::uint64_t sent1 = sent.load();
  const view::ViewCounters counters = server.counters();
  reading = false;
  publishing = false;
  publisher.join();
  for (auto& t : readers) t.join();
  server.stop();

  std::vector<double> all;
  double min_rate = 1e300, sum_rate = 0.0;
  for (int i = 0; i < clients; ++i) {
    all.insert(all.end(), latency_ms[i].begin(), latency_ms[i].end());
    const double r = static_cast<double>(received[i]) / wall_s;
    min_rate = std::min(min_rate, r);
    sum_rate += r;
  }
  std::uint64_t dropped = 0;
  for (const auto& c : counters.clients) dropped += c.dropped;
  return {{"clients", clients},
          {"input_hz", static_cast<double>(sent1 - sent0) / wall_s},
          {"poses_per_s_per_client", {{"mean", sum_rate / clients}, {"min", min_rate}}},
          {"latency_ms",
           {{"p50", quantile(all, 0.5)}, {"p95", quantile(all, 0.95)}, {"p99", quantile(all, 0.99)},
            {"samples", all.size()}}},
          {"view_cpu_percent", 100.0 * cpu_s / wall_s},
          {"dropped_slow", dropped},
          {"seconds", wall_s}};
}

}  // namespace

json run_view_bench(const ViewBenchOptions& o) {
  PoseSource source;
  json runs = json::array();
  for (int clients : o.clients) runs.push_back(run_once(o, clients, source));
  return {{"rate_hz", o.rate_hz}, {"runs", runs}, {"pose_bytes", source.pose(1).size()}};
}

std::string view_bench_table(const json& r) {
  std::string s;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "fabrik view at %.0f Hz per client, poses of %zu bytes (JSON, default config)\n"
                "clients  input/s  poses/s per client (mean, min)  latency p50 / p95 / p99 ms  "
                "view CPU %% of a core  dropped (slow)\n",
                r["rate_hz"].get<double>(), r["pose_bytes"].get<std::size_t>());
  s += buf;
  for (const json& run : r["runs"]) {
    std::snprintf(buf, sizeof buf, "%7d  %7.0f  %14.1f %6.1f            %7.3f / %.3f / %.3f      %13.1f  %14llu\n",
                  run["clients"].get<int>(), run["input_hz"].get<double>(),
                  run["poses_per_s_per_client"]["mean"].get<double>(),
                  run["poses_per_s_per_client"]["min"].get<double>(),
                  run["latency_ms"]["p50"].get<double>(), run["latency_ms"]["p95"].get<double>(),
                  run["latency_ms"]["p99"].get<double>(), run["view_cpu_percent"].get<double>(),
                  static_cast<unsigned long long>(run["dropped_slow"].get<std::uint64_t>()));
    s += buf;
  }
  s += "latency: pose arrives at the view's SUB thread -> a client's read returns (loopback).\n";
  return s;
}

}  // namespace fabrik::bench
