#include "bridges/natnet_sim_server.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "bridges/ipv4_multicast.hpp"
#include "bridges/udp_socket.hpp"

namespace fabrik::bridges {

namespace {

using Clock = std::chrono::steady_clock;
using natnet::MessageId;

constexpr auto kServerSlice = std::chrono::milliseconds(100);
constexpr auto kClientTimeout = std::chrono::seconds(10);
constexpr auto kModelsChangedFor = std::chrono::seconds(1);
constexpr std::size_t kMaxDatagramBytes = 65503;  // PacketClient's MAX_PACKETSIZE
constexpr std::int32_t kAssetId = 1;
constexpr float kMarkerSize_m = 0.014F;
constexpr std::uint64_t kClockHz = 1'000'000'000;  // steady_clock nanoseconds

Eigen::Vector3d parse_axis(const std::string& text, const char* what) {
  if (text.size() == 2 && (text[0] == '+' || text[0] == '-') && text[1] >= 'x' && text[1] <= 'z') {
    Eigen::Vector3d a = Eigen::Vector3d::Zero();
    a[text[1] - 'x'] = text[0] == '+' ? 1.0 : -1.0;
    return a;
  }
  throw std::runtime_error(std::string("NatNet simulator: ") + what + " '" + text +
                           "' is not one of +x, -x, +y, -y, +z, -z");
}

// Motive's version for a NatNet version (Motive 2.1: 3.0, 2.2/2.3: 3.1,
// 3.0: 4.0, 3.1+: 4.1).
natnet::Version motive_version(const natnet::Version& v) {
  if (v.major >= 4) return {3, v.minor, 0, 0};
  return {2, static_cast<std::uint8_t>(v.minor == 0 ? 1 : 3), 0, 0};
}

Clock::duration duration_of_s(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(std::max(0.0, s)));
}

}  // namespace

struct NatNetSimServer::Impl {
  SimRecording rec;
  SimScript script;
  Options opt;
  Eigen::Matrix3d rotation;  // recording axes -> Motive's streaming axes
  std::string set_name;
  natnet::Version version;
  std::uint16_t command_port = 0, data_port = 0;
  UdpSocket command, data;
  UdpEndpoint group{};
  struct Client {
    UdpEndpoint at;
    Clock::time_point last_heard;
  };
  std::vector<Client> clients;
  std::vector<std::string> names;        // current marker names (after renames)
  std::vector<bool> pause_done, restart_done, rename_done;
  bool models_changed = false;
  Clock::time_point models_changed_at{};
  bool timeline_stopped = false;
  std::vector<std::uint8_t> last_frame, buffer;
  std::atomic<std::uint64_t> frames_sent{0};
  std::atomic<int> client_count{0};

  Impl(SimRecording r, SimScript s, Options o)
      : rec(std::move(r)), script(std::move(s)), opt(std::move(o)), version(opt.version) {
    const auto fail = [](const std::string& what) {
      throw std::runtime_error("NatNet simulator: " + what);
    };
    if (rec.p_mm.empty() || rec.names.empty()) fail("the recording has no frames or no markers");
    for (const auto& f : rec.p_mm)
      if (f.size() != rec.names.size()) fail("a recording frame's marker count differs from its names");
    if (!(rec.rate_hz > 0) || !(script.rate_scale > 0)) fail("rate and rate scale must be positive");
    if (!natnet::supported(version))
      fail("NatNet " + natnet::to_string(version) + " cannot be served (3.x and 4.x can)");
    rotation = Eigen::Quaterniond::FromTwoVectors(parse_axis(rec.up, "the recording's up axis"),
                                                  parse_axis(opt.up_axis, "up_axis"))
                   .toRotationMatrix();
    set_name = script.subject_prefix.empty() ? kSimMarkerSet : script.subject_prefix;
    names = rec.names;
    pause_done.assign(script.pauses.size(), false);
    restart_done.assign(script.restarts.size(), false);
    rename_done.assign(script.renames.size(), false);
    // The largest frame (every marker seen and labelled) must fit one datagram.
    const auto sizes = [&](const natnet::Version& v) {
      natnet::FrameOfData f = frame(0);
      f.labeled_markers.resize(rec.names.size());
      return std::max(natnet::encode_frame_of_data(f, v).size(),
                      natnet::encode_model_definitions(definitions(v), v).size()) +
             natnet::kHeaderBytes;
    };
    if (sizes(version) > kMaxDatagramBytes || sizes({3, 0, 0, 0}) > kMaxDatagramBytes)
      fail(std::to_string(rec.names.size()) + " markers do not fit one NatNet datagram (" +
           std::to_string(kMaxDatagramBytes) + " bytes); NatNet does not split frames");
    std::string error;
    const auto g = resolve_ipv4(opt.multicast_group, opt.data_port, error);
    if (!g) fail("multicast group: " + error);
    if (const std::string problem = multicast_group_problem(opt.multicast_group);
        opt.multicast && !problem.empty())
      fail("multicast group: " + problem + "; Motive's default is 239.255.42.99");
    group = *g;
    command_port = opt.command_port;
    data_port = opt.data_port;
    if (opt.multicast && data_port == 0) {  // a free port for the group's listeners
      UdpSocket probe;
      if (!probe.open("0.0.0.0", 0, false, error)) fail(error);
      data_port = probe.local_port();
    }
    group.port = data_port;
    if (!open_sockets(error)) fail(error);
  }

