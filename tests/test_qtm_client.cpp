// The QTM RT client (src/bridges/qtm/client.cpp) over loopback: against the
// simulator (QtmSimServer) for frames, labels, renames and restarts, and
// against tiny hand-written peers for every way a server can go wrong. Waits
// are on conditions with deadlines; no sleep is a synchronisation.
#include <catch2/catch.hpp>

#include <poll.h>
#include <sys/socket.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bridges/qtm/client.hpp"
#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "bridges/qtm/sim_server.hpp"
#include "bridges/tcp.hpp"
#include "qtm_fake_peer.hpp"
#include "unknown_host.hpp"

using namespace fabrik;
using namespace fabrik::qtm;
using Bytes = std::vector<std::uint8_t>;
using bridges::Clock;

namespace {

// A simulated QTM on loopback, on any free pair of ports.
QtmSimServer::Options any_free_ports() {
  QtmSimServer::Options o;
  o.base_port = 0;
  return o;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Polls `done` until it holds or `seconds` pass: a bounded wait on a condition.
template <class F>
bool eventually(F done, double seconds) {
  const auto deadline = bridges::deadline_after(seconds);
  while (!done()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Records what the client hands over.
class RecordingSink : public bridges::FrameSink {
 public:
  struct Frame {
    std::uint64_t number;
    double time_s;
    std::vector<Eigen::Vector3d> p_mm;
    std::size_t label_set;  // index into label_sets
    std::uint64_t counted;  // the status's frame count as the frame was handed over
  };
  explicit RecordingSink(const bridges::SourceStatus* status = nullptr) : status_(status) {}
  void labels(std::span<const std::string> names) override {
    std::lock_guard lock(m_);
    label_sets_.emplace_back(names.begin(), names.end());
    cv_.notify_all();
  }
  void frame(std::uint64_t n, double t, std::span<const Eigen::Vector3d> p) override {
    std::lock_guard lock(m_);
    const std::uint64_t counted = status_ ? status_->snapshot().frames : 0;
    if (frames_.size() < 100000)
      frames_.push_back({n, t, {p.begin(), p.end()}, label_sets_.size() - 1, counted});
    cv_.notify_all();
  }
  // Waits (bounded) until `done(frames, label_sets)` holds.
  template <class F>
  bool wait(F done, double seconds) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return done(frames_, label_sets_); });
  }
  std::vector<Frame> frames() {
    std::lock_guard lock(m_);
    return frames_;
  }
  std::vector<std::vector<std::string>> label_sets() {
    std::lock_guard lock(m_);
    return label_sets_;
  }

 private:
  const bridges::SourceStatus* status_;
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<Frame> frames_;
  std::vector<std::vector<std::string>> label_sets_;
};

// A client on its own thread.
struct ClientThread {
  RecordingSink sink;
  bridges::SourceStatus status;
  std::jthread thread;
  explicit ClientThread(QtmClientOptions o)
      : sink(&status),  // only its address: read once frames come
        thread([this, o](std::stop_token st) { run_qtm_client(o, sink, status, st); }) {}
  // Seconds from the stop request to the thread's end.
  double stop() {
    const auto t0 = Clock::now();
    thread.request_stop();
    thread.join();
    return seconds_since(t0);
  }
};

bridges::ConnectionPolicy fast_policy() {
  bridges::ConnectionPolicy p;
  p.connect_timeout_s = 0.3;
  p.reply_timeout_s = 0.3;
  p.stall_timeout_s = 0.5;
  p.reconnect_min_s = 0.02;
  p.reconnect_max_s = 0.1;
  p.max_packet_bytes = 64 * 1024;
  return p;
}

QtmClientOptions options_for(std::uint16_t port, int divisor = 1) {
  QtmClientOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.frequency_divisor = divisor;
  o.policy = fast_policy();
  return o;
}

// 4 markers, 100 frames at 100 Hz; positions no float holds exactly; m2 not
// seen in frames 10..19 of the file.
bridges::SimRecording recording() {
  bridges::SimRecording r;
  r.rate_hz = 100.0;
  r.names = {"m0", "m1", "m2", "m3"};
  for (int f = 0; f < 100; ++f) {
    std::vector<Eigen::Vector3d> row;
    for (int i = 0; i < 4; ++i)
      row.emplace_back(1000.0 * i + 0.37 * f + 0.1, -20.5 + 1.3 * f, 3.25 * i - 0.01 * f);
    if (f >= 10 && f < 20) row[2].setConstant(kNaN);
    r.p_mm.push_back(row);
  }
  return r;
}

bridges::SimScript looping(double rate_scale = 5.0) {
  bridges::SimScript s;
  s.loop = true;
  s.rate_scale = rate_scale;
  return s;
}

struct ServerThread {
  QtmSimServer server;
  std::jthread thread;
  ServerThread(bridges::SimRecording r, bridges::SimScript s)
      : server(std::move(r), std::move(s), any_free_ports()),
        thread([this](std::stop_token st) { server.run(st); }) {}
};

// What frame g of the simulated measurement should hold, as floats widen.
std::optional<Eigen::Vector3d> expected_p_mm(const bridges::SimRecording& r, const bridges::SimScript& s,
                                             std::uint64_t g, std::size_t marker) {
  const Eigen::Vector3d p = r.p_mm[g % r.p_mm.size()][marker];
  for (const auto& d : s.drops)
    if (static_cast<std::int64_t>(g) >= d.from_frame && static_cast<std::int64_t>(g) < d.to_frame &&
        d.marker == r.names[marker])
      return std::nullopt;
  if (p.hasNaN()) return std::nullopt;
  // Through memory: GCC 12 at -O2 (its SLP vectoriser) folds the round trip
  // double -> float -> double of x and y into nothing, in Eigen's cast<float>()
  // and in scalar casts alike; -fno-tree-slp-vectorize or a volatile float keeps it.
  auto as_float = [](double v) {
    volatile float f = static_cast<float>(v);
    return static_cast<double>(f);
  };
  return Eigen::Vector3d(as_float(p.x()), as_float(p.y()), as_float(p.z()));
}

void check_frames(const std::vector<RecordingSink::Frame>& frames, const bridges::SimRecording& r,
                  const bridges::SimScript& s, std::uint64_t step) {
  REQUIRE(frames.size() >= 2);
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto& f = frames[k];
    INFO("frame " << f.number);
    REQUIRE(f.number >= 1);
    const std::uint64_t g = f.number - 1;  // the simulator numbers frames from 1
    CHECK(f.time_s == Approx(static_cast<double>(g) / r.rate_hz).margin(1e-9));
    if (k > 0) CHECK(f.number - frames[k - 1].number == step);
    REQUIRE(f.p_mm.size() == r.names.size());
    for (std::size_t i = 0; i < r.names.size(); ++i) {
      const auto want = expected_p_mm(r, s, g, i);
      if (!want)
        CHECK(f.p_mm[i].array().isNaN().all());
      else
        CHECK(f.p_mm[i] == *want);  // float precision of the protocol, exactly
    }
  }
}

}  // namespace

