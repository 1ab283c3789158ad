// fabrikd's NatNet client (src/bridges/natnet_client.*) against the simulated
// Motive (natnet_sim_server.*) over loopback, and against a hand-written bad
// peer for every failure the client must survive: each gives a clear
// SourceStatus error, the client keeps retrying, and stops promptly.
//
// Unicast throughout, plus one multicast test that SKIPs where the container's
// loopback cannot carry multicast (it needs a route for 224.0.0.0/4 and
// IP_MULTICAST_LOOP; many containers have neither on lo).
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

#include "bridges/natnet_client.hpp"
#include "bridges/natnet_protocol.hpp"
#include "bridges/natnet_sim_server.hpp"
#include "bridges/udp_socket.hpp"

using namespace fabrik;
using namespace fabrik::bridges;
using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Received {
  std::uint64_t frame_number;
  double time_s;
  std::vector<Eigen::Vector3d> p_mm;
  std::size_t labels_version;  // index into RecordingSink::labels
  std::uint64_t counted;       // the status's frame count as the frame was handed over
};

// Keeps what the client delivers; tests wait on it with deadlines.
class RecordingSink : public FrameSink {
 public:
  explicit RecordingSink(const SourceStatus* status = nullptr) : status_(status) {}
  void labels(std::span<const std::string> names) override {
    std::lock_guard lock(mutex_);
    labels_.emplace_back(names.begin(), names.end());
    changed_.notify_all();
  }
  void frame(std::uint64_t frame_number, double time_s,
             std::span<const Eigen::Vector3d> p_mm) override {
    const std::uint64_t counted = status_ ? status_->snapshot().frames : 0;
    std::lock_guard lock(mutex_);
    if (frames_.size() < 100000)
      frames_.push_back(
          {frame_number, time_s, {p_mm.begin(), p_mm.end()}, labels_.size() - 1, counted});
    changed_.notify_all();
  }
  // Waits until pred(frames, labels) holds or the timeout passes.
  bool wait(double timeout_s,
            const std::function<bool(const std::vector<Received>&,
                                     const std::vector<std::vector<std::string>>&)>& pred) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                             [&] { return pred(frames_, labels_); });
  }
  std::vector<Received> frames() {
    std::lock_guard lock(mutex_);
    return frames_;
  }
  std::vector<std::vector<std::string>> label_sets() {
    std::lock_guard lock(mutex_);
    return labels_;
  }

 private:
  const SourceStatus* status_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Received> frames_;
  std::vector<std::vector<std::string>> labels_;
};

// Polls the status (it has no notification) until pred holds or timeout.
bool wait_status(const SourceStatus& status, double timeout_s,
                 const std::function<bool(const SourceStatus::Snapshot&)>& pred) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (Clock::now() < deadline) {
    if (pred(status.snapshot())) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pred(status.snapshot());
}

ConnectionPolicy fast_policy() {
  ConnectionPolicy p;
  p.connect_timeout_s = 0.3;
  p.reply_timeout_s = 0.3;
  p.stall_timeout_s = 0.4;
  p.reconnect_min_s = 0.02;
  p.reconnect_max_s = 0.1;
  return p;
}

// The client on a thread; stopping it is timed.
class ClientThread {
 public:
  ClientThread(NatNetClientOptions options, FrameSink& sink, SourceStatus& status)
      : options_(std::move(options)),
        thread_([this, &sink, &status](std::stop_token stop) {
          run_natnet_client(options_, sink, status, stop);
        }) {}
  double stop_s() {
    const auto t0 = Clock::now();
    thread_.request_stop();
    thread_.join();
    return std::chrono::duration<double>(Clock::now() - t0).count();
  }
  ~ClientThread() {
    if (thread_.joinable()) stop_s();
  }

 private:
  NatNetClientOptions options_;
  std::jthread thread_;
};

