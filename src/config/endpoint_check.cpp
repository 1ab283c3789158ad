#include "endpoint_check.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <stdexcept>
#include <string>

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

struct TcpAddress {
  std::string host;        // lower case, without [ ]; "localhost" as 127.0.0.1
  unsigned long port = 0;  // 0: * or unreadable
  bool any_port = false;   // *: a bind chooses a free one
};

std::optional<TcpAddress> tcp_address(std::string_view address) {
  if (!address.starts_with("tcp://")) return std::nullopt;
  std::string_view rest = address.substr(6);
  if (const auto semicolon = rest.rfind(';'); semicolon != std::string_view::npos)
    rest.remove_prefix(semicolon + 1);
  const auto colon = rest.rfind(':');
  if (colon == std::string_view::npos) return std::nullopt;
  const std::string_view port = rest.substr(colon + 1);
  TcpAddress t;
  t.any_port = port == "*";
  if (const auto value = port_number(port); value && *value <= 65535) t.port = *value;
  std::string_view host = rest.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  for (char c : host) t.host += static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  if (t.host == "localhost") t.host = "127.0.0.1";
  // One spelling per IPv6 address (0:0:0:0:0:0:0:0 and ::0 are ::, 0::1 is ::1).
  in6_addr v6{};
  char canonical[INET6_ADDRSTRLEN] = {};
  if (inet_pton(AF_INET6, t.host.c_str(), &v6) == 1 &&
      inet_ntop(AF_INET6, &v6, canonical, sizeof canonical) != nullptr)
    t.host = canonical;
  // An IPv4-mapped address is that IPv4 address (ZeroMQ's IPv6 socket reaches it so).
  if (t.host.starts_with("::ffff:") && t.host.find('.') != std::string::npos)
    t.host = t.host.substr(7);
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
  const auto scheme_end = address.find("://");
  if (scheme_end == std::string_view::npos) return false;
  const std::string_view scheme = address.substr(0, scheme_end);
  std::string_view rest = address.substr(scheme_end + 3);
  if (scheme == "ws" || scheme == "wss")
    rest = rest.substr(0, rest.find('/'));  // ws://host:port/path
  else if (scheme != "tcp" && scheme != "udp")
    return false;
  const auto t = tcp_address("tcp://" + std::string(rest));
  return t && any_address(t->host);
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

std::optional<EndpointProblem> endpoint_problem(std::string_view address, SocketMode mode) {
  const std::string quoted = "'" + std::string(address) + "'";
  const auto scheme_end = address.find("://");
  if (scheme_end == std::string_view::npos || scheme_end == 0)
    return EndpointProblem{quoted + " is not a ZeroMQ endpoint",
                           "write transport://address, e.g. \"tcp://127.0.0.1:5555\", "
                           "\"ipc:///tmp/fabrikd.sock\" or \"inproc://markers\""};
  const std::string_view scheme = address.substr(0, scheme_end);
  const bool ws = scheme == "ws" || scheme == "wss";
  if (!ws && scheme != "tcp" && scheme != "udp" && scheme != "pgm" && scheme != "epgm")
    return std::nullopt;
  std::string_view rest = address.substr(scheme_end + 3);
  // tcp source;destination and pgm interface;group: the port is the destination's. A ws
  // path may hold ';' and ':' of its own: it goes first.
  if (ws) rest = rest.substr(0, rest.find('/'));  // ws://host:port/path
  if (const auto semicolon = rest.rfind(';'); semicolon != std::string_view::npos)
    rest.remove_prefix(semicolon + 1);
  const auto colon = rest.rfind(':');
  // A colon inside [IPv6] brackets is not the port's.
  if (colon == std::string_view::npos ||
      (rest.find(']') != std::string_view::npos && colon < rest.rfind(']')))
    return EndpointProblem{quoted + " has no port", "add one: " + std::string(kPortFix)};
  const std::string_view port = rest.substr(colon + 1);
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