TEST_CASE("qtm client: frames arrive with their numbers, times, labels and positions, both byte orders",
          "[qtm][client]") {
  const bool big = GENERATE(false, true);
  INFO((big ? "big endian" : "little endian"));
  auto s = looping();
  s.drops.push_back({"m3", 50, 60});
  ServerThread server(recording(), s);
  ClientThread client(
      options_for(big ? server.server.port_big_endian() : server.server.port_little_endian()));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return f.size() >= 150; }, 5.0));
  const double stop_s = client.stop();
  CHECK(stop_s < 0.35);
  check_frames(client.sink.frames(), recording(), s, 1);
  const auto labels = client.sink.label_sets();
  REQUIRE(labels.size() == 1);
  CHECK(labels[0] == recording().names);
  const auto st = client.status.snapshot();
  CHECK(st.server == "QTM RT protocol 1.19");
  CHECK(st.connections == 1);
  CHECK(st.errors == 0);
  CHECK(st.frames == client.sink.frames().size());
  CHECK_FALSE(st.connected);  // disconnected on stop
  // Each frame is counted before it is handed over: stats read between the two would else show
  // fewer frames than the poses they caused.
  const auto frames = client.sink.frames();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    INFO("frame " << k);
    REQUIRE(frames[k].counted == k + 1);
  }
}

TEST_CASE("qtm client: several subjects' Subject:Marker labels arrive whole", "[qtm][client]") {
  // The daemon routes NAME:Marker to subject NAME and keeps a name it takes whole
  // (test_source_input, "[subjects]"): the client must hand QTM's labels over as QTM names them,
  // a subject's colon and a name's UTF-8 kept.
  bridges::SimRecording r = recording();
  r.names = {"Alice:LASI", "Bob:LASI", "Daphn\xc3\xa9:ASISl", "Carol:RASI"};
  ServerThread server(r, looping());
  ClientThread client(options_for(server.server.port_little_endian()));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return f.size() >= 5; }, 5.0));
  client.stop();
  const auto labels = client.sink.label_sets();
  REQUIRE(labels.size() == 1);
  CHECK(labels[0] == r.names);
}