class ServerThread {
 public:
  explicit ServerThread(NatNetSimServer& server)
      : thread_([&server](std::stop_token stop) { server.run(stop); }) {}

 private:
  std::jthread thread_;
};

// Three markers over `frames` frames: A moves, B still, C unseen in frames 5..9.
SimRecording recording(int frames, const std::string& up = "+y") {
  SimRecording r;
  r.rate_hz = 100.0;
  r.names = {"A", "B", "C"};
  r.up = up;
  for (int k = 0; k < frames; ++k) {
    std::vector<Eigen::Vector3d> p{{100.0 + k, 1000.5, -250.25}, {-33.3, 1234.567, 89.01},
                                   {0.1 * k, 777.0, 10.0}};
    if (k >= 5 && k < 10) p[2].setConstant(kNaN);
    r.p_mm.push_back(p);
  }
  return r;
}

NatNetSimServer::Options unicast_server(natnet::Version v = {4, 1, 0, 0}) {
  NatNetSimServer::Options o;
  o.command_port = 0;
  o.data_port = 0;
  o.multicast = false;
  o.version = v;
  return o;
}

NatNetClientOptions unicast_client(std::uint16_t port) {
  NatNetClientOptions o;
  o.host = "127.0.0.1";
  o.command_port = port;
  o.multicast = false;
  o.local_interface = "127.0.0.1";
  o.policy = fast_policy();
  return o;
}

// Float precision of the wire: metres as float, then mm.
bool near_float(const Eigen::Vector3d& got_mm, const Eigen::Vector3d& want_mm) {
  return (got_mm - want_mm).cwiseAbs().maxCoeff() <= 1e-6 * want_mm.cwiseAbs().maxCoeff() + 1e-4;
}

}  // namespace

TEST_CASE("NatNet client over loopback: frame numbers, times, labels and positions",
          "[natnet][client]") {
  const natnet::Version version = GENERATE(natnet::Version{3, 0, 0, 0}, natnet::Version{3, 1, 0, 0},
                                           natnet::Version{4, 0, 0, 0}, natnet::Version{4, 1, 0, 0});
  INFO("NatNet " << natnet::to_string(version));
  const SimRecording rec = recording(60);
  SimScript script;
  script.rate_scale = 4.0;
  script.drops.push_back({"B", 20, 25});
  NatNetSimServer server(rec, script, unicast_server(version));
  SourceStatus status;
  RecordingSink sink(&status);
  ClientThread client(unicast_client(server.command_port()), sink, status);
  ServerThread serving(server);

  REQUIRE(sink.wait(5.0, [](const auto& frames, const auto&) {
    return !frames.empty() && frames.back().frame_number >= 40;
  }));
  const auto s = status.snapshot();
  CHECK(s.connected);
  CHECK(s.server == "Motive " + std::string(version.major == 4 ? "3." : "2.") +
                        std::to_string(version.major == 4 ? version.minor : (version.minor == 0 ? 1 : 3)) +
                        ".0, NatNet " + std::to_string(version.major) + "." +
                        std::to_string(version.minor));
  CHECK(s.errors == 0);
  const auto labels = sink.label_sets();
  REQUIRE(labels.size() == 1);  // NatNet 3.x's "all" set is not a second copy
  CHECK(labels[0] == std::vector<std::string>{"Subject:A", "Subject:B", "Subject:C"});

  const auto frames = sink.frames();
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto& f = frames[i];
    INFO("frame " << f.frame_number);
    if (i > 0) CHECK(f.frame_number == frames[i - 1].frame_number + 1);  // none lost on loopback
    CHECK(f.time_s == Approx(static_cast<double>(f.frame_number) / 100.0));
    REQUIRE(f.p_mm.size() == 3);
    const auto& want = rec.p_mm[f.frame_number];
    CHECK(near_float(f.p_mm[0], want[0]));
    const bool dropped = f.frame_number >= 20 && f.frame_number < 25;
    CHECK(f.p_mm[1].array().isNaN().all() == dropped);  // occluded flag
    if (!dropped) CHECK(near_float(f.p_mm[1], want[1]));
    const bool unseen = f.frame_number >= 5 && f.frame_number < 10;
    CHECK(f.p_mm[2].array().isNaN().all() == unseen);  // (0,0,0) in the marker set
    if (!unseen) CHECK(near_float(f.p_mm[2], want[2]));
  }
  client.stop_s();  // the status may count frames that arrived after the copy above
  CHECK(status.snapshot().frames >= frames.size());
  // Each frame is counted before it is handed over: stats read between the two would else show
  // fewer frames than the poses they caused.
  for (std::size_t i = 0; i < frames.size(); ++i) {
    INFO("frame " << i);
    REQUIRE(frames[i].counted == i + 1);
  }
}

