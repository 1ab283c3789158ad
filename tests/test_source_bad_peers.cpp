// The issue's requirement, through the whole daemon: "a server that is the
// wrong version, stalls, or sends malformed, truncated or oversized packets
// gives a clear error in stats and the log and never stops or wedges the
// daemon". Each case runs a real wire::Daemon with the real vendor client
// (the default make_source_client) against a hand-written peer on loopback,
// then checks stats.source, the log's warning, that the ZeroMQ input is still
// served, and that the daemon stops promptly. The clients alone:
// test_qtm_client, test_natnet_client.
#include <spdlog/spdlog.h>
#include <catch2/catch.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bridges/natnet_protocol.hpp"
#include "bridges/udp_socket.hpp"
#include "config/daemon_config.hpp"
#include "daemon_thread.hpp"
#include "log_capture.hpp"
#include "qtm_fake_peer.hpp"
#include "socket_client.hpp"
#include "solver/posture.hpp"

using namespace fabrik;
using nlohmann::json;
using Bytes = std::vector<std::uint8_t>;
using test::LogCapture;
using namespace std::chrono_literals;

namespace {

// Short timeouts keep the suite fast; the backoff leaves the connection down
// long enough (0.15 s, three stats intervals) for stats to show it down.
constexpr const char* kFastOptions =
    R"("connect_timeout_s": 0.2, "reply_timeout_s": 0.2, "stall_timeout_s": 0.3,
       "reconnect_min_s": 0.15, "reconnect_max_s": 0.15)";

// What a bad peer must make the daemon show.
struct Expect {
  std::string phrase;   // in stats.source.last_error and the log's warning
  bool bad_packet;      // counted in bad_packets (a packet refused), not only in errors
  bool handshakes;      // the client gets as far as connected (then loses it)
  int good_frames = 0;  // the peer's good frames a connection, before it goes wrong
};

// A port on loopback that nothing listens on: bound by the kernel's choice, then closed.
std::uint16_t closed_tcp_port() {
  std::uint16_t port = 0;
  std::string error;
  bridges::Fd fd = bridges::listen_tcp("127.0.0.1", 0, port, error);
  REQUIRE(fd.valid());
  return port;  // closed as fd goes
}
std::uint16_t closed_udp_port() {
  bridges::UdpSocket socket;
  std::string error;
  REQUIRE(socket.open("127.0.0.1", 0, false, error));
  return socket.local_port();
}

