#include "bridges/natnet_client.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <vector>

#include "bridges/natnet_marker_table.hpp"
#include "bridges/natnet_protocol.hpp"
#include "bridges/udp_socket.hpp"

namespace fabrik::bridges {

namespace {

using Clock = std::chrono::steady_clock;
using natnet::MessageId;

constexpr auto kSlice = std::chrono::milliseconds(100);
constexpr auto kConnectResend = std::chrono::milliseconds(250);
// NatNetClient.py and PacketClient keep a unicast subscription alive by
// sending NAT_KEEPALIVE on the command socket; once a second is plenty.
constexpr auto kKeepAlive = std::chrono::seconds(1);
constexpr std::size_t kReceiveCapacity = 65536;  // any IPv4 UDP datagram fits

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

std::string format_seconds(double s) {
  std::string text = std::to_string(s);
  text.erase(text.find_last_not_of('0') + 1);
  if (text.back() == '.') text.pop_back();
  return text + " s";
}

std::string short_version(const natnet::Version& v, bool with_build) {
  return std::to_string(v.major) + "." + std::to_string(v.minor) +
         (with_build ? "." + std::to_string(v.build) : "");
}

// One connection, from NAT_CONNECT until it fails or stop is requested.
class Connection {
 public:
  Connection(const NatNetClientOptions& options, FrameSink& sink, SourceStatus& status,
             Backoff& backoff, std::stop_token stop)
      : o_(options), sink_(sink), status_(status), backoff_(backoff), stop_(std::move(stop)) {}

  void run() {
    if (open_sockets() && handshake()) stream();
  }

 private:
  enum class Next { message, timeout, stopped, failed };

  void fail(const std::string& text) { status_.error("NatNet " + where() + ": " + text); }
  void bad(const std::string& text) { status_.bad_packet("NatNet " + where() + ": " + text); }
  std::string where() const { return bridges::host_port(o_.host, o_.command_port); }

  bool open_sockets() {
    std::string error;
    const auto server = resolve_ipv4(o_.host, o_.command_port, error);
    if (!server) {
      fail(error);
      return false;
    }
    server_ = *server;
    if (!command_.open(o_.local_interface, 0, false, error)) {
      fail("command socket: " + error);
      return false;
    }
    // Joined on "any", the kernel picks the default route's interface, which
    // is not the one Motive streams from when it is on this host (loopback)
    // or behind another interface: join on the one that routes to Motive.
    std::string interface_address = o_.local_interface;
    if (o_.multicast && interface_address == "0.0.0.0") {
      std::string route_error;
      if (auto local = local_address_towards(server_, route_error)) interface_address = *local;
    }
    joined_interface_ = interface_address;
    if (o_.multicast && (!data_.open("0.0.0.0", o_.data_port, true, error) ||
                         !data_.join_multicast(o_.multicast_group, interface_address, error))) {
      fail("data socket: " + error);
      return false;
    }
    return true;
  }

  bool send(MessageId id, std::span<const std::uint8_t> payload = {}) {
    const auto datagram = natnet::encode_message(id, payload);
    std::string error;
    if (!command_.send_to(server_, datagram, error)) {
      fail(error);
      return false;
    }
    return true;
  }

  // The next NatNet message from Motive before `deadline`; datagrams from
  // other hosts on the command socket are not Motive's and are ignored.
  Next next_message(Clock::time_point deadline, natnet::Message& message) {
    for (;;) {
      if (stop_.stop_requested()) return Next::stopped;
      const auto now = Clock::now();
      if (now >= deadline) return Next::timeout;
      const auto slice = std::min<Clock::duration>(kSlice, deadline - now);
      const int slice_ms = static_cast<int>(
          std::chrono::ceil<std::chrono::milliseconds>(slice).count());
      const UdpSocket* sockets[] = {&command_, &data_};
      const int ready = wait_readable(std::span(sockets, data_.is_open() ? 2 : 1), slice_ms);
      if (ready < 0) continue;
      UdpSocket& socket = ready == 0 ? command_ : data_;
      UdpEndpoint from;
      std::size_t bytes = 0;
      std::string error;
      const auto got = socket.receive(buffer_, kReceiveCapacity, from, bytes, 0, error);
      if (got == UdpSocket::Received::timeout) continue;
      if (got == UdpSocket::Received::error) {
        fail(error);
        return Next::failed;
      }
      if (ready == 0 && from.address_be != server_.address_be) continue;
      if (bytes > o_.policy.max_packet_bytes || bytes > kReceiveCapacity) {
        bad("a datagram of " + std::to_string(bytes) + " bytes from " + to_string(from) +
            ", more than the " + std::to_string(std::min(o_.policy.max_packet_bytes, kReceiveCapacity)) +
            "-byte limit (oversized)");
        return Next::failed;
      }
      if (!natnet::split_message(buffer_, message, error)) {
        bad(error);
        return Next::failed;
      }
      return Next::message;
    }
  }