TEST_CASE("NatNet simulator rotates a Z-up recording into Motive's Y-up", "[natnet][client]") {
  const SimRecording rec = recording(40, "+z");
  SimScript script;
  script.rate_scale = 4.0;
  NatNetSimServer server(rec, script, unicast_server());
  RecordingSink sink;
  SourceStatus status;
  ClientThread client(unicast_client(server.command_port()), sink, status);
  ServerThread serving(server);
  REQUIRE(sink.wait(5.0, [](const auto& frames, const auto&) { return frames.size() >= 5; }));
  for (const auto& f : sink.frames()) {
    const Eigen::Vector3d& p = rec.p_mm[f.frame_number][0];
    CHECK(near_float(f.p_mm[0], Eigen::Vector3d(p.x(), p.z(), -p.y())));  // Z-up -> Y-up
  }
}

TEST_CASE("NatNet client: a rename mid-stream brings the new labels with the renamed frames",
          "[natnet][client]") {
  SimScript script;
  script.rate_scale = 4.0;
  script.renames.push_back({30, "B", "Bee"});
  NatNetSimServer server(recording(80), script, unicast_server());
  RecordingSink sink;
  SourceStatus status;
  ClientThread client(unicast_client(server.command_port()), sink, status);
  ServerThread serving(server);
  REQUIRE(sink.wait(5.0, [](const auto& frames, const auto&) {
    return !frames.empty() && frames.back().frame_number >= 50;
  }));
  const auto labels = sink.label_sets();
  REQUIRE(labels.size() >= 2);
  CHECK(labels.front() == std::vector<std::string>{"Subject:A", "Subject:B", "Subject:C"});
  CHECK(labels.back() == std::vector<std::string>{"Subject:A", "Subject:Bee", "Subject:C"});
  for (const auto& f : sink.frames()) {
    INFO("frame " << f.frame_number << " under labels " << f.labels_version);
    CHECK((labels[f.labels_version][1] == "Subject:Bee") == (f.frame_number >= 30));
  }
  CHECK(status.snapshot().errors == 0);
}

TEST_CASE("NatNet client: the server restarts, the client reconnects and streams on",
          "[natnet][client]") {
  SimScript script;
  script.rate_scale = 4.0;
  script.loop = true;
  script.restarts.push_back({20, 0.8});
  NatNetSimServer server(recording(100), script, unicast_server());
  RecordingSink sink;
  SourceStatus status;
  ClientThread client(unicast_client(server.command_port()), sink, status);
  ServerThread serving(server);
  const bool streamed_on = sink.wait(8.0, [](const auto& frames, const auto&) {
    return !frames.empty() && frames.back().frame_number >= 40;
  });
  const auto s = status.snapshot();
  INFO("sent " << server.progress().frames_sent << ", clients " << server.progress().clients
               << ", received " << s.frames << ", last error: " << s.last_error);
  REQUIRE(streamed_on);
  CHECK(s.connected);
  CHECK(s.connections >= 2);
  CHECK(s.reconnects == s.connections - 1);
  CHECK(s.errors >= 1);
  CHECK(s.bad_packets == 0);
  INFO(s.last_error);
  CHECK((s.last_error.find("no frame of data") != std::string::npos ||
         s.last_error.find("no reply to NAT_CONNECT") != std::string::npos));
  CHECK(sink.label_sets().size() == s.connections);  // labels again after each handshake
}

