#include "endpoint_check.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

#include "common/ascii_case.hpp"
#include "common/edit_distance.hpp"
#include "common/safe_text.hpp"

namespace fabrik {

namespace {

constexpr const char* kPortFix =
    "use a port from 1 to 65535, e.g. tcp://127.0.0.1:5555, or * to bind any free port "
    "(tcp://127.0.0.1:*)";

// A port written in digits, leading zeros being none of them: its value, at most 100000
// (more than five digits); nullopt when it is not digits alone.
std::optional<unsigned long> port_number(std::string_view port) {
  if (port.empty() ||
      !std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  const std::string_view digits = port.substr(std::min(port.find_first_not_of('0'), port.size()));
  return digits.size() > 5 ? 100000 : std::stoul("0" + std::string(digits));
}

// An endpoint taken apart for its port: the transport, and the host:port the port is read from
// (after a tcp source;destination or pgm interface;group, the destination's; a ws path cut
// first, since it may hold ';' and ':' of its own). `host_port` is empty for a transport without
// a port (ipc, inproc, ...), left to ZeroMQ.
struct EndpointParts {
  std::string_view scheme, host_port;
};

// Every transport of libzmq 4.3, drafts included (a later one's vsock would need adding);
// which of them this one has depends on its build (ws, pgm, norm, ...), left to its
// EPROTONOSUPPORT at the bind (open_socket's fix).
constexpr std::array<std::string_view, 11> kZmqTransports = {
    "tcp", "ipc", "inproc", "udp", "ws", "wss", "pgm", "epgm", "norm", "tipc", "vmci"};

bool transport_has_port(std::string_view scheme) {
  return scheme == "tcp" || scheme == "udp" || scheme == "ws" || scheme == "wss" ||
         scheme == "pgm" || scheme == "epgm";
}

// nullopt when `address` is not transport://address.
std::optional<EndpointParts> endpoint_parts(std::string_view address) {
  const auto scheme_end = address.find("://");
  if (scheme_end == std::string_view::npos || scheme_end == 0) return std::nullopt;
  EndpointParts parts{address.substr(0, scheme_end), {}};
  if (!transport_has_port(parts.scheme)) return parts;
  std::string_view rest = address.substr(scheme_end + 3);
  if (parts.scheme == "ws" || parts.scheme == "wss")
    rest = rest.substr(0, rest.find('/'));  // ws://host:port/path
  if (const auto semicolon = rest.rfind(';'); semicolon != std::string_view::npos)
    rest.remove_prefix(semicolon + 1);
  parts.host_port = rest;
  return parts;
}

struct HostAndPort {
  std::string_view host, port;
};

// Split at the last colon outside [IPv6] brackets; nullopt without one.
std::optional<HostAndPort> split_port(std::string_view host_port) {
  const auto colon = host_port.rfind(':');
  if (colon == std::string_view::npos ||
      (host_port.find(']') != std::string_view::npos && colon < host_port.rfind(']')))
    return std::nullopt;
  return HostAndPort{host_port.substr(0, colon), host_port.substr(colon + 1)};
}

// One spelling per host: lower case, without [ ], "localhost" as 127.0.0.1, an IPv6 address
// as inet_ntop writes it (0:0:0:0:0:0:0:0 and ::0 are ::, 0::1 is ::1), and an IPv4-mapped
// address as its IPv4 address (ZeroMQ's IPv6 socket reaches it so).
std::string canonical_host(std::string_view host) {
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  std::string out = ascii_lower(host);
  if (out == "localhost") return "127.0.0.1";
  in6_addr v6{};
  char canonical[INET6_ADDRSTRLEN] = {};
  if (inet_pton(AF_INET6, out.c_str(), &v6) == 1 &&
      inet_ntop(AF_INET6, &v6, canonical, sizeof canonical) != nullptr)
    out = canonical;
  if (out.starts_with("::ffff:") && out.find('.') != std::string::npos) out = out.substr(7);
  return out;
}

struct TcpAddress {
  std::string host;        // canonical_host
  unsigned long port = 0;  // 0: * or unreadable
  bool any_port = false;   // *: a bind chooses a free one
};

std::optional<TcpAddress> tcp_address(std::string_view address) {
  const auto parts = endpoint_parts(address);
  if (!parts || parts->scheme != "tcp") return std::nullopt;
  const auto split = split_port(parts->host_port);
  if (!split) return std::nullopt;
  TcpAddress t;
  t.any_port = split->port == "*";
  if (const auto value = port_number(split->port); value && *value <= 65535) t.port = *value;
  t.host = canonical_host(split->host);
  return t;
}

bool any_address(const std::string& host) {
  return host == "*" || host == "0.0.0.0" || host == "::";
}

bool this_machine(const std::string& host) {
  return host.starts_with("127.") || host == "::1";
}

}  // namespace

Endpoint endpoint_option(std::string_view spec, SocketMode mode, std::string_view option,
                         std::string_view mode_option) {
  Endpoint out{std::string(spec), mode};
  for (auto [prefix, prefixed] : {std::pair{std::string_view("bind:"), SocketMode::bind},
                                  std::pair{std::string_view("connect:"), SocketMode::connect}}) {
    if (!spec.starts_with(prefix)) continue;
    if (!mode_option.empty() && prefixed != mode)
      throw std::invalid_argument(safe_text(std::string(option) + ": '" + std::string(spec) +
                                                "' connects, and " + std::string(mode_option) +
                                                " binds. Fix: give one of them",
                                            1024));
    out = {std::string(spec.substr(prefix.size())), prefixed};
  }
  require_usable_endpoint(out.address, out.mode, option);
  return out;
}

bool binds_any_address(std::string_view address) {
  const auto parts = endpoint_parts(address);
  if (!parts || (parts->scheme != "tcp" && parts->scheme != "udp" && parts->scheme != "ws" &&
                 parts->scheme != "wss"))
    return false;
  const auto split = split_port(parts->host_port);
  return split && any_address(canonical_host(split->host));
}

std::optional<std::string> tcp_host_name(std::string_view address) {
  const auto parts = endpoint_parts(address);
  if (!parts || parts->scheme != "tcp") return std::nullopt;
  const auto split = split_port(parts->host_port);
  if (!split || split->host.empty() || split->host == "*" || split->host.front() == '[')
    return std::nullopt;
  return std::string(split->host);
}

bool ipv6_literal(std::string_view address) {
  return address.find("://[") != std::string_view::npos ||
         address.find(";[") != std::string_view::npos;
}

bool endpoints_clash(const Endpoint& a, const Endpoint& b) {
  const auto ta = tcp_address(a.address), tb = tcp_address(b.address);
  if (!ta || !tb) return a.address == b.address;
  if (ta->any_port || tb->any_port) return false;
  if (ta->port != tb->port) return false;
  if (ta->host == tb->host) return true;
  const bool a_bind = a.mode == SocketMode::bind, b_bind = b.mode == SocketMode::bind;
  if (a_bind && b_bind) return any_address(ta->host) || any_address(tb->host);
  if (a_bind != b_bind) {
    const TcpAddress& bound = a_bind ? *ta : *tb;
    const TcpAddress& connected = a_bind ? *tb : *ta;
    return this_machine(connected.host) && any_address(bound.host);
  }
  return false;
}

std::string clash_spelling(const Endpoint& a, const Endpoint& b) {
  return a.address == b.address ? "" : " ('" + b.address + "', one port of this machine)";
}

// A lower-case word no libzmq has (a typo: tpc://): would fail only at the bind, "Protocol not
// supported". The fix names the transports one typo away, the endpoint rewritten if one is.
EndpointProblem unknown_transport(std::string_view address, std::string_view scheme) {
  std::string all, near;
  std::string_view first_near;
  int near_count = 0;
  for (const std::string_view t : kZmqTransports) {
    // udp is ZeroMQ's, but not for fabrikd's sockets: said where it is listed.
    all += (all.empty() ? "" : ", ") + std::string(t) + (t == "udp" ? " (not for PUB/SUB)" : "");
    if (t == "udp" || typo_distance(scheme, t) > 1) continue;  // udp: refused below
    near += (near.empty() ? "" : ", ") + std::string(t) + "://";
    if (near_count++ == 0) first_near = t;
  }
  const std::string rest(address.substr(scheme.size()));
  std::string fix;
  if (near_count == 1)
    fix = "write \"" + std::string(first_near) + rest + "\"";
  else if (near_count > 1)
    fix =
        "write the transport meant (" + near + "), e.g. \"" + std::string(first_near) + rest + "\"";
  else
    fix = "write tcp://, ipc:// or inproc://, e.g. \"tcp://127.0.0.1:5555\"";
  return EndpointProblem{"transport '" + std::string(scheme) + "' of '" + std::string(address) +
                             "' is not one ZeroMQ has (" + all + ")",
                         fix};
}

std::optional<EndpointProblem> endpoint_problem(std::string_view address, SocketMode mode) {
  const std::string quoted = "'" + std::string(address) + "'";
  const auto parts = endpoint_parts(address);
  if (!parts)
    return EndpointProblem{quoted + " is not a ZeroMQ endpoint",
                           "write transport://address, e.g. \"tcp://127.0.0.1:5555\", "
                           "\"ipc:///tmp/fabrikd.sock\" or \"inproc://markers\""};
  // ZeroMQ's transports are lower-case words: TCP:// would fail at the bind with "Protocol not
  // supported" (and the config schema refuses it).
  const auto lower_case_word = [](std::string_view word) {
    return !word.empty() &&
           std::all_of(word.begin(), word.end(), [](char c) { return c >= 'a' && c <= 'z'; });
  };
  if (!lower_case_word(parts->scheme)) {
    const std::string lower = ascii_lower(parts->scheme);
    std::string fix = "write tcp://, ipc:// or inproc://, e.g. \"tcp://127.0.0.1:5555\"";
    if (lower.starts_with("bind:") || lower.starts_with("connect:"))
      fix =
          "give the mode apart: \"mode\" in a config, one bind: or connect: before the "
          "endpoint on a command line";
    else if (lower_case_word(lower))
      fix = "write \"" + lower + std::string(address.substr(parts->scheme.size())) + "\"";
    return EndpointProblem{"transport '" + std::string(parts->scheme) + "' of " + quoted +
                               " is not one ZeroMQ knows (they are lower-case words)",
                           fix};
  }
  if (std::find(kZmqTransports.begin(), kZmqTransports.end(), parts->scheme) ==
      kZmqTransports.end())
    return unknown_transport(address, parts->scheme);
  // ZeroMQ takes udp for RADIO and DISH sockets only; every endpoint fabrikd and its tools
  // open is PUB/SUB (the bind fails: "The protocol is not compatible with the socket type").
  if (parts->scheme == "udp")
    return EndpointProblem{quoted +
                               ": ZeroMQ's udp:// serves RADIO and DISH sockets only, and "
                               "fabrikd's are PUB and SUB",
                           "use tcp://, or pgm:// or epgm:// for multicast"};
  if (!transport_has_port(parts->scheme)) return std::nullopt;
  const auto split = split_port(parts->host_port);
  if (!split) return EndpointProblem{quoted + " has no port", "add one: " + std::string(kPortFix)};
  const std::string_view port = split->port;
  const std::string quoted_port = "'" + std::string(port) + "'";
  if (port == "*") {
    if (mode == SocketMode::bind) return std::nullopt;
    return EndpointProblem{
        "port * of " + quoted + " means any free port, which only a bind can choose",
        "connect to the port the peer binds, e.g. tcp://127.0.0.1:5555"};
  }
  const std::optional<unsigned long> number = port_number(port);
  if (!number)
    return EndpointProblem{"port " + quoted_port + " of " + quoted + " is not a port number",
                           kPortFix};
  const unsigned long value = *number;
  if (value == 0)
    return EndpointProblem{
        "port 0 of " + quoted + " is not a port (ZeroMQ would bind any free port)", kPortFix};
  if (value > 65535)
    return EndpointProblem{"port " + quoted_port + " of " + quoted +
                               " is out of range (ZeroMQ would silently use it modulo 65536)",
                           kPortFix};
  return std::nullopt;
}

void require_usable_endpoint(std::string_view address, SocketMode mode, std::string_view option) {
  if (auto p = endpoint_problem(address, mode))
    throw std::invalid_argument(
        safe_text(std::string(option) + ": " + p->problem + ". Fix: " + p->fix, 1024));
}

}  // namespace fabrik