TEST_CASE("qtm client: a frequency divisor gets every n-th frame", "[qtm][client]") {
  ServerThread server(recording(), looping());
  ClientThread client(options_for(server.server.port_little_endian(), 3));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return f.size() >= 40; }, 5.0));
  client.stop();
  check_frames(client.sink.frames(), recording(), looping(), 3);
}

TEST_CASE("qtm client: the dropped and unseen markers of the file arrive as NaN", "[qtm][client]") {
  auto s = looping(10.0);
  s.drops.push_back({"m0", 0, 1000000});
  ServerThread server(recording(), s);
  ClientThread client(options_for(server.server.port_little_endian()));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return f.size() >= 120; }, 5.0));
  client.stop();
  const auto frames = client.sink.frames();
  std::size_t unseen_m2 = 0;
  for (const auto& f : frames) {
    CHECK(f.p_mm[0].array().isNaN().all());
    CHECK_FALSE(f.p_mm[1].hasNaN());
    unseen_m2 += f.p_mm[2].hasNaN() ? 1 : 0;
  }
  CHECK(unseen_m2 >= 10);  // 120 consecutive frames of a 100-frame loop hold its 10 gaps
  check_frames(frames, recording(), s, 1);
}

TEST_CASE("qtm client: labels renamed mid-stream are read again, no reconnect", "[qtm][client]") {
  auto s = looping();
  s.renames.push_back({150, "m1", "m1_new"});
  ServerThread server(recording(), s);
  ClientThread client(options_for(server.server.port_little_endian()));
  // Frames served after the rename, with the new labels.
  REQUIRE(client.sink.wait(
      [](auto& f, auto& l) { return l.size() >= 2 && !f.empty() && f.back().label_set == l.size() - 1 && f.back().number > 160; },
      5.0));
  client.stop();
  const auto labels = client.sink.label_sets();
  const std::vector<std::string> renamed = {"m0", "m1_new", "m2", "m3"};
  CHECK(labels.back() == renamed);
  for (const auto& f : client.sink.frames())
    if (f.number > 151) CHECK(labels[f.label_set] == renamed);  // no frame of the new measurement under the old names
  const auto st = client.status.snapshot();
  CHECK(st.connections == 1);
  CHECK(st.errors == 0);
}

TEST_CASE("qtm client: a server restart is a reconnect, then streaming resumes", "[qtm][client]") {
  auto s = looping();
  s.restarts.push_back({100, 0.3});
  ServerThread server(recording(), s);
  auto o = options_for(server.server.port_little_endian());
  o.policy.reconnect_min_s = 0.1;  // the shutdown error stays last for 0.1 s, long enough to be seen
  ClientThread client(o);
  bool saw_shutdown = false;
  REQUIRE(eventually(
      [&] {
        const auto st = client.status.snapshot();
        saw_shutdown |= st.last_error.find("shutting down") != std::string::npos;
        return st.reconnects >= 1;
      },
      5.0));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return !f.empty() && f.back().number > 150; }, 5.0));
  client.stop();
  const auto st = client.status.snapshot();
  CHECK(st.connections >= 2);
  CHECK(saw_shutdown);  // QTM Shutting Down (event 12) before the listeners closed
  CHECK(st.errors >= 1);
  CHECK(client.sink.label_sets().size() >= 2);  // labels read again on the new connection
}

TEST_CASE("qtm simulator: several clients at once, both ports", "[qtm][client]") {
  ServerThread server(recording(), looping());
  ClientThread a(options_for(server.server.port_little_endian()));
  ClientThread b(options_for(server.server.port_big_endian()));
  ClientThread c(options_for(server.server.port_little_endian(), 2));
  for (ClientThread* t : {&a, &b, &c})
    REQUIRE(t->sink.wait([](auto& f, auto&) { return f.size() >= 30; }, 5.0));
  CHECK(server.server.progress().clients == 3);
  CHECK(server.server.progress().frames_sent >= 30);
  for (ClientThread* t : {&a, &b, &c}) t->stop();
  CHECK(eventually([&] { return server.server.progress().clients == 0; }, 2.0));
}

// ----------------------------------------------------------------------------
// Hand-written peers (qtm_fake_peer.hpp).

using namespace fabrik::qtm::test_peer;

namespace {

struct BadPeerCase {
  const char* name;
  FakePeer::Behaviour behaviour;
  const char* error_contains;
  bool bad_packet;
  bool handshakes;  // the client gets as far as connected()
};

}  // namespace