TEST_CASE("NatNet client over loopback multicast", "[natnet][client]") {
  NatNetSimServer::Options so;
  so.command_port = 0;
  so.data_port = 0;
  so.multicast = true;
  so.multicast_group = "239.255.42.99";
  SimScript script;
  script.loop = true;
  NatNetSimServer server(recording(50), script, so);
  NatNetClientOptions co = unicast_client(server.command_port());
  co.multicast = true;
  co.data_port = server.data_port();
  co.multicast_group = so.multicast_group;
  RecordingSink sink;
  SourceStatus status;
  ClientThread client(co, sink, status);
  ServerThread serving(server);
  if (!sink.wait(3.0, [](const auto& frames, const auto&) { return frames.size() >= 10; })) {
    WARN("no multicast over loopback here (" << status.snapshot().last_error
                                             << "); unicast is tested above");
    return;
  }
  CHECK(status.snapshot().connected);
}

namespace {

// A hand-written NatNet peer that misbehaves in one way.
enum class Misbehaviour {
  silent, wrong_version, natnet2, garbage, stall, malformed, truncated, oversized, huge,
  undescribed_set  // frames name a marker set the first definitions do not have
};

class BadPeer {
 public:
  explicit BadPeer(Misbehaviour how) : how_(how) {
    std::string error;
    if (!socket_.open("127.0.0.1", 0, false, error)) throw std::runtime_error(error);
    thread_ = std::jthread([this](std::stop_token stop) { serve(stop); });
  }
  std::uint16_t port() const { return socket_.local_port(); }
  std::vector<Bytes> received() {
    std::lock_guard lock(mutex_);
    return received_;
  }
  int connects() {
    std::lock_guard lock(mutex_);
    return connects_;
  }

 private:
  void reply(const UdpEndpoint& to, const Bytes& datagram) {
    std::string error;
    socket_.send_to(to, datagram, error);
  }
  void serve(const std::stop_token& stop) {
    Bytes buffer;
    while (!stop.stop_requested()) {
      UdpEndpoint from;
      std::size_t bytes = 0;
      std::string error;
      if (socket_.receive(buffer, 65536, from, bytes, 50, error) != UdpSocket::Received::datagram)
        continue;
      {
        std::lock_guard lock(mutex_);
        if (received_.size() < 1000) received_.push_back(buffer);
        if (buffer.size() >= 2 && buffer[0] == 0 && buffer[1] == 0) ++connects_;
      }
      natnet::Message m;
      if (!natnet::split_message(buffer, m, error)) continue;
      respond(from, m.id);
    }
  }
  void respond(const UdpEndpoint& to, natnet::MessageId id) {
    using natnet::MessageId;
    natnet::ServerInfo info;
    info.application_name = "Motive";
    info.application_version = {3, 1, 0, 0};
    info.natnet_version = {4, 1, 0, 0};
    const natnet::Version v = info.natnet_version;
    if (id == MessageId::connect) {
      switch (how_) {
        case Misbehaviour::silent:
          return;
        case Misbehaviour::wrong_version:
          info.natnet_version = {5, 0, 0, 0};
          break;
        case Misbehaviour::natnet2: {  // a bare sSender, as NatNet 2.x servers send
          Bytes sender(264, 0);
          std::memcpy(sender.data(), "Motive", 6);
          sender[260] = 2;
          sender[261] = 9;
          reply(to, natnet::encode_message(MessageId::server_info, sender));
          return;
        }
        case Misbehaviour::garbage:
          reply(to, {0xDE, 0xAD, 0xBE});
          return;
        default:
          break;
      }
      reply(to, natnet::encode_message(MessageId::server_info, natnet::encode_server_info(info)));
      return;
    }
    if (id != MessageId::request_model_def) return;
    ++model_requests_;
    const bool second_set = how_ == Misbehaviour::undescribed_set;
    natnet::ModelDefinitions defs;
    defs.marker_sets.push_back({second_set && model_requests_ > 1 ? "T" : "S", {"M1", "M2"}});
    reply(to, natnet::encode_message(MessageId::model_def, natnet::encode_model_definitions(defs, v)));
    natnet::FrameOfData frame;
    frame.frame_number = model_requests_;
    frame.marker_sets.push_back({second_set ? "T" : "S", {{0.1F, 0.2F, 0.3F}, {0.4F, 0.5F, 0.6F}}});
    const Bytes good = natnet::encode_message(MessageId::frame_of_data,
                                              natnet::encode_frame_of_data(frame, v));
    Bytes bad = good;
    switch (how_) {
      case Misbehaviour::undescribed_set:
        reply(to, good);
        return;
      case Misbehaviour::stall:
        return;
      case Misbehaviour::malformed:  // marker set count -5
        bad[8] = 0xFB, bad[9] = bad[10] = bad[11] = 0xFF;
        break;
      case Misbehaviour::truncated:
        bad.resize(bad.size() - 7);
        break;
      case Misbehaviour::oversized:
        bad.insert(bad.end(), 9, 0);
        break;
      case Misbehaviour::huge:  // over the client's max_packet_bytes (1000 in the test)
        bad.assign(3000, 0);
        bad[0] = 7;
        break;
      default:
        return;
    }
    reply(to, good);  // one good frame first: the bad one follows a working stream
    reply(to, bad);
  }

