// A wire::Daemon running on a thread of its own for tests: stop() asks it to
// stop and waits a bounded time, aborting the test run with a message if it
// does not (a wedged daemon would otherwise hang ctest until its timeout).
#pragma once

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <thread>

#include "transport/daemon.hpp"

namespace fabrik::test {

struct DaemonThread {
  DaemonThread(zmq::context_t& context, DaemonConfig config,
               wire::Daemon::SourceClientFactory f = {})
      : daemon(context, std::move(config), std::move(f)) {
    thread = std::thread([this] {
      daemon.run(control);
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
  wire::Daemon daemon;
  wire::DaemonControl control;
  std::promise<void> done;
  std::future<void> finished = done.get_future();
  std::thread thread;
};

}  // namespace fabrik::test