  bool open_sockets(std::string& error) {
    if (!command.open(opt.bind_address, command_port, false, error)) {
      error = "command socket: " + error;
      return false;
    }
    command_port = command.local_port();
    if (!data.open(opt.bind_address, 0, false, error) ||
        (opt.multicast && !data.set_multicast_sender(opt.bind_address, error))) {
      error = "data socket: " + error;
      command.close();
      return false;
    }
    if (!opt.multicast && data_port == 0) data_port = data.local_port();
    return true;
  }

  natnet::ModelDefinitions definitions(const natnet::Version& v) const {
    natnet::ModelDefinitions defs;
    defs.marker_sets.push_back({set_name, names});
    if (v.major == 3) defs.marker_sets.push_back({"all", names});
    return defs;
  }

  bool dropped(std::size_t marker, std::int64_t index) const {
    return std::any_of(script.drops.begin(), script.drops.end(), [&](const SimScript::Drop& d) {
      return index >= d.from_frame && index < d.to_frame &&
             (d.marker == rec.names[marker] || d.marker == names[marker]);
    });
  }

  natnet::FrameOfData frame(std::int64_t index) {
    natnet::FrameOfData f;
    const auto& p_file_mm = rec.p_mm[static_cast<std::size_t>(index) % rec.p_mm.size()];
    std::vector<natnet::Point3f> p_m(names.size(), natnet::Point3f{0, 0, 0});
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (!p_file_mm[i].allFinite()) continue;  // not seen: (0,0,0), not labelled
      const Eigen::Vector3f p = (rotation * p_file_mm[i] / 1000.0).cast<float>();
      p_m[i] = {p.x(), p.y(), p.z()};
      natnet::LabeledMarker m;
      m.id = (kAssetId << 16) | static_cast<std::int32_t>(i + 1);
      m.p_m = p_m[i];
      m.size_m = kMarkerSize_m;
      m.params = dropped(i, index) ? natnet::LabeledMarker::kOccluded | natnet::LabeledMarker::kModelSolved
                                   : natnet::LabeledMarker::kPointCloudSolved;
      f.labeled_markers.push_back(m);
    }
    f.frame_number = static_cast<std::int32_t>(index);
    f.marker_sets.push_back({set_name, p_m});
    if (version.major == 3) f.marker_sets.push_back({"all", p_m});
    f.timestamp_s = static_cast<double>(index) / rec.rate_hz;
    const auto ticks = static_cast<std::uint64_t>(Clock::now().time_since_epoch().count());
    f.camera_mid_exposure_ticks = f.camera_data_received_ticks = f.transmit_ticks = ticks;
    const auto wall = std::chrono::system_clock::now().time_since_epoch();
    const auto wall_s = std::chrono::duration_cast<std::chrono::seconds>(wall);
    f.precision_timestamp_s = static_cast<std::uint32_t>(wall_s.count());
    f.precision_timestamp_fraction = static_cast<std::uint32_t>(
        std::chrono::duration<double>(wall - wall_s).count() * 4294967296.0);
    f.params = models_changed ? 0x02 : 0x00;
    return f;
  }

  void send(const UdpEndpoint& to, MessageId id, std::span<const std::uint8_t> payload) {
    const auto datagram = natnet::encode_message(id, payload);
    std::string ignored;  // a client gone is not the server's failure
    command.send_to(to, datagram, ignored);
  }

  void heard(const UdpEndpoint& from) {
    const auto it = std::find_if(clients.begin(), clients.end(),
                                 [&](const Client& c) { return c.at == from; });
    if (it == clients.end()) clients.push_back({from, Clock::now()});
    else it->last_heard = Clock::now();
  }

  void forget(const UdpEndpoint& from) {
    std::erase_if(clients, [&](const Client& c) { return c.at == from; });
  }

  static std::int32_t parse_bitstream(const std::string& request, natnet::Version& v) {
    // "Bitstream,4.1" or "Bitstream,4.1.0.0"
    unsigned major = 0, minor = 0;
    if (std::sscanf(request.c_str() + 10, "%u.%u", &major, &minor) != 2) return 1;
    const natnet::Version asked{static_cast<std::uint8_t>(major), static_cast<std::uint8_t>(minor), 0, 0};
    if (major > 255 || minor > 255 || !natnet::supported(asked)) return 1;
    v = asked;
    return 0;
  }

  void answer_request(const UdpEndpoint& from, std::span<const std::uint8_t> payload) {
    const auto* text = reinterpret_cast<const char*>(payload.data());
    const std::string request(text, strnlen(text, payload.size()));
    std::int32_t result = 0;
    if (request.rfind("Bitstream,", 0) == 0) result = parse_bitstream(request, version);
    else if (request == "TimelineStop") timeline_stopped = true;
    else if (request == "TimelinePlay") timeline_stopped = false;
    else {
      send(from, MessageId::unrecognized_request, {});
      return;
    }
    std::uint8_t bytes[4];
    std::memcpy(bytes, &result, 4);
    send(from, MessageId::response, bytes);
  }

  void handle(const UdpEndpoint& from, const natnet::Message& m) {
    switch (m.id) {
      case MessageId::connect: {
        heard(from);
        natnet::ServerInfo info;
        info.application_name = "Motive";
        info.application_version = motive_version(version);
        info.natnet_version = version;
        info.high_res_clock_frequency_hz = kClockHz;
        info.data_port = data_port;
        info.is_multicast = opt.multicast;
        std::memcpy(info.multicast_group.data(), &group.address_be, 4);
        send(from, MessageId::server_info, natnet::encode_server_info(info));
        break;
      }
      case MessageId::request_model_def:
        heard(from);
        models_changed = false;
        send(from, MessageId::model_def, natnet::encode_model_definitions(definitions(version), version));
        break;
      case MessageId::request:
        heard(from);
        answer_request(from, m.payload);
        break;
      case MessageId::keep_alive:
        heard(from);
        break;
      case MessageId::request_frame_of_data:
        heard(from);
        if (!last_frame.empty()) command.send_to(from, last_frame, buffer_error);
        break;
      case MessageId::disconnect:
        forget(from);
        break;
      default:
        break;  // Motive ignores what it does not know
    }
  }

  // A command as the SDK's clients send it. Leniently: NatNetClient.py ends
  // even its payload-less requests (NAT_REQUEST_MODELDEF, NAT_KEEPALIVE) with
  // a NUL that the header's size of 0 does not count, so bytes past the
  // header's size are ignored; fewer than it says is still refused.
  static bool split_request(std::span<const std::uint8_t> datagram, natnet::Message& m) {
    if (datagram.size() < natnet::kHeaderBytes) return false;
    const std::size_t size = datagram[2] | (datagram[3] << 8);
    if (datagram.size() - natnet::kHeaderBytes < size) return false;
    m.id = static_cast<MessageId>(datagram[0] | (datagram[1] << 8));
    m.payload = datagram.subspan(natnet::kHeaderBytes, size);
    return true;
  }

  // Answers commands until `until` (or stop), in slices of at most 100 ms.
  void serve_commands(Clock::time_point until, const std::stop_token& stop) {
    for (;;) {
      if (stop.stop_requested()) return;
      const auto now = Clock::now();
      std::erase_if(clients, [&](const Client& c) { return now - c.last_heard > kClientTimeout; });
      client_count = static_cast<int>(clients.size());
      if (now >= until) return;
      const auto slice = std::min<Clock::duration>(kServerSlice, until - now);
      UdpEndpoint from;
      std::size_t bytes = 0;
      std::string error;
      const auto got = command.receive(
          buffer, 65536, from, bytes,
          static_cast<int>(std::chrono::ceil<std::chrono::milliseconds>(slice).count()), error);
      if (got != UdpSocket::Received::datagram || bytes > buffer.size()) continue;
      natnet::Message m;
      if (split_request(buffer, m)) handle(from, m);
    }
  }

  void send_frame(std::int64_t index) {
    if (models_changed && Clock::now() - models_changed_at > kModelsChangedFor) models_changed = false;
    last_frame = natnet::encode_message(MessageId::frame_of_data,
                                        natnet::encode_frame_of_data(frame(index), version));
    const Clock::time_point send_start = Clock::now();
    if (opt.multicast) {
      data.send_to(group, last_frame, buffer_error);
    } else {
      for (const auto& c : clients) data.send_to(c.at, last_frame, buffer_error);
    }
    ++frames_sent;
    if (opt.on_frame_sent && (opt.multicast || !clients.empty()))
      opt.on_frame_sent(static_cast<std::uint64_t>(index), send_start);
  }

  // Script events at or before `index` not yet done: renames, then a restart,
  // then a pause. Returns when they are done (or stop).
  void script_events(std::int64_t index, const std::stop_token& stop) {
    for (std::size_t i = 0; i < script.renames.size(); ++i) {
      const auto& r = script.renames[i];
      if (rename_done[i] || r.at_frame > index) continue;
      rename_done[i] = true;
      const auto it = std::find(names.begin(), names.end(), r.from);
      if (it == names.end()) continue;
      *it = r.to;
      models_changed = true;
      models_changed_at = Clock::now();
    }
    for (std::size_t i = 0; i < script.restarts.size(); ++i) {
      if (restart_done[i] || script.restarts[i].at_frame > index) continue;
      restart_done[i] = true;
      command.close();
      data.close();
      clients.clear();
      client_count = 0;
      models_changed = false;
      std::mutex m;
      std::condition_variable_any cv;
      std::unique_lock lock(m);
      cv.wait_for(lock, stop, duration_of_s(script.restarts[i].down_seconds), [] { return false; });
      std::string error;
      if (!open_sockets(error)) throw std::runtime_error("NatNet simulator restart: " + error);
    }
    for (std::size_t i = 0; i < script.pauses.size(); ++i) {
      if (pause_done[i] || script.pauses[i].at_frame > index) continue;
      pause_done[i] = true;
      serve_commands(Clock::now() + duration_of_s(script.pauses[i].seconds), stop);
    }
  }

  void run(const std::stop_token& stop) {
    const auto period = duration_of_s(1.0 / (rec.rate_hz * script.rate_scale));
    const auto frames = static_cast<std::int64_t>(rec.p_mm.size());
    std::int64_t index = 0;
    std::uint64_t sent = 0;
    auto due = Clock::now();
    while (!stop.stop_requested()) {
      if (script.max_frames >= 0 && sent >= static_cast<std::uint64_t>(script.max_frames)) return;
      if (!script.loop && index >= frames) return;
      const auto before = Clock::now();
      script_events(index, stop);
      if (Clock::now() - before > period) due = Clock::now();  // a pause or restart: no catch-up burst
      serve_commands(due, stop);
      if (stop.stop_requested()) return;
      if (timeline_stopped) {
        due = Clock::now() + period;
        continue;
      }
      send_frame(index);
      ++index;
      ++sent;
      due += period;
      if (Clock::now() - due > 10 * period) due = Clock::now();  // fell far behind: no burst
    }
  }

  std::string buffer_error;  // send errors to clients are not the server's failure
};

NatNetSimServer::NatNetSimServer(SimRecording recording, SimScript script, Options options)
    : impl_(std::make_unique<Impl>(std::move(recording), std::move(script), std::move(options))) {}
NatNetSimServer::~NatNetSimServer() = default;
std::uint16_t NatNetSimServer::command_port() const { return impl_->command_port; }
std::uint16_t NatNetSimServer::data_port() const { return impl_->data_port; }
void NatNetSimServer::run(std::stop_token stop) { impl_->run(stop); }
NatNetSimServer::Progress NatNetSimServer::progress() const {
  return {impl_->frames_sent.load(), impl_->client_count.load()};
}

}  // namespace fabrik::bridges