TEST_CASE("qtm client: each bad peer gives a clear error, the client retries and stops promptly",
          "[qtm][client]") {
  const std::vector<BadPeerCase> cases = {
      {"garbage, not a QTM server",
       [](int fd, const std::stop_token& st) {
         const std::string http = "HTTP/1.1 400 Bad Request\r\n\r\n";
         send_bytes(fd, Bytes(http.begin(), http.end()), st);
         hold(fd, st);
       },
       "not a QTM RT server", true, false},
      {"silent peer, no welcome",
       [](int fd, const std::stop_token& st) { hold(fd, st); }, "no welcome message", false, false},
      {"wrong version",
       [](int fd, const std::stop_token& st) {
         PacketSplitter in(ByteOrder::little, 1 << 16);
         send_bytes(fd, string_packet(PacketType::command, "QTM RT Interface connected"), st);
         while (read_command(fd, in, st)) send_bytes(fd, string_packet(PacketType::error, "Version NOT supported"), st);
       },
       "refused RT protocol versions 1.19, 1.8", false, false},
      {"a version we do not decode",
       [](int fd, const std::stop_token& st) {
         PacketSplitter in(ByteOrder::little, 1 << 16);
         send_bytes(fd, string_packet(PacketType::command, "QTM RT Interface connected"), st);
         while (read_command(fd, in, st)) send_bytes(fd, string_packet(PacketType::command, "Version set to 1.5"), st);
       },
       "decodes 1.8 and later", false, false},
      {"stall in the handshake",
       [](int fd, const std::stop_token& st) {
         send_bytes(fd, string_packet(PacketType::command, "QTM RT Interface connected"), st);
         hold(fd, st);
       },
       "no reply to 'Version 1.19' within", false, false},
      {"no frames after the handshake",
       [](int fd, const std::stop_token& st) {
         if (handshake(fd, st)) hold(fd, st);
       },
       "no frame for 0.5 s", false, true},
      {"stall mid-packet",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         const Bytes p = good_data_packet(1);
         send_bytes(fd, Bytes(p.begin(), p.begin() + 20), st);
         hold(fd, st);
       },
       "stalled mid-packet", false, true},
      {"truncated: closed mid-packet",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         const Bytes p = good_data_packet(1);
         send_bytes(fd, Bytes(p.begin(), p.begin() + 30), st);
       },
       "closed the connection in the middle of a packet (truncated)", false, true},
      {"truncated 3D component",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         Bytes p = good_data_packet(1);
         p[32] = 9;  // Marker Count 9 of a component that holds 2
         send_bytes(fd, p, st);
         hold(fd, st);
       },
       "data packet refused", true, true},
      {"malformed: component size disagrees",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         Bytes p = good_data_packet(1);
         p[24] = static_cast<std::uint8_t>(p[24] - 4);  // Component Size 4 bytes short
         send_bytes(fd, p, st);
         hold(fd, st);
       },
       "malformed", true, true},
      {"oversized packet",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         send_bytes(fd, {0, 0, 0x10, 0, 3, 0, 0, 0}, st);  // Size 1 MiB > max_packet_bytes 64 KiB
         hold(fd, st);
       },
       "above the configured maximum", true, true},
      {"unknown packet type",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         send_bytes(fd, {8, 0, 0, 0, 42, 0, 0, 0}, st);
         hold(fd, st);
       },
       "not in the RT protocol", true, true},
      {"label count disagrees with the frames",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         DataFrame f;
         f.frame_number = 1;
         f.has_3d = true;
         f.labelled_p_qtm_mm.resize(3, Eigen::Vector3f::Zero());  // 3 markers, 2 labels
         Bytes b;
         write_data_packet(f, ByteOrder::little, b);
         PacketSplitter in(ByteOrder::little, 1 << 16);
         send_bytes(fd, b, st);
         // Should the client read the labels again, the same 2 come back.
         while (read_command(fd, in, st)) {
           Parameters3d p;
           p.labels = kPeerLabels;
           send_bytes(fd, string_packet(PacketType::xml, write_parameters_3d(p, "1.19")), st);
           send_bytes(fd, b, st);
         }
         hold(fd, st);
       },
       "markers but the 3D parameters 2 labels", true, true},
      {"server closes after the handshake",
       [](int fd, const std::stop_token& st) {
         if (handshake(fd, st)) send_bytes(fd, good_data_packet(1), st);
       },
       "the server closed the connection", false, true},
      {"QTM shuts down",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         send_bytes(fd, {9, 0, 0, 0, 6, 0, 0, 0, 12}, st);
         hold(fd, st);
       },
       "shutting down (event 12)", false, true},
      {"an error while streaming",
       [](int fd, const std::stop_token& st) {
         if (!handshake(fd, st)) return;
         send_bytes(fd, string_packet(PacketType::error, "Parse Error"), st);
         hold(fd, st);
       },
       "sent an error while streaming: \"Parse Error\"", false, true},
  };
  for (const BadPeerCase& c : cases) {
    DYNAMIC_SECTION(c.name) {
      FakePeer peer(c.behaviour);
      ClientThread client(options_for(peer.port()));
      // Two failures: it gave up on the first attempt and tried again.
      const bool retried = eventually(
          [&] { return client.status.snapshot().errors >= 2 && peer.accepted() >= 2; }, 5.0);
      const double stop_s = client.stop();
      const auto st = client.status.snapshot();
      INFO("last error: " << st.last_error);
      CHECK(retried);
      CHECK(st.last_error.find(c.error_contains) != std::string::npos);
      CHECK((st.bad_packets > 0) == c.bad_packet);
      CHECK((st.connections > 0) == c.handshakes);
      CHECK_FALSE(st.connected);
      CHECK(stop_s < 0.35);
    }
  }
}