  Misbehaviour how_;
  UdpSocket socket_;
  std::mutex mutex_;
  std::vector<Bytes> received_;
  int connects_ = 0;
  int model_requests_ = 0;  // the serving thread's only
  std::jthread thread_;  // last: stops before the rest is destroyed
};

}  // namespace

TEST_CASE("NatNet client: each bad peer gives a clear error, retries, and stops promptly",
          "[natnet][client]") {
  struct Case {
    Misbehaviour how;
    const char* error;  // what last_error must say
    bool bad_packet;
  };
  const Case c = GENERATE(
      Case{Misbehaviour::silent, "no reply to NAT_CONNECT within 0.3 s", false},
      Case{Misbehaviour::wrong_version, "Motive speaks NatNet 5.0.0.0; fabrikd reads NatNet 3.x and 4.x", false},
      Case{Misbehaviour::natnet2, "bare sSender, NatNet 2.9", true},
      Case{Misbehaviour::garbage, "NatNet header", true},
      Case{Misbehaviour::stall, "no frame of data for 0.4 s", false},
      Case{Misbehaviour::malformed, "marker set count is negative", true},
      Case{Misbehaviour::truncated, "(truncated)", true},
      Case{Misbehaviour::oversized, "(oversized)", true},
      Case{Misbehaviour::huge, "3000 bytes", true});
  INFO("expecting: " << c.error);
  BadPeer peer(c.how);
  RecordingSink sink;
  SourceStatus status;
  auto options = unicast_client(peer.port());
  options.policy.max_packet_bytes = 1000;
  ClientThread client(options, sink, status);
  // Retrying: at least three handshakes, each failing the same way.
  REQUIRE(wait_status(status, 10.0, [&](const auto& s) { return s.errors >= 3; }));
  const auto s = status.snapshot();
  INFO(s.last_error);
  CHECK(s.last_error.find(c.error) != std::string::npos);
  CHECK(s.last_error.rfind("NatNet 127.0.0.1:", 0) == 0);  // says which server
  CHECK((s.bad_packets > 0) == c.bad_packet);
  CHECK(peer.connects() >= 3);
  const double stop_s = client.stop_s();
  CHECK(stop_s < 0.5);
  CHECK_FALSE(status.snapshot().connected);
  for (const auto& f : sink.frames()) CHECK(near_float(f.p_mm[0], {100, 200, 300}));  // good ones only
}

