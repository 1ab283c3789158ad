// The one check of a ZeroMQ endpoint before a socket opens it, for the daemon
// config, fabrikd's --input/--output and the `fabrik` tools' --to/--from.
// ZeroMQ takes a tcp port modulo 65536 (tcp://127.0.0.1:99999 binds 34463,
// :-1 binds 65535), so an out-of-range port would open a socket nobody asked
// for: ports must be 1-65535 in digits, or * for a bind to any free port.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "daemon_config.hpp"

namespace fabrik {

struct EndpointProblem {
  std::string problem, fix;
};

// What is wrong with `address` for a socket in `mode`, or nothing. Checked:
// transport://address form; for tcp, udp, ws, wss, pgm and epgm the port of
// the (last) destination. Other transports (ipc, inproc, ...) are left to
// ZeroMQ.
std::optional<EndpointProblem> endpoint_problem(std::string_view address, SocketMode mode);

// For command-line endpoints: std::invalid_argument "<option>: <problem>. Fix:
// <fix>" (safe text), naming the option so the message says where to fix it.
void require_usable_endpoint(std::string_view address, SocketMode mode, std::string_view option);

}  // namespace fabrik
