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
// transport://address form; a transport of libzmq 4.3 other than udp (which
// serves RADIO/DISH sockets only); for tcp, ws, wss, pgm and epgm the port of
// the (last) destination. Other transports (ipc, inproc, ...) are left to
// ZeroMQ.
std::optional<EndpointProblem> endpoint_problem(std::string_view address, SocketMode mode);

// For command-line endpoints: std::invalid_argument "<option>: <problem>. Fix:
// <fix>" (safe text), naming the option so the message says where to fix it.
void require_usable_endpoint(std::string_view address, SocketMode mode, std::string_view option);

// An endpoint given on a command line: "bind:ENDPOINT" or "connect:ENDPOINT" chooses the mode,
// a bare endpoint takes `mode`; checked as require_usable_endpoint (std::invalid_argument
// naming `option`). With `mode_option` (a tool's --bind flag, given), a prefix that says
// otherwise is refused too.
Endpoint endpoint_option(std::string_view spec, SocketMode mode, std::string_view option,
                         std::string_view mode_option = {});

// Whether a tcp `address` names any address of its host (*, 0.0.0.0, or :: however it is
// written): bound there, the socket is reached at one of the host's own addresses.
bool binds_any_address(std::string_view address);

// The host name a tcp `address` connects to, for a resolver ("nohost.invalid" of
// "tcp://nohost.invalid:5556", the destination's after a "source;"); nothing for another
// transport, a wildcard or an IPv6 literal.
std::optional<std::string> tcp_host_name(std::string_view address);

// Whether `address` names an IPv6 literal host (tcp://[::1]:5555, a source's or destination's):
// ZeroMQ resolves one only on a socket with ZMQ_IPV6 set ("No such device" otherwise).
bool ipv6_literal(std::string_view address);

// Whether two sockets of one process would meet at one address: the same text, or tcp on the
// same port where both bind hosts that overlap (one of them any address: *, 0.0.0.0, ::) or
// one connects to this machine (localhost, 127.x.x.x, ::1) where the other binds it or any
// address. Port * never clashes (each bind gets a free port of its own). A connect to one of this
// machine's other addresses is not seen (that would take its interfaces); ZeroMQ's own bind error
// still stops a double bind.
bool endpoints_clash(const Endpoint& a, const Endpoint& b);

// For the message of a clash of `a` with `b`: "" when they are written alike, else
// " ('B', one port of this machine)".
std::string clash_spelling(const Endpoint& a, const Endpoint& b);

}  // namespace fabrik