// Hand-computed from NatNetTypes.h / NatNetClient.py: message id (uint16 LE)
// and payload size (uint16 LE), then the payload.
TEST_CASE("NatNet client sends NAT_CONNECT, NAT_REQUEST_MODELDEF and NAT_KEEPALIVE as the SDK does",
          "[natnet][client]") {
  BadPeer peer(Misbehaviour::stall);
  RecordingSink sink;
  SourceStatus status;
  auto options = unicast_client(peer.port());
  options.policy.stall_timeout_s = 2.5;  // long enough for keepalives (one a second)
  ClientThread client(options, sink, status);
  const Bytes keep_alive = {0x0A, 0x00, 0x00, 0x00};  // id 10, no payload
  REQUIRE(wait_status(status, 5.0, [&](const auto&) {
    const auto got = peer.received();
    return std::count(got.begin(), got.end(), keep_alive) >= 2;
  }));
  const auto got = peer.received();
  REQUIRE(got.size() >= 4);
  // NAT_CONNECT: id 0, 271 payload bytes (0x010F): "Ping", zero padding, the
  // version asked for at 265 (0.0.0.0: the server's own), a final NUL.
  REQUIRE(got[0].size() == 4 + 271);
  CHECK(Bytes(got[0].begin(), got[0].begin() + 8) == Bytes{0x00, 0x00, 0x0F, 0x01, 'P', 'i', 'n', 'g'});
  CHECK(std::all_of(got[0].begin() + 8, got[0].end(), [](std::uint8_t b) { return b == 0; }));
  CHECK(got[1] == Bytes{0x04, 0x00, 0x00, 0x00});  // NAT_REQUEST_MODELDEF, no payload
  CHECK(got[2] == keep_alive);
}

// The simulator's answers to NAT_REQUEST, as bytes: NAT_RESPONSE (id 3) with
// an int32 result, NAT_UNRECOGNIZED_REQUEST (id 100) with no payload.
TEST_CASE("NatNet simulator answers Bitstream and unknown requests as Motive does",
          "[natnet][client]") {
  NatNetSimServer server(recording(10), SimScript{}, unicast_server());
  ServerThread serving(server);
  UdpSocket socket;
  std::string error;
  REQUIRE(socket.open("127.0.0.1", 0, false, error));
  const UdpEndpoint to = *resolve_ipv4("127.0.0.1", server.command_port(), error);
  const auto ask = [&](const Bytes& request, natnet::MessageId want) {
    REQUIRE(socket.send_to(to, request, error));
    Bytes reply;
    const auto deadline = Clock::now() + std::chrono::seconds(3);
    while (Clock::now() < deadline) {
      UdpEndpoint from;
      std::size_t bytes = 0;
      if (socket.receive(reply, 65536, from, bytes, 100, error) == UdpSocket::Received::datagram &&
          reply.size() >= 2 && reply[0] == static_cast<std::uint8_t>(want))
        return reply;
    }
    FAIL("no reply of id " << static_cast<int>(want));
    return reply;
  };
  // NAT_REQUEST (2), 14 bytes: "Bitstream,3.0" and its NUL.
  const Bytes bitstream = {0x02, 0x00, 0x0E, 0x00, 'B', 'i', 't', 's', 't', 'r', 'e', 'a', 'm', ',', '3', '.', '0', 0x00};
  CHECK(ask(bitstream, natnet::MessageId::response) == Bytes{0x03, 0x00, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00});
  const Bytes unknown = {0x02, 0x00, 0x04, 0x00, 'F', 'o', 'o', 0x00};
  CHECK(ask(unknown, natnet::MessageId::unrecognized_request) == Bytes{0x64, 0x00, 0x00, 0x00});
  // The stream is now NatNet 3.0: its definitions carry Motive 2's "all" set.
  // Asked as NatNetClient.py asks: a size of 0 and a NUL the size does not count.
  const Bytes defs_reply = ask({0x04, 0x00, 0x00, 0x00, 0x00}, natnet::MessageId::model_def);
  natnet::Message m;
  REQUIRE(natnet::split_message(defs_reply, m, error));
  natnet::ModelDefinitions defs;
  REQUIRE(natnet::decode_model_definitions(m.payload, {3, 0, 0, 0}, defs, error));
  REQUIRE(defs.marker_sets.size() == 2);
  CHECK(defs.marker_sets[0].name == "Subject");
  CHECK(defs.marker_sets[1].name == "all");
}

