// Binding or connecting a ZeroMQ socket, and saying why it failed in words a
// user can act on. fabrikd's sockets, the tools' (replay --to, watch --from)
// and the view's --pose all open through here, so one errno gets one advice.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

#include <zmq.hpp>

#include "config/daemon_config.hpp"

namespace fabrik::wire {

// What the caller's user can change, worded for where they change it.
struct OpenAdvice {
  std::string socket;      // named in the problem: "the input socket", or empty
  std::string change_at;   // where the endpoint is given: "here or with --input", "with --to"
  std::string to_connect;  // how to connect instead of binding: "leave out --bind"
  // Offered for a taken port, after choosing another: where the holder may be
  // the program to reach (fabrikd's input for `replay --bind`), not a twin.
  std::string when_taken;
};

// Why binding or connecting failed, and what to do about it.
struct OpenFailure {
  std::string problem;  // "cannot bind the input socket to 'A': <ZeroMQ's reason>"
  std::string fix;
  int error = 0;  // ZeroMQ's errno

  // "<option>: <problem>. Fix: <fix>", for an endpoint given on the command line.
  std::string message(std::string_view option) const {
    return std::string(option) + ": " + problem + ". Fix: " + fix;
  }
};

// Binds (mode bind) or connects `socket` to `address` (an IPv6 literal
// switches the socket to IPv6 first); nothing on success.
std::optional<OpenFailure> open_socket(zmq::socket_t& socket, const std::string& address,
                                       SocketMode mode, const OpenAdvice& advice);

// For a tcp:// endpoint to connect to by host name: why that name cannot be resolved, if the
// resolver says it does not exist (ZeroMQ would retry it for ever, silently). Nothing for an
// address, another transport, or a resolver that could not answer now. Blocks on the
// resolver: for setup only (`fabrik view --pose`), never on a frame loop.
std::optional<OpenFailure> unknown_host(const std::string& address);

// The same, waiting at most `wait` for the resolver (a broken one can take many seconds):
// nothing when it has not answered by then. The lookup goes on in a thread of its own, which
// ends when the resolver answers.
std::optional<OpenFailure> unknown_host_within(const std::string& address,
                                               std::chrono::milliseconds wait);

}  // namespace fabrik::wire