  bool handshake() {
    // The version asked for is left 0 ("the server's"): frames are then read
    // with the version the server info announces.
    natnet::Message m;
    const auto connect_deadline = Clock::now() + seconds(o_.policy.connect_timeout_s);
    // UDP: a NAT_CONNECT sent while Motive was not yet (or no longer) up is
    // lost without a word, so it is sent again every kConnectResend.
    if (!send(MessageId::connect, natnet::encode_connect_request({}))) return false;
    auto resend_at = Clock::now() + kConnectResend;
    for (;;) {
      const Next next = next_message(std::min(connect_deadline, resend_at), m);
      if (next == Next::timeout && Clock::now() < connect_deadline) {
        if (!send(MessageId::connect, natnet::encode_connect_request({}))) return false;
        resend_at = Clock::now() + kConnectResend;
        continue;
      }
      if (next == Next::timeout)
        fail("no reply to NAT_CONNECT within " + format_seconds(o_.policy.connect_timeout_s) +
             " (is Motive running with streaming on, at this address and command port?)");
      if (next != Next::message) return false;
      if (m.id == MessageId::server_info) break;  // frames of an earlier connection: not yet
    }
    std::string error;
    if (!natnet::decode_server_info(m.payload, info_, error)) {
      bad(error);
      return false;
    }
    const auto& v = info_.natnet_version;
    if (!natnet::supported(v)) {
      fail(info_.application_name + " speaks NatNet " + natnet::to_string(v) +
           "; fabrikd reads NatNet 3.x and 4.x (Motive 2.x and 3.x)");
      return false;
    }
    if (info_.is_multicast != o_.multicast) {
      fail(std::string("Motive streams ") + (info_.is_multicast ? "multicast" : "unicast") +
           " but the client is set to " + (o_.multicast ? "multicast" : "unicast") +
           ": set both the same (Motive's Transmission Type)");
      return false;
    }
    if (!request_definitions()) return false;
    const auto defs_deadline = Clock::now() + seconds(o_.policy.reply_timeout_s);
    for (;;) {
      const Next next = next_message(defs_deadline, m);
      if (next == Next::timeout)
        fail("no reply to NAT_REQUEST_MODELDEF within " +
             format_seconds(o_.policy.reply_timeout_s));
      if (next != Next::message) return false;
      if (m.id == MessageId::model_def) break;
    }
    if (!take_definitions(m.payload)) return false;
    status_.connected(info_.application_name + " " +
                      short_version(info_.application_version, true) + ", NatNet " +
                      short_version(v, false));
    backoff_.reset();
    return true;
  }

  bool request_definitions() {
    defs_requested_at_ = Clock::now();
    defs_pending_ = true;
    return send(MessageId::request_model_def);
  }

  bool take_definitions(std::span<const std::uint8_t> payload) {
    natnet::ModelDefinitions defs;
    std::string error;
    if (!natnet::decode_model_definitions(payload, info_.natnet_version, defs, error)) {
      bad(error);
      return false;
    }
    table_.reset(defs);
    sink_.labels(table_.names());
    defs_pending_ = false;
    return true;
  }