TEST_CASE(
    "qtm client: a host no resolver knows is told as a name to check, an IPv6 address in "
    "brackets",
    "[qtm][client]") {
  CHECK(bridges::host_port("::1", 22223) == "[::1]:22223");  // was "::1:22223"
  CHECK(bridges::host_port("10.0.0.5", 22223) == "10.0.0.5:22223");
  if (const std::string why = test::resolver_cannot_answer(); !why.empty()) {
    WARN("skipped: " << why);
    return;
  }
  QtmClientOptions o = options_for(22223);
  o.host = test::kUnknownHost;
  ClientThread client(o);
  REQUIRE(eventually([&] { return client.status.snapshot().errors > 0; }, 10.0));
  client.stop();
  const std::string error = client.status.snapshot().last_error;
  CHECK_THAT(error, Catch::Contains("no host is named 'nohost.invalid'") &&
                        Catch::Contains("check the host's name in the source URL"));
  CHECK_THAT(error, !Catch::Contains("RT server on"));  // no port or server to check for a name
}

TEST_CASE("qtm client: the 11th client is refused with QTM's message", "[qtm][client]") {
  ServerThread server(recording(), looping());
  std::vector<bridges::Fd> ten;
  std::stop_source never;
  for (int i = 0; i < 10; ++i) {
    std::string error;
    ten.push_back(bridges::connect_tcp("127.0.0.1", server.server.port_little_endian(), 1.0, never.get_token(), error));
    REQUIRE(ten.back().valid());
  }
  REQUIRE(eventually([&] { return server.server.progress().clients == 10; }, 2.0));
  ClientThread client(options_for(server.server.port_little_endian()));
  REQUIRE(eventually([&] { return client.status.snapshot().errors >= 1; }, 3.0));
  client.stop();
  CHECK(client.status.snapshot().last_error.find("Connection refused. Max number of clients reached.") !=
        std::string::npos);
}