// Runs a daemon whose source is `url` (with the fast options and `options`)
// and checks everything the requirement asks of it. `name` keeps the inproc
// endpoints of the cases apart.
void check_daemon_survives(const std::string& name, const std::string& url, const std::string& options,
                           const Expect& expect) {
  LogCapture log;  // before the daemon: outlives it
  zmq::context_t context;
  DaemonConfig config = default_daemon_config();
  config.input = {"inproc://" + name + "-markers", SocketMode::bind};
  config.output = {"inproc://" + name + "-poses", SocketMode::bind};
  config.stats_interval_s = 0.05;
  const json input = json::parse(R"({"source": ")" + url + R"(", "source_options": {)" + kFastOptions +
                                 options + "}}");
  config.source = read_source_config(JsonReader(input, "test.json", "/input"));
  const Model& model = *config.tracker.model;
  const std::vector<MarkerTarget> targets = config.tracker.markers;

  test::DaemonThread daemon(context, config);  // no factory: the real vendor clients
  test::SocketClient client(context, config.input.address, config.output.address);

  // Two failures: the client gave up on one connection and tried again.
  // Handshaking peers: also a connection made, and stats catching it lost.
  json last_seen;  // for the failure message
  const auto stats = client.stats_until(
      [&](const json& s) {
        const json& src = last_seen = s["source"];
        return src["errors"] >= 2 && src["connected"] == false &&
               (!expect.handshakes || src["connections"] >= 1);
      },
      8s);
  INFO("the last stats.source: " << last_seen.dump());
  REQUIRE(stats);
  const json& src = (*stats)["source"];
  const std::string last_error = src["last_error"].is_string() ? src["last_error"].get<std::string>() : "";
  INFO("stats.source: " << src.dump());
  CHECK(src["url"] == url);
  CHECK_THAT(last_error, Catch::Contains(expect.phrase));
  CHECK((src["bad_packets"] >= 1) == expect.bad_packet);
  CHECK((src["connections"] >= 1) == expect.handshakes);
  CHECK(src["frames_dropped"] == 0);
  // Stats count each good frame once (the snapshot is taken whole, and
  // every connection shown ended after its good frames).
  CHECK(src["frames"] == src["connections"].get<int>() * expect.good_frames);

  // Meanwhile the ZeroMQ input is served: probes until a pose answers, then a
  // real frame (the model's markers at rest) comes back solved.
  const std::uint64_t frame = client.handshake();
  const Posture rest = Posture::rest(model);
  json markers = json::object();
  for (const MarkerTarget& t : targets) {
    const Eigen::Vector3d p_mm = rest.point_world_m(model, t.point) * 1e3;
    markers[t.marker] = {p_mm.x(), p_mm.y(), p_mm.z()};
  }
  client.send_frame(frame, markers);
  // (The source's own good frames are posed too, on the same output.)
  const auto pose = client.pose_of(frame, 5s);
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
  CHECK((*pose)["occluded"].empty());

  // The log says it too, as a warning naming the source (polled: the loop
  // logs what changed after each wake, at least every 100 ms).
  const std::string prefix = "warning source " + url + ": ";
  std::string line;
  const auto deadline = std::chrono::steady_clock::now() + 3s;
  while ((line = log.find(prefix, expect.phrase)).empty() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  INFO("log:\n" << log.all());
  CHECK_THAT(line, Catch::Contains(expect.phrase));

  // And it stops promptly, the source's thread with it (DaemonThread aborts after 5 s).
  CHECK(daemon.stop() < 1.0);
}

// ---------------------------------------------------------------------------
// NatNet: a UDP peer that answers each of the client's requests as told.

class NatNetPeer {
 public:
  using Respond = std::function<void(NatNetPeer&, const bridges::UdpEndpoint& from, natnet::MessageId)>;
  explicit NatNetPeer(Respond respond) : respond_(std::move(respond)) {
    std::string error;
    REQUIRE(socket_.open("127.0.0.1", 0, false, error));
    thread_ = std::jthread([this](std::stop_token stop) { serve(stop); });
  }
  std::uint16_t port() const { return socket_.local_port(); }
  void send(const bridges::UdpEndpoint& to, const Bytes& datagram) {
    std::string error;
    socket_.send_to(to, datagram, error);
  }

 private:
  void serve(const std::stop_token& stop) {
    Bytes buffer;
    while (!stop.stop_requested()) {
      bridges::UdpEndpoint from;
      std::size_t bytes = 0;
      std::string error;
      if (socket_.receive(buffer, 65536, from, bytes, 50, error) != bridges::UdpSocket::Received::datagram)
        continue;
      natnet::Message m;
      if (natnet::split_message(buffer, m, error)) respond_(*this, from, m.id);
    }
  }

  Respond respond_;
  bridges::UdpSocket socket_;
  std::jthread thread_;  // last: stops before the socket closes
};

// NatNet 3.1 throughout: no per-section byte counts, so the offsets below are fixed.
constexpr natnet::Version kNatNet31{3, 1, 0, 0};

Bytes server_info(natnet::Version v) {
  natnet::ServerInfo info;
  info.application_name = "Motive";
  info.application_version = {2, 3, 0, 0};
  info.natnet_version = v;
  info.is_multicast = false;
  return natnet::encode_message(natnet::MessageId::server_info, natnet::encode_server_info(info));
}

Bytes model_def() {
  natnet::ModelDefinitions defs;
  defs.marker_sets.push_back({"S", {"M1", "M2"}});
  return natnet::encode_message(natnet::MessageId::model_def,
                                natnet::encode_model_definitions(defs, kNatNet31));
}

// A frame of set "S": datagram bytes 4-7 frame number, 8-11 set count,
// 12-13 "S\0", 14-17 the set's marker count (2), then 2 x float3.
Bytes frame_of_data(std::int32_t number) {
  natnet::FrameOfData f;
  f.frame_number = number;
  f.marker_sets.push_back({"S", {{0.1F, 0.2F, 0.3F}, {0.4F, 0.5F, 0.6F}}});
  Bytes b = natnet::encode_message(natnet::MessageId::frame_of_data, natnet::encode_frame_of_data(f, kNatNet31));
  REQUIRE(Bytes(b.begin() + 12, b.begin() + 18) == Bytes{'S', 0, 2, 0, 0, 0});  // the layout above
  return b;
}

// Plays Motive through the handshake; once the definitions are asked for,
// sends `after` (one good frame first where given: a bad one then ends a
// working stream).
NatNetPeer::Respond motive_then(std::function<std::vector<Bytes>()> after) {
  return [after](NatNetPeer& peer, const bridges::UdpEndpoint& from, natnet::MessageId id) {
    if (id == natnet::MessageId::connect) peer.send(from, server_info(kNatNet31));
    if (id != natnet::MessageId::request_model_def) return;
    peer.send(from, model_def());
    for (const Bytes& d : after()) peer.send(from, d);
  };
}

}  // namespace

