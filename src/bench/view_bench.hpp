// `fabrik bench view`: `fabrik view`'s server in-process, fed poses at a fixed rate (1 kHz) by
// a ZeroMQ PUB over loopback tcp as fabrikd would publish them; 1 and 5 WebSocket clients
// (Beast) read as fast as they can. Prints poses per second delivered per client, latency
// from a pose's arrival at the view (its SUB thread) to a client's receive, and the CPU of
// the view's own two threads as % of one core. Figures only, no pass/fail.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct ViewBenchOptions {
  double input_hz = 1000.0;
  double rate_hz = 60.0;  // the view's per-client cap
  double seconds = 5.0;   // per client count
  std::vector<int> clients = {1, 5};
};
nlohmann::json run_view_bench(const ViewBenchOptions& options);
std::string view_bench_table(const nlohmann::json& result);

}  // namespace fabrik::bench