// A whole big-endian session in bytes laid out by hand from the protocol
// document ("Command / Command Response packet", "XML packet", "Data packet",
// "3D component"): what the client must send, and what it must make of QTM's replies.
TEST_CASE("qtm client: a big-endian session, byte for byte", "[qtm][client]") {
  auto ascii = [](std::string_view s) {
    Bytes b(s.begin(), s.end());
    b.push_back(0);
    return b;
  };
  auto cat = [](std::initializer_list<Bytes> parts) {
    Bytes out;
    for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
  };
  // Server -> client. Welcome: 26 chars + NUL = 27, Size 35 = 0x23, Type 1.
  const Bytes welcome = cat({{0, 0, 0, 0x23, 0, 0, 0, 1}, ascii("QTM RT Interface connected")});
  // "Version set to 1.19": 19 + 1 = 20, Size 28 = 0x1C.
  const Bytes version_set = cat({{0, 0, 0, 0x1C, 0, 0, 0, 1}, ascii("Version set to 1.19")});
  // "Byte order is big endian": 24 + 1 = 25, Size 33 = 0x21.
  const Bytes big_endian = cat({{0, 0, 0, 0x21, 0, 0, 0, 1}, ascii("Byte order is big endian")});
  // XML, Type 2: 25 + 8 + 18 + 7 + 17 + 8 + 9 + 26 = 118 chars + NUL = 119, Size 127 = 0x7F.
  const std::string xml =
      "<QTM_Parameters_Ver_1.19><The_3D><Labels>1</Labels><Label><Name>LASI</Name></Label></The_3D>"
      "</QTM_Parameters_Ver_1.19>";
  REQUIRE(xml.size() == 118);  // the hand count above
  const Bytes parameters = cat({{0, 0, 0, 0x7F, 0, 0, 0, 2}, ascii(xml)});
  // Data, Type 3: Size 52 = 8 + 16 + 28; Timestamp 2 500 000 us = 0x2625A0,
  // Frame Number 7, 1 component: Size 28 = 8 + 4 + 2 + 2 + 12, Type 1, Marker
  // Count 1, rates 0 0, (1.5, -2.0, 1000.25) = 0x3FC00000 0xC0000000 0x447A1000.
  const Bytes data = {0, 0, 0, 0x34, 0, 0, 0, 3,
                      0, 0, 0, 0, 0, 0x26, 0x25, 0xA0,
                      0, 0, 0, 7, 0, 0, 0, 1,
                      0, 0, 0, 0x1C, 0, 0, 0, 1,
                      0, 0, 0, 1, 0, 0, 0, 0,
                      0x3F, 0xC0, 0, 0, 0xC0, 0, 0, 0, 0x44, 0x7A, 0x10, 0};
  // Client -> server, big endian, each with its NUL: Size = 8 + chars + 1.
  const std::vector<Bytes> expected_commands = {
      cat({{0, 0, 0, 21, 0, 0, 0, 1}, ascii("Version 1.19")}),
      cat({{0, 0, 0, 18, 0, 0, 0, 1}, ascii("ByteOrder")}),
      cat({{0, 0, 0, 25, 0, 0, 0, 1}, ascii("GetParameters 3D")}),
      cat({{0, 0, 0, 34, 0, 0, 0, 1}, ascii("StreamFrames AllFrames 3D")}),
  };
  const std::vector<Bytes> replies = {version_set, big_endian, parameters, data};
  std::atomic<int> commands_matched{0};
  FakePeer peer([&](int fd, const std::stop_token& st) {
    send_bytes(fd, welcome, st);
    for (std::size_t i = 0; i < expected_commands.size(); ++i) {
      Bytes got;
      const auto deadline = bridges::deadline_after(1.0);
      while (got.size() < expected_commands[i].size()) {
        if (bridges::wait_fd(fd, POLLIN, deadline, st) != bridges::WaitResult::ready) return;
        std::uint8_t b[256];
        const long n = bridges::read_some(fd, std::span(b, expected_commands[i].size() - got.size()));
        if (n == 0 || n == -2) return;
        if (n > 0) got.insert(got.end(), b, b + n);
      }
      if (got != expected_commands[i]) return;
      ++commands_matched;
      send_bytes(fd, replies[i], st);
    }
    hold(fd, st);
  });
  ClientThread client(options_for(peer.port()));
  REQUIRE(client.sink.wait([](auto& f, auto&) { return !f.empty(); }, 3.0));
  client.stop();
  CHECK(commands_matched == 4);
  const auto frames = client.sink.frames();
  REQUIRE(frames.size() == 1);
  CHECK(frames[0].number == 7);
  CHECK(frames[0].time_s == Approx(2.5).margin(1e-12));
  CHECK(frames[0].p_mm[0] == Eigen::Vector3d(1.5, -2.0, 1000.25));
  CHECK(client.sink.label_sets() == std::vector<std::vector<std::string>>{{"LASI"}});
  CHECK(client.status.snapshot().server == "QTM RT protocol 1.19");
}

// ----------------------------------------------------------------------------
// The simulator seen from a raw connection, as a third-party client sees it.

namespace {

class RawConnection {
 public:
  explicit RawConnection(std::uint16_t port, ByteOrder order = ByteOrder::little) : order_(order), in_(order, 1 << 20) {
    std::string error;
    fd_ = bridges::connect_tcp("127.0.0.1", port, 1.0, stop_.get_token(), error);
    REQUIRE(fd_.valid());
  }
  void command(std::string_view text) {
    Bytes b;
    write_command_packet(text, order_, b);
    send_bytes(fd_.get(), b, stop_.get_token());
  }
  // The next packet's type and bytes (string packets: their text), within `seconds`.
  std::optional<std::pair<PacketType, Bytes>> next(double seconds = 1.0) {
    const auto deadline = bridges::deadline_after(seconds);
    for (;;) {
      PacketView p;
      if (in_.next(p) == Status::ok) return std::pair{*p.type(), Bytes(p.data.begin(), p.data.end())};
      if (bridges::wait_fd(fd_.get(), POLLIN, deadline, stop_.get_token()) != bridges::WaitResult::ready)
        return std::nullopt;
      std::uint8_t buf[8192];
      const long n = bridges::read_some(fd_.get(), buf);
      if (n == 0 || n == -2) return std::nullopt;
      if (n > 0) in_.feed(std::span(buf, static_cast<std::size_t>(n)));
    }
  }
  // The next packet that is not data or no-more-data, as text.
  std::optional<std::pair<PacketType, std::string>> reply(double seconds = 1.0) {
    for (;;) {
      auto p = next(seconds);
      if (!p) return std::nullopt;
      if (p->first == PacketType::data || p->first == PacketType::no_more_data) continue;
      std::string text(p->second.begin(), p->second.end());
      if (!text.empty() && text.back() == '\0') text.pop_back();
      return std::pair{p->first, text};
    }
  }
  ByteOrder order() const { return order_; }

