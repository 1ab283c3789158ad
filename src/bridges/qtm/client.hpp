// A QTM RT protocol client (TCP) feeding fabrikd: connects, negotiates the
// protocol version, reads the 3D labels, streams 3D frames, and on any
// failure records it in SourceStatus, waits with backoff and connects again.
// The protocol facts it relies on are in docs/qtm-rt-protocol.md.
#pragma once

#include <cstdint>
#include <stop_token>
#include <string>

#include "bridges/source.hpp"

namespace fabrik::qtm {

struct QtmClientOptions {
  std::string host;
  // QTM's little-endian port (base + 1). The byte order is the one the server's
  // welcome packet is written in (QTM picks it by port: 22223 little, 22224 big).
  std::uint16_t port = 22223;
  int frequency_divisor = 1;  // 1 = all frames; n = every n-th real-time frame
  bridges::ConnectionPolicy policy;
};

// Runs until `stop`; never throws, never logs. Calls the sink on this thread.
void run_qtm_client(const QtmClientOptions& options, bridges::FrameSink& sink, bridges::SourceStatus& status,
                    std::stop_token stop);

}  // namespace fabrik::qtm
