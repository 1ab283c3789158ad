#include "open_socket.hpp"

#include <netdb.h>
#include <sys/socket.h>

#include <cerrno>
#include <future>
#include <memory>
#include <thread>

#include "config/endpoint_check.hpp"

namespace fabrik::wire {

namespace {

std::string fix_for(int error, const OpenAdvice& a) {
  const std::string change = a.change_at.empty() ? "" : " " + a.change_at;
  switch (error) {
    case EADDRINUSE:
      return "the port is taken (another fabrikd or tool running?): choose another port" + change +
             (a.when_taken.empty() ? std::string() : ", or " + a.when_taken);
    case EADDRNOTAVAIL:
    case ENODEV:
      return "bind to an address of this machine (127.0.0.1, or 0.0.0.0 for every interface)" +
             (a.to_connect.empty() ? std::string()
                                   : ", or " + a.to_connect + " to reach another machine");
    case EACCES:
      return "use a port above 1023, or a path you may write for ipc://";
    case EPROTONOSUPPORT:
      return "use a transport this ZeroMQ knows: tcp://, ipc:// or inproc:// (ws:// and pgm:// "
             "only where libzmq was built with them)" +
             change;
    case ENOCOMPATPROTO:  // udp:// on a PUB/SUB socket
      return "ZeroMQ's udp:// serves RADIO and DISH sockets only: use tcp://, or pgm:// or "
             "epgm:// for multicast" +
             change;
    default:
      return "check the endpoint (transport://address:port)" + change;
  }
}

}  // namespace

std::optional<OpenFailure> open_socket(zmq::socket_t& socket, const std::string& address,
                                       SocketMode mode, const OpenAdvice& advice) {
  if (ipv6_literal(address)) socket.set(zmq::sockopt::ipv6, true);  // else ZeroMQ refuses [::1]
  try {
    if (mode == SocketMode::bind)
      socket.bind(address);
    else
      socket.connect(address);
    return std::nullopt;
  } catch (const zmq::error_t& e) {
    const std::string how = mode == SocketMode::bind ? "bind " : "connect ";
    const std::string socket_name = advice.socket.empty() ? "" : advice.socket + " ";
    return OpenFailure{"cannot " + how + socket_name + "to '" + address + "': " + e.what(),
                       fix_for(e.num(), advice), e.num()};
  }
}

std::optional<OpenFailure> unknown_host(const std::string& address) {
  const std::optional<std::string> name = tcp_host_name(address);
  if (!name) return std::nullopt;
  const std::string& host = *name;
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int error = ::getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (found) ::freeaddrinfo(found);
  // EAI_FAIL is a resolver that failed, not a name it knows is unknown: not a refusal.
  if (error != EAI_NONAME) return std::nullopt;  // found, or ask again later
  return OpenFailure{"cannot connect to '" + address + "': no host is named '" + host + "' (" +
                         ::gai_strerror(error) + ")",
                     "check the name of the host that runs fabrikd, or give its address", 0};
}

std::optional<OpenFailure> unknown_host_within(const std::string& address,
                                               std::chrono::milliseconds wait) {
  if (!tcp_host_name(address)) return std::nullopt;  // nothing to look up
  using Answer = std::optional<OpenFailure>;
  auto answer = std::make_shared<std::promise<Answer>>();
  std::future<Answer> ready = answer->get_future();
  try {
    std::thread([answer, address] {
      try {
        answer->set_value(unknown_host(address));
      } catch (...) {  // no memory for the message: no answer
      }
    }).detach();
  } catch (const std::system_error&) {  // no thread to be had: no answer either
    return std::nullopt;
  }
  if (ready.wait_for(wait) != std::future_status::ready) return std::nullopt;
  try {
    return ready.get();
  } catch (const std::future_error&) {  // the thread gave no value
    return std::nullopt;
  }
}

}  // namespace fabrik::wire