 private:
  std::stop_source stop_;
  ByteOrder order_;
  PacketSplitter in_;
  bridges::Fd fd_;
};

}  // namespace

TEST_CASE("qtm simulator: answers commands as the protocol document says", "[qtm][client]") {
  ServerThread server(recording(), looping());
  RawConnection c(server.server.port_little_endian());
  using R = std::pair<PacketType, std::string>;
  // Exactly this string: Qualisys's Python SDK compares it whole.
  CHECK(c.reply() == R{PacketType::command, "QTM RT Interface connected"});
  c.command("Version");
  CHECK(c.reply() == R{PacketType::command, "Version is 1.1"});  // QTM's default without Version
  c.command("version 1.7");
  CHECK(c.reply() == R{PacketType::error, "Version NOT supported"});
  c.command("version 1.26");
  CHECK(c.reply() == R{PacketType::command, "Version set to 1.26"});
  c.command("ByteOrder");
  CHECK(c.reply() == R{PacketType::command, "Byte order is little endian"});
  c.command("QTMVersion");
  CHECK(c.reply()->second.rfind("QTM Version is ", 0) == 0);
  c.command("NoSuchCommand");
  CHECK(c.reply() == R{PacketType::error, "Parse Error"});
  c.command("Start");
  CHECK(c.reply() == R{PacketType::error, "You must be master to issue this command"});
  c.command("GetParameters 6D");
  CHECK(c.reply() == R{PacketType::error, "Parameters not available"});
  c.command("getparameters general 3d");
  const auto xml = c.reply();
  REQUIRE(xml);
  CHECK(xml->first == PacketType::xml);
  CHECK(xml->second.rfind("<QTM_Parameters_Ver_1.26>", 0) == 0);
  CHECK(xml->second.find("<Frequency>500</Frequency>") != std::string::npos);  // 100 Hz x rate_scale 5
  Parameters3d p;
  std::string error;
  REQUIRE(read_parameters_3d(xml->second, p, error));
  CHECK(p.labels == recording().names);
  // GetState: an event packet with the state, RT from file running.
  c.command("GetState");
  const auto state = c.next();
  REQUIRE(state);
  CHECK(state->first == PacketType::event);
  CHECK(state->second == Bytes{8});
  // GetCurrentFrame: one data packet.
  c.command("GetCurrentFrame 3D");
  const auto frame = c.next();
  REQUIRE(frame);
  CHECK(frame->first == PacketType::data);
  // StreamFrames has no reply of its own: data packets follow. Frequency:50
  // of a 500 Hz stream is about every 10th frame.
  c.command("StreamFrames Frequency:50 3D");
  std::vector<std::uint32_t> numbers;
  while (numbers.size() < 6) {
    const auto d = c.next();
    REQUIRE(d);
    REQUIRE(d->first == PacketType::data);
    Bytes whole_packet;
    write_packet(PacketType::data, d->second, ByteOrder::little, whole_packet);
    PacketView v;
    REQUIRE(read_packet(whole_packet, ByteOrder::little, 1 << 20, v) == Status::ok);
    DataFrame f;
    REQUIRE(read_data(v, ByteOrder::little, 100, f) == Status::ok);
    CHECK(f.has_3d);
    numbers.push_back(f.frame_number);
  }
  for (std::size_t i = 1; i < numbers.size(); ++i) CHECK(numbers[i] - numbers[i - 1] == 10);
  c.command("StreamFrames Stop");
  c.command("ByteOrder");  // after Stop, the reply comes once the data in flight has
  CHECK(c.reply() == R{PacketType::command, "Byte order is little endian"});
  CHECK_FALSE(c.next(0.1));  // nothing more streams
}

TEST_CASE("qtm simulator: the 3D parameters name the recording's up axis, each of the six",
          "[qtm][client]") {
  for (const std::string up : {"+x", "-x", "+y", "-y", "+z", "-z"}) {
    CAPTURE(up);
    bridges::SimRecording rec = recording();
    rec.up = up;
    ServerThread server(rec, looping());
    RawConnection c(server.server.port_little_endian());
    REQUIRE(c.reply());  // the welcome
    c.command("getparameters 3d");
    const auto xml = c.reply();
    REQUIRE(xml);
    Parameters3d p;
    std::string error;
    REQUIRE(read_parameters_3d(xml->second, p, error));
    const std::string want{up[0], static_cast<char>(up[1] - 'a' + 'A')};
    CHECK(p.axis_upwards == want);  // +x and -x were served as +Z
  }
}