TEST_CASE("fabrikd with a bad NatNet server: clear error in stats and log, input served, stops promptly",
          "[source][daemon]") {
  struct Case {
    const char* name;
    std::function<std::unique_ptr<NatNetPeer>()> peer;  // null: nothing at the port
    Expect expect;
  };
  const auto peer = [](NatNetPeer::Respond r) {
    return [r] { return std::make_unique<NatNetPeer>(r); };
  };
  const Case c = GENERATE_COPY(
      Case{"nothing listening", nullptr, {"no reply to NAT_CONNECT within 0.2 s", false, false}},
      Case{"wrong version",
           peer([](NatNetPeer& p, const bridges::UdpEndpoint& from, natnet::MessageId id) {
             if (id == natnet::MessageId::connect) p.send(from, server_info({5, 0, 0, 0}));
           }),
           {"Motive speaks NatNet 5.0.0.0; fabrikd reads NatNet 3.x and 4.x", false, false}},
      Case{"stalls after connecting", peer(motive_then([] { return std::vector<Bytes>{}; })),
           {"no frame of data for 0.3 s (unicast): Motive stopped streaming or is gone", false, true}},
      Case{"malformed frame",
           peer(motive_then([] {
             Bytes bad = frame_of_data(2);
             bad[8] = 0xFB, bad[9] = bad[10] = bad[11] = 0xFF;  // marker set count -5
             return std::vector<Bytes>{frame_of_data(1), bad};
           })),
           {"marker set count is negative", true, true, 1}},
      Case{"truncated datagram",
           peer(motive_then([] {
             Bytes bad = frame_of_data(2);
             bad.resize(bad.size() - 7);  // shorter than its header says
             return std::vector<Bytes>{frame_of_data(1), bad};
           })),
           {"(truncated)", true, true, 1}},
      Case{"oversized datagram",
           peer(motive_then([] {
             Bytes bad = frame_of_data(2);
             bad.insert(bad.end(), 9, 0);  // longer than its header says
             return std::vector<Bytes>{frame_of_data(1), bad};
           })),
           {"(oversized)", true, true, 1}},
      Case{"a count that overruns the datagram",
           peer(motive_then([] {
             Bytes bad = frame_of_data(2);
             bad[14] = 0x40, bad[15] = 0x42, bad[16] = 0x0F;  // 1 000 000 markers in a set of 2
             return std::vector<Bytes>{frame_of_data(1), bad};
           })),
           {"marker set marker count 1000000 does not fit in the", true, true, 1}});
  INFO("case: " << c.name);
  const std::unique_ptr<NatNetPeer> server = c.peer ? c.peer() : nullptr;
  const std::uint16_t port = server ? server->port() : closed_udp_port();
  check_daemon_survives(std::string("natnet-") + std::to_string(port),
                        "natnet://127.0.0.1:" + std::to_string(port),
                        R"(, "natnet_data": "unicast", "local_interface": "127.0.0.1")", c.expect);
}

TEST_CASE("fabrikd with a bad QTM server: clear error in stats and log, input served, stops promptly",
          "[source][daemon]") {
  using namespace qtm;
  using namespace qtm::test_peer;
  struct Case {
    const char* name;
    FakePeer::Behaviour behaviour;  // null: nothing listening
    Expect expect;
  };
  const Case c = GENERATE_COPY(
      Case{"nothing listening", nullptr, {"cannot connect (", false, false}},
      Case{"wrong version",
           [](int fd, const std::stop_token& st) {
             PacketSplitter in(ByteOrder::little, 1 << 16);
             send_bytes(fd, string_packet(PacketType::command, "QTM RT Interface connected"), st);
             while (read_command(fd, in, st))
               send_bytes(fd, string_packet(PacketType::error, "Version NOT supported"), st);
           },
           {"refused RT protocol versions 1.19, 1.8 (\"Version NOT supported\")", false, false}},
      Case{"stalls after connecting",
           [](int fd, const std::stop_token& st) {
             if (handshake(fd, st)) hold(fd, st);
           },
           {"no frame for 0.3 s (stream stalled)", false, true}},
      Case{"not a QTM server",
           [](int fd, const std::stop_token& st) {
             const std::string http = "HTTP/1.1 400 Bad Request\r\n\r\n";
             send_bytes(fd, Bytes(http.begin(), http.end()), st);
             hold(fd, st);
           },
           {"not a QTM RT server", true, false}},
      Case{"malformed data packet",
           [](int fd, const std::stop_token& st) {
             if (!handshake(fd, st)) return;
             Bytes p = good_data_packet(2);
             p[24] = static_cast<std::uint8_t>(p[24] - 4);  // Component Size 4 bytes short
             send_bytes(fd, good_data_packet(1), st);
             send_bytes(fd, p, st);
             hold(fd, st);
           },
           {"data packet refused", true, true, 1}},
      Case{"truncated: closed mid-packet",
           [](int fd, const std::stop_token& st) {
             if (!handshake(fd, st)) return;
             const Bytes p = good_data_packet(1);
             send_bytes(fd, Bytes(p.begin(), p.begin() + 30), st);
           },
           {"closed the connection in the middle of a packet (truncated)", false, true}},
      Case{"oversized packet",
           [](int fd, const std::stop_token& st) {
             if (!handshake(fd, st)) return;
             send_bytes(fd, {0, 0, 0, 0x7F, 3, 0, 0, 0}, st);  // Size 2 GiB > max_packet_bytes (16 MiB)
             hold(fd, st);
           },
           {"above the configured maximum", true, true}});
  INFO("case: " << c.name);
  const std::unique_ptr<FakePeer> server = c.behaviour ? std::make_unique<FakePeer>(c.behaviour) : nullptr;
  const std::uint16_t port = server ? server->port() : closed_tcp_port();
  check_daemon_survives(std::string("qtm-") + std::to_string(port), "qtm://127.0.0.1:" + std::to_string(port),
                        "", c.expect);
}
