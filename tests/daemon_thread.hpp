// A wire::Daemon running on a thread of its own for in-process tests, its config on inproc
// endpoints and a vendor source read as a config's "input" would be, and a comparison of two
// documents' numbers (poses from two daemons).
#pragma once

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <future>
#include <nlohmann/json.hpp>
#include <thread>

#include "config/json_reader.hpp"
#include "config/source_config.hpp"
#include "transport/daemon.hpp"

namespace fabrik::test {

// `c` on inproc endpoints named after `tag`, with stats every 50 ms.
inline DaemonConfig on_inproc(DaemonConfig c, const std::string& tag) {
  c.input = {"inproc://" + tag + "-markers", SocketMode::bind};
  c.output = {"inproc://" + tag + "-poses", SocketMode::bind};
  c.stats_interval_s = 0.05;
  return c;
}

// A source as a config's "input" object gives it (`{"source": "natnet://..."}`).
inline SourceConfig source_of(const std::string& input_json) {
  const nlohmann::json j = nlohmann::json::parse(input_json);
  return read_source_config(JsonReader(j, "test.json", "/input"));
}

// Stops the daemon on destruction; a daemon that does not stop within 5 s
// aborts the test run with a message (a wedged loop must fail, not hang).
struct DaemonThread {
  // `load`: what a reload (control.reload) reads; empty: reloads are refused.
  DaemonThread(zmq::context_t& context, DaemonConfig config,
               wire::Daemon::SourceClientFactory source_client = {},
               std::function<DaemonConfig()> load = {})
      : daemon(context, std::move(config), std::move(source_client)), load_config(std::move(load)) {
    thread = std::thread([this] {
      daemon.run(control, load_config);
      done.set_value();
    });
  }
  ~DaemonThread() { stop(); }
  // Seconds from the request until run() returned (0 when already stopped).
  double stop() {
    if (!thread.joinable()) return 0.0;
    const auto t0 = std::chrono::steady_clock::now();
    control.stop = true;
    if (finished.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
      std::fprintf(stderr, "FAILED: the daemon did not stop within 5 s\n");
      std::abort();
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    thread.join();
    return s;
  }
  DaemonThread(const DaemonThread&) = delete;
  DaemonThread& operator=(const DaemonThread&) = delete;

  wire::Daemon daemon;
  std::function<DaemonConfig()> load_config;
  wire::DaemonControl control;
  std::promise<void> done;
  std::future<void> finished = done.get_future();
  std::thread thread;
};

// The largest difference between the numbers of two documents of the same
// shape; infinity where the shapes, keys or other values differ.
inline double largest_difference(const nlohmann::json& a, const nlohmann::json& b) {
  if (a.is_number() && b.is_number()) return std::abs(a.get<double>() - b.get<double>());
  if (a.type() != b.type() || a.size() != b.size()) return INFINITY;
  double d = 0;
  if (a.is_object()) {
    for (const auto& [k, v] : a.items())
      d = std::max(d, b.contains(k) ? largest_difference(v, b.at(k)) : INFINITY);
    return d;
  }
  if (a.is_array()) {
    for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, largest_difference(a[i], b[i]));
    return d;
  }
  return a == b ? 0.0 : INFINITY;
}

}  // namespace fabrik::test
