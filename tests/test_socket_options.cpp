// What fabrikd's sockets are given (src/transport/socket_options.hpp): the
// input's queue follows the config within its memory bound, and a socket
// kept across a reload ends with the limits a new one would get; and how a
// socket is opened (src/transport/open_socket.hpp): what a failure says.
#include <catch2/catch.hpp>
#include <cerrno>
#include <cstdint>
#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "transport/daemon.hpp"
#include "transport/open_socket.hpp"
#include "transport/socket_options.hpp"

using namespace fabrik;

namespace {

DaemonConfig with_limits(std::size_t max_payload_bytes, int max_backlog_frames) {
  DaemonConfig c;
  c.max_payload_bytes = max_payload_bytes;
  c.max_backlog_frames = max_backlog_frames;
  return c;
}

}  // namespace

TEST_CASE("The input socket's queue follows the payload limit within its memory bound") {
  zmq::context_t context(1);
  for (const std::size_t payload : {std::size_t{1} << 10, std::size_t{1} << 20,
                                    std::size_t{8} << 20, std::size_t{64} << 20}) {
    CAPTURE(payload);
    zmq::socket_t s(context, zmq::socket_type::sub);
    wire::set_input_options(s, with_limits(payload, 16));
    const std::int64_t max_message_bytes = s.get(zmq::sockopt::maxmsgsize);
    const int queue_messages = s.get(zmq::sockopt::rcvhwm);
    // A payload up to the limit, and past it, reaches the decoder (which counts it).
    CHECK(max_message_bytes > static_cast<std::int64_t>(payload));
    CHECK(queue_messages >= 16);
    CHECK(queue_messages <= 1000);
    // Within the bound, except where the queue is at its floor of 16.
    if (queue_messages > 16)
      CHECK(static_cast<std::size_t>(queue_messages) * static_cast<std::size_t>(max_message_bytes) <=
            wire::kInputQueueBytes);
    CHECK(s.get(zmq::sockopt::rcvbuf) == wire::kInputReceiveBufferBytes);
  }
}

TEST_CASE("A socket kept across a reload gets the limits a new socket would") {
  zmq::context_t context(1);
  const DaemonConfig before = with_limits(std::size_t{1} << 10, 4);
  const DaemonConfig after = with_limits(std::size_t{8} << 20, 64);

  zmq::socket_t kept_in(context, zmq::socket_type::sub), new_in(context, zmq::socket_type::sub);
  wire::set_input_options(kept_in, before);
  const int queue_before = kept_in.get(zmq::sockopt::rcvhwm);
  wire::set_input_limits(kept_in, after);
  wire::set_input_options(new_in, after);
  REQUIRE(new_in.get(zmq::sockopt::rcvhwm) != queue_before);  // the reload changes something
  CHECK(kept_in.get(zmq::sockopt::rcvhwm) == new_in.get(zmq::sockopt::rcvhwm));
  CHECK(kept_in.get(zmq::sockopt::maxmsgsize) == new_in.get(zmq::sockopt::maxmsgsize));

  zmq::socket_t kept_out(context, zmq::socket_type::xpub), new_out(context, zmq::socket_type::xpub);
  wire::set_output_options(kept_out, before);
  const int subscriber_queue_before = kept_out.get(zmq::sockopt::sndhwm);
  wire::set_output_limits(kept_out, after);
  wire::set_output_options(new_out, after);
  REQUIRE(new_out.get(zmq::sockopt::sndhwm) != subscriber_queue_before);
  CHECK(kept_out.get(zmq::sockopt::sndhwm) == new_out.get(zmq::sockopt::sndhwm));
  CHECK(new_out.get(zmq::sockopt::sndhwm) == wire::pose_queue_messages(after.max_backlog_frames));
}

TEST_CASE("Opening a socket: a taken port, an address not of this machine and an IPv6 literal") {
  zmq::context_t context(1);
  const wire::OpenAdvice advice{"the input socket", "here or with --input",
                                "write connect: before it"};
  zmq::socket_t holder(context, zmq::socket_type::pub);
  REQUIRE_FALSE(wire::open_socket(holder, "tcp://127.0.0.1:*", SocketMode::bind, advice));
  const std::string taken = holder.get(zmq::sockopt::last_endpoint);

  zmq::socket_t s(context, zmq::socket_type::sub);
  const auto in_use = wire::open_socket(s, taken, SocketMode::bind, advice);
  REQUIRE(in_use);
  CHECK_THAT(in_use->problem,
             Catch::StartsWith("cannot bind the input socket to '" + taken + "': "));
  CHECK(in_use->error == EADDRINUSE);
  // No holder to connect to named: none offered
  CHECK_THAT(in_use->fix, Catch::EndsWith("choose another port here or with --input"));
  const auto in_use_tool =
      wire::open_socket(s, taken, SocketMode::bind, {"", "with --to", "", "leave out --bind"});
  REQUIRE(in_use_tool);
  CHECK_THAT(in_use_tool->fix,
             Catch::EndsWith("choose another port with --to, or leave out --bind"));

  // A transport ZeroMQ does not know (refused by its errno: "Protocol not supported").
  const auto no_transport = wire::open_socket(s, "bogus://x", SocketMode::bind, advice);
  REQUIRE(no_transport);
  CHECK(no_transport->error == EPROTONOSUPPORT);
  CHECK_THAT(no_transport->fix, Catch::StartsWith("use a transport this ZeroMQ knows: tcp://") &&
                                    Catch::EndsWith("here or with --input"));
  // udp:// is ZeroMQ's for RADIO and DISH sockets: a SUB's bind fails ("The protocol is not
  // compatible with the socket type"), and the fix says what to use instead.
  const auto udp = wire::open_socket(s, "udp://127.0.0.1:5599", SocketMode::bind, advice);
  REQUIRE(udp);
  if (udp->error == EPROTONOSUPPORT) {
    WARN("SKIPPED the udp part: this libzmq was built without udp://");
  } else {
    CHECK(udp->error == ENOCOMPATPROTO);
    CHECK_THAT(udp->fix, Catch::StartsWith("ZeroMQ's udp:// serves RADIO and DISH sockets only") &&
                             Catch::EndsWith("here or with --input"));
  }

  const auto elsewhere = wire::open_socket(s, "tcp://192.0.2.1:5555", SocketMode::bind, {});
  REQUIRE(elsewhere);
  CHECK_THAT(elsewhere->problem, Catch::StartsWith("cannot bind to 'tcp://192.0.2.1:5555': "));
  CHECK_THAT(elsewhere->fix,
             Catch::StartsWith("bind to an address of this machine") &&
                 Catch::EndsWith("for every interface)"));  // no way to connect given: none offered

  // ZeroMQ refuses an IPv6 address on a socket not switched to IPv6.
  zmq::socket_t v6(context, zmq::socket_type::sub);
  const auto loopback6 = wire::open_socket(v6, "tcp://[::1]:*", SocketMode::bind, advice);
  if (loopback6 && (loopback6->error == EADDRNOTAVAIL || loopback6->error == EAFNOSUPPORT)) {
    WARN("SKIPPED the IPv6 part: this machine has no ::1 (" << loopback6->problem << ")");
    return;
  }
  CHECK_FALSE(loopback6);
  CHECK(v6.get(zmq::sockopt::ipv6));
}
