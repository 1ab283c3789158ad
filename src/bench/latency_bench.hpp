// `fabrik bench latency`: the daemon pipeline (decode, solve, encode,
// publish) on its own thread, fed by a marker source at a fixed rate over
// loopback tcp and ipc; end-to-end latency from the source's send to the
// subscriber's receive, on one steady clock.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fabrik::bench {

struct LatencyOptions {
  double rate_hz = 1000.0;
  double seconds = 10.0;
  std::vector<std::string> transports = {"tcp", "ipc"};
  std::string encoding = "json";  // of the marker frames and poses
  // "none"; "mixed": markers plus an orientation sensor on every segment;
  // "only": the sensors alone (the frames' `orientations`, wire contract addition).
  std::string orientations = "none";
};
nlohmann::json run_latency(const LatencyOptions& options);
std::string latency_table(const nlohmann::json& result);

}  // namespace fabrik::bench