  void stream() {
    const bool unicast = !o_.multicast;
    auto last_frame = Clock::now();
    auto next_keep_alive = last_frame + kKeepAlive;
    const auto stall = seconds(o_.policy.stall_timeout_s);
    natnet::Message m;
    std::string error;
    std::string held_because;  // why frames are held until new definitions arrive
    for (;;) {
      auto deadline = last_frame + stall;
      if (unicast) deadline = std::min(deadline, next_keep_alive);
      if (defs_pending_) deadline = std::min(deadline, defs_requested_at_ + seconds(o_.policy.reply_timeout_s));
      const Next next = next_message(deadline, m);
      if (next == Next::stopped || next == Next::failed) return;
      const auto now = Clock::now();
      if (unicast && now >= next_keep_alive) {
        if (!send(MessageId::keep_alive)) return;
        next_keep_alive = now + kKeepAlive;
      }
      if (defs_pending_ && now >= defs_requested_at_ + seconds(o_.policy.reply_timeout_s)) {
        fail("no reply to NAT_REQUEST_MODELDEF within " +
             format_seconds(o_.policy.reply_timeout_s) + " (asked because " + held_because + ")");
        return;
      }
      if (now >= last_frame + stall) {
        // Multicast that never arrives is NatNet users' most common "no data":
        // say where the client listened and what to try.
        fail("no frame of data for " + format_seconds(o_.policy.stall_timeout_s) +
             (o_.multicast ? " on " + o_.multicast_group + ":" + std::to_string(o_.data_port) +
                                 " (joined on " + joined_interface_ +
                                 "): Motive stopped streaming, or its multicast does not reach this "
                                 "interface (set local_interface, open UDP " +
                                 std::to_string(o_.data_port) + " in the firewall, or use unicast)"
                           : std::string(" (unicast): Motive stopped streaming or is gone")));
        return;
      }
      if (next != Next::message) continue;
      switch (m.id) {
        case MessageId::frame_of_data: {
          if (!natnet::decode_frame_of_data(m.payload, info_.natnet_version, frame_, error)) {
            bad(error);
            return;
          }
          if (defs_pending_) break;  // held until the new definitions arrive
          std::string why;
          if (frame_.tracked_models_changed()) {
            why = "the frame says the tracked models changed";
          } else if (table_.fill(frame_, p_mm_, why)) {
            status_.frame_delivered();  // first: stats must not show fewer frames than poses
            sink_.frame(static_cast<std::uint32_t>(frame_.frame_number), frame_.timestamp_s, p_mm_);
            last_frame = now;
            break;
          }
          held_because = why;
          if (!request_definitions()) return;
          break;
        }
        case MessageId::model_def:
          if (!take_definitions(m.payload)) return;
          break;
        case MessageId::disconnect:
          fail("Motive sent NAT_DISCONNECT (it stopped streaming or is closing)");
          return;
        case MessageId::server_info:
        case MessageId::response:
        case MessageId::message_string:
        case MessageId::keep_alive:
        case MessageId::unrecognized_request:
          break;  // nothing asked for: nothing to do
        default:
          bad("unexpected message id " + std::to_string(static_cast<int>(m.id)) +
              " from the server");
          return;
      }
    }
  }

  const NatNetClientOptions& o_;
  FrameSink& sink_;
  SourceStatus& status_;
  Backoff& backoff_;
  std::stop_token stop_;
  UdpEndpoint server_;
  UdpSocket command_, data_;
  std::string joined_interface_;  // where the data socket joined the group
  std::vector<std::uint8_t> buffer_;
  natnet::ServerInfo info_;
  natnet::MarkerTable table_;
  natnet::FrameOfData frame_;
  std::vector<Eigen::Vector3d> p_mm_;
  bool defs_pending_ = false;
  Clock::time_point defs_requested_at_{};
};

}  // namespace

void run_natnet_client(const NatNetClientOptions& options, FrameSink& sink, SourceStatus& status,
                       std::stop_token stop) {
  Backoff backoff(options.policy);
  std::mutex mutex;
  std::condition_variable_any wake;
  while (!stop.stop_requested()) {
    Connection(options, sink, status, backoff, stop).run();
    status.disconnected();
    std::unique_lock lock(mutex);
    wake.wait_for(lock, stop, seconds(backoff.next_wait_s()), [] { return false; });
  }
}

}  // namespace fabrik::bridges