TEST_CASE("qtm simulator: a script that ends says so, pauses hold the frames back", "[qtm][client]") {
  bridges::SimScript s;
  s.rate_scale = 10.0;  // 1000 Hz: 100 frames in 0.1 s
  s.pauses.push_back({50, 0.3});
  QtmSimServer server(recording(), s, any_free_ports());
  RawConnection c(server.port_big_endian(), ByteOrder::big);  // connected before frames start
  std::jthread serving([&](std::stop_token st) { server.run(st); });
  REQUIRE(c.reply());
  c.command("StreamFrames AllFrames 3D");
  std::vector<std::pair<std::uint32_t, Clock::time_point>> got;
  bool no_more_data = false, stopped_event = false;
  while (auto p = c.next(2.0)) {
    if (p->first == PacketType::data) {
      Bytes whole_packet;
      write_packet(PacketType::data, p->second, ByteOrder::big, whole_packet);
      PacketView v;
      DataFrame f;
      REQUIRE(read_packet(whole_packet, ByteOrder::big, 1 << 20, v) == Status::ok);
      REQUIRE(read_data(v, ByteOrder::big, 100, f) == Status::ok);
      got.emplace_back(f.frame_number, Clock::now());
    }
    no_more_data |= p->first == PacketType::no_more_data;
    stopped_event |= p->first == PacketType::event && p->second == Bytes{9};
  }
  serving.join();  // run() returned by itself: the script ended
  CHECK(no_more_data);
  CHECK(stopped_event);
  REQUIRE(got.size() >= 60);
  CHECK(got.back().first == 100);
  CHECK(server.progress().frames_sent == 100);
  // The pause before frame index 50 (frame number 51).
  for (std::size_t i = 1; i < got.size(); ++i)
    if (got[i].first == 51) CHECK(std::chrono::duration<double>(got[i].second - got[i - 1].second).count() > 0.25);
}

TEST_CASE("qtm client: stop is seen within a poll slice in every long wait", "[qtm][client]") {
  auto o = [](std::uint16_t port) {
    auto opts = options_for(port);
    opts.policy.connect_timeout_s = opts.policy.reply_timeout_s = opts.policy.stall_timeout_s = 30.0;
    return opts;
  };
  SECTION("waiting for the welcome") {
    FakePeer peer([](int fd, const std::stop_token& st) { hold(fd, st); });
    ClientThread client(o(peer.port()));
    REQUIRE(eventually([&] { return peer.accepted() == 1; }, 2.0));
    CHECK(client.stop() < 0.25);
  }
  SECTION("streaming, no frame yet") {
    FakePeer peer([](int fd, const std::stop_token& st) {
      if (handshake(fd, st)) hold(fd, st);
    });
    ClientThread client(o(peer.port()));
    REQUIRE(eventually([&] { return client.status.snapshot().connected; }, 2.0));
    CHECK(client.stop() < 0.25);
    CHECK(client.status.snapshot().errors == 0);  // a stop is not an error
  }
  SECTION("waiting out a backoff") {
    FakePeer peer([](int, const std::stop_token&) {});  // accepts and closes
    auto opts = o(peer.port());
    opts.policy.reconnect_min_s = opts.policy.reconnect_max_s = 30.0;
    ClientThread client(opts);
    REQUIRE(eventually([&] { return client.status.snapshot().errors == 1; }, 2.0));
    CHECK(client.stop() < 0.25);
  }
}

TEST_CASE("qtm client: the rest of a started packet is bounded by reply_timeout_s, not stall_timeout_s",
          "[qtm][client]") {
  FakePeer peer([](int fd, const std::stop_token& st) {
    if (!handshake(fd, st)) return;
    const Bytes p = good_data_packet(1);
    send_bytes(fd, Bytes(p.begin(), p.begin() + 20), st);
    hold(fd, st);
  });
  auto opts = options_for(peer.port());
  opts.policy.stall_timeout_s = 30.0;
  opts.policy.reply_timeout_s = 0.2;
  ClientThread client(opts);
  REQUIRE(eventually([&] { return client.status.snapshot().connected; }, 2.0));
  const auto t0 = Clock::now();
  REQUIRE(eventually([&] { return client.status.snapshot().errors >= 1; }, 3.0));
  const double waited_s = seconds_since(t0);
  client.stop();
  CHECK(client.status.snapshot().last_error.find("stalled mid-packet") != std::string::npos);
  CHECK(waited_s < 1.0);
}