TEST_CASE("NatNet simulator refuses what it cannot serve, with a clear message", "[natnet][client]") {
  auto o = unicast_server();
  o.up_axis = "y";
  CHECK_THROWS_WITH(NatNetSimServer(recording(3), SimScript{}, o), Catch::Contains("up_axis 'y'"));
  CHECK_THROWS_WITH(NatNetSimServer(SimRecording{}, SimScript{}, unicast_server()),
                    Catch::Contains("no frames"));
  SimRecording many = recording(1);
  many.names.assign(3000, "M");
  many.p_mm[0].assign(3000, Eigen::Vector3d::Zero());
  CHECK_THROWS_WITH(NatNetSimServer(many, SimScript{}, unicast_server()),
                    Catch::Contains("do not fit one NatNet datagram"));
  auto unicast_group = unicast_server();  // a multicast server's group that is one host
  unicast_group.multicast = true;
  unicast_group.multicast_group = "10.0.0.5";
  CHECK_THROWS_WITH(NatNetSimServer(recording(3), SimScript{}, unicast_group),
                    Catch::Contains("'10.0.0.5' is not an IPv4 multicast group"));
  NatNetSimServer first(recording(3), SimScript{}, unicast_server());
  auto same = unicast_server();
  same.command_port = first.command_port();
  CHECK_THROWS_WITH(NatNetSimServer(recording(3), SimScript{}, same), Catch::Contains("command socket"));
}

TEST_CASE("NatNet client stops promptly in the middle of a long wait for a reply",
          "[natnet][client]") {
  BadPeer peer(Misbehaviour::silent);
  RecordingSink sink;
  SourceStatus status;
  auto options = unicast_client(peer.port());
  options.policy.connect_timeout_s = 30.0;
  ClientThread client(options, sink, status);
  REQUIRE(wait_status(status, 5.0, [&](const auto&) { return peer.connects() >= 1; }));
  CHECK(client.stop_s() < 0.3);  // waits are sliced to 100 ms
  CHECK(status.snapshot().errors == 0);  // stopping is not a failure
}

TEST_CASE("NatNet client asks for definitions again when a frame names an undescribed marker set",
          "[natnet][client]") {
  BadPeer peer(Misbehaviour::undescribed_set);
  RecordingSink sink;
  SourceStatus status;
  ClientThread client(unicast_client(peer.port()), sink, status);
  REQUIRE(sink.wait(5.0, [](const auto& frames, const auto&) { return !frames.empty(); }));
  const auto labels = sink.label_sets();
  REQUIRE(labels.size() == 2);
  CHECK(labels[0] == std::vector<std::string>{"S:M1", "S:M2"});
  CHECK(labels[1] == std::vector<std::string>{"T:M1", "T:M2"});
  const auto frames = sink.frames();
  CHECK(frames.front().labels_version == 1);  // the frame that named T waited for T's names
  CHECK(frames.front().frame_number == 2);
  CHECK(near_float(frames.front().p_mm[1], {400, 500, 600}));
  CHECK(status.snapshot().errors == 0);
}
