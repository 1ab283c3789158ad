#include "bridges/qtm/sim_server.hpp"

#include <poll.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <atomic>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <list>
#include <stdexcept>
#include <string_view>
#include <thread>
#include <vector>

#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "bridges/tcp.hpp"
#include "common/ascii_case.hpp"

namespace fabrik::qtm {

namespace {

using bridges::Clock;

// Protocol versions served: 1.8 changed the 3D component to 32-bit floats
// without padding, the layout written here, and no later version changed it.
// QTM refuses a version newer than it knows; the simulator accepts any 1.x
// from 1.8 on, so that a client newer than this file (Qualisys's Python SDK
// asks for its own latest version) is not locked out.
constexpr ProtocolVersion kOldest{1, 8}, kNewest{1, 99};
constexpr int kMaxClients = 10;                       // doc, "Connecting"
constexpr std::size_t kMaxClientPacket = 1u << 20;    // commands and settings XML
constexpr std::size_t kMaxQueuedBytes = 8u << 20;     // a client this far behind is dropped

bool vless(ProtocolVersion a, ProtocolVersion b) { return a.major != b.major ? a.major < b.major : a.minor < b.minor; }
std::string vtext(ProtocolVersion v) { return std::to_string(v.major) + "." + std::to_string(v.minor); }

std::vector<std::string> lower_words(std::string_view s) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && s[i] == ' ') ++i;
    std::size_t j = i;
    while (j < s.size() && s[j] != ' ') ++j;
    if (j > i) out.push_back(ascii_lower(s.substr(i, j - i)));
    i = j;
  }
  return out;
}

std::optional<std::uint32_t> positive_after(std::string_view word, std::string_view prefix) {
  if (word.substr(0, prefix.size()) != prefix) return std::nullopt;
  std::uint32_t v = 0;
  const auto rest = word.substr(prefix.size());
  const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), v);
  if (ec != std::errc() || end != rest.data() + rest.size() || v == 0) return std::nullopt;
  return v;
}

struct Client {
  bridges::Fd fd;
  ByteOrder order;
  PacketSplitter in;
  std::vector<std::uint8_t> out;
  std::size_t out_sent = 0;
  bool closing = false;  // close once `out` is sent
  bool dead = false;
  ProtocolVersion version{1, 1};  // QTM's default without a Version command
  bool master = false;
  // Streaming.
  bool streaming = false;
  enum class Rate { all, divisor, frequency } rate = Rate::all;
  std::uint32_t n = 1;
  std::uint64_t counter = 0;
  double credit = 0.0;
  bool want_3d = false, want_3d_no_labels = false;

  Client(bridges::Fd f, ByteOrder o) : fd(std::move(f)), order(o), in(o, kMaxClientPacket) {}
};

}  // namespace

struct QtmSimServer::Impl {
  bridges::SimRecording rec;
  bridges::SimScript script;
  Options options;
  std::uint16_t port_le = 0, port_be = 0;
  bridges::Fd listen_le, listen_be;
  std::list<Client> clients;
  std::vector<std::string> labels;  // current labels (renames applied)
  std::atomic<std::uint64_t> frames_served{0};
  std::atomic<int> client_count{0};

  // The simulated measurement.
  std::int64_t next_index = 0;  // global frame index to serve next
  bool have_frame = false;      // a frame has been served (GetCurrentFrame)
  DataFrame current;            // the last frame served
  bool ended = false;
  Event state = Event::rt_from_file_started;
  std::vector<std::uint8_t> scratch;

  void bind_ports() {
    std::string error;
    if (options.base_port != 0) {
      if (options.base_port > 65533) throw std::runtime_error("QTM simulator: base port must be at most 65533");
      std::uint16_t got = 0;
      listen_le = bridges::listen_tcp(options.bind_address, static_cast<std::uint16_t>(options.base_port + 1), got, error);
      if (!listen_le.valid()) throw std::runtime_error("QTM simulator: " + error);
      port_le = got;
      listen_be = bridges::listen_tcp(options.bind_address, static_cast<std::uint16_t>(options.base_port + 2), got, error);
      if (!listen_be.valid()) throw std::runtime_error("QTM simulator: " + error);
      port_be = got;
      return;
    }
    for (int attempt = 0; attempt < 50; ++attempt) {  // a free pair of adjacent ports
      std::uint16_t le = 0, be = 0;
      bridges::Fd a = bridges::listen_tcp(options.bind_address, 0, le, error);
      if (!a.valid()) throw std::runtime_error("QTM simulator: " + error);
      if (le == 65535) continue;
      bridges::Fd b = bridges::listen_tcp(options.bind_address, static_cast<std::uint16_t>(le + 1), be, error);
      if (!b.valid()) continue;
      listen_le = std::move(a);
      listen_be = std::move(b);
      port_le = le;
      port_be = be;
      return;
    }
    throw std::runtime_error("QTM simulator: no two adjacent free ports on " + options.bind_address);
  }

  // After a restart: the same ports again, retried until stop.
  bool rebind(const std::stop_token& stop) {
    while (!stop.stop_requested()) {
      std::string error;
      std::uint16_t got = 0;
      listen_le = bridges::listen_tcp(options.bind_address, port_le, got, error);
      listen_be = bridges::listen_tcp(options.bind_address, port_be, got, error);
      if (listen_le.valid() && listen_be.valid()) return true;
      listen_le.reset();
      listen_be.reset();
      std::this_thread::sleep_for(bridges::kPollSlice);
    }
    return false;
  }

  // --- output --------------------------------------------------------------
  void queue(Client& c, std::span<const std::uint8_t> bytes) {
    if (c.dead || c.closing) return;
    if (c.out.size() - c.out_sent + bytes.size() > kMaxQueuedBytes) {
      c.dead = true;  // a client that does not read cannot hold the server
      return;
    }
    c.out.insert(c.out.end(), bytes.begin(), bytes.end());
    flush(c);
  }
  void flush(Client& c) {
    if (c.dead || c.out_sent == c.out.size()) return;
    const long n = bridges::send_some(c.fd.get(), std::span(c.out).subspan(c.out_sent));
    if (n < 0) {
      c.dead = true;
      return;
    }
    c.out_sent += static_cast<std::size_t>(n);
    if (c.out_sent == c.out.size()) {
      c.out.clear();
      c.out_sent = 0;
    }
  }
  void send_string(Client& c, PacketType type, std::string_view text) {
    write_string_packet(type, text, c.order, scratch);
    queue(c, scratch);
  }
  void send_event(Client& c, Event e) {
    write_event_packet(e, c.order, scratch);
    queue(c, scratch);
  }
  void send_no_more_data(Client& c) {
    write_packet(PacketType::no_more_data, {}, c.order, scratch);
    queue(c, scratch);
  }
  void send_frame(Client& c, bool want_3d, bool want_3d_no_labels) {
    current.has_3d = want_3d;
    current.has_3d_no_labels = want_3d_no_labels;  // every simulated marker is labelled: an empty list
    write_data_packet(current, c.order, scratch);
    queue(c, scratch);
  }

  // --- commands ------------------------------------------------------------
  std::string parameters_xml(bool general, bool three_d, const Client& c) const {
    const std::string version = vtext(vless(c.version, kOldest) ? kOldest : c.version);
    Parameters3d p;
    p.labels = labels;
    p.axis_upwards =
        rec.up.size() == 2
            ? std::string{rec.up[0],
                          static_cast<char>(std::toupper(static_cast<unsigned char>(rec.up[1])))}
            : "+Z";
    std::string xml = write_parameters_3d(p, version);
    if (!three_d) {  // keep the root, drop The_3D
      const std::size_t a = xml.find("  <The_3D>"), b = xml.find("  </The_3D>\n");
      xml.erase(a, b + 12 - a);
    }
    if (general) {
      const double rate = rec.rate_hz * script.rate_scale;
      const double capture_s = static_cast<double>(rec.p_mm.size()) / rec.rate_hz;
      std::string g = "  <General>\n    <Frequency>" + std::to_string(static_cast<long>(std::lround(rate))) +
                      "</Frequency>\n    <Capture_Time>" + std::to_string(capture_s) +
                      "</Capture_Time>\n    <Start_On_External_Trigger>False</Start_On_External_Trigger>\n"
                      "  </General>\n";
      xml.insert(xml.find('\n') + 1, g);
    }
    return xml;
  }

  void command(Client& c, std::string_view text) {
    const std::vector<std::string> w = lower_words(text);
    if (w.empty()) return send_string(c, PacketType::error, "Parse Error");
    const std::string& name = w[0];
    if (name == "version") {
      if (w.size() == 1) return send_string(c, PacketType::command, "Version is " + vtext(c.version));
      const ParsedCommand pc = parse_command(text);
      if (w.size() != 2 || !pc.version || vless(*pc.version, kOldest) || vless(kNewest, *pc.version))
        return send_string(c, PacketType::error, "Version NOT supported");
      c.version = *pc.version;
      return send_string(c, PacketType::command, "Version set to " + vtext(c.version));
    }
    if (name == "qtmversion") return send_string(c, PacketType::command, "QTM Version is fabrik sim (build 1)");
    if (name == "byteorder")
      return send_string(c, PacketType::command,
                         c.order == ByteOrder::little ? "Byte order is little endian" : "Byte order is big endian");
    if (name == "getstate") return send_event(c, state);
    if (name == "getparameters") {
      bool general = false, three_d = false, other = false;
      for (std::size_t i = 1; i < w.size(); ++i) {
        if (w[i] == "all") general = three_d = true;
        else if (w[i] == "general") general = true;
        else if (w[i] == "3d") three_d = true;
        else other = true;
      }
      if (!general && !three_d) return send_string(c, PacketType::error, other ? "Parameters not available" : "Parse Error");
      return send_string(c, PacketType::xml, parameters_xml(general, three_d, c));
    }
    if (name == "getcurrentframe") {
      bool d3 = false, nl = false;
      for (std::size_t i = 1; i < w.size(); ++i) {
        d3 |= w[i] == "3d" || w[i] == "all";
        nl |= w[i] == "3dnolabels" || w[i] == "all";
      }
      if (!have_frame || ended) return send_no_more_data(c);
      return send_frame(c, d3, nl);
    }
    if (name == "streamframes") return stream_frames(c, w);
    if (name == "takecontrol") {
      const bool was = c.master;
      for (Client& o : clients)
        if (&o != &c && o.master) return send_string(c, PacketType::error, "Client control disabled in QTM");
      c.master = true;
      return send_string(c, PacketType::command, was ? "You are already master" : "You are now master");
    }
    if (name == "releasecontrol") {
      const bool was = c.master;
      c.master = false;
      return send_string(c, PacketType::command, was ? "You are now a regular client" : "You are already a regular client");
    }
    static const std::array<std::string_view, 16> known = {
        "new", "close", "start", "stop", "load", "save", "loadproject", "getcapturec3d", "getcaptureqtm",
        "trig", "setqtmevent", "event", "reprocess", "led", "calibrate", "quit"};
    for (std::string_view k : known)
      if (name == k) {
        if (!c.master && k != "quit") return send_string(c, PacketType::error, "You must be master to issue this command");
        return send_string(c, PacketType::error, "Command not supported.");
      }
    send_string(c, PacketType::error, "Parse Error");  // doc, "Commands": an unrecognised command
  }

  void stream_frames(Client& c, const std::vector<std::string>& w) {
    if (w.size() == 2 && w[1] == "stop") {
      c.streaming = false;
      return;
    }
    bool rate_given = false, d3 = false, nl = false;
    Client::Rate rate = Client::Rate::all;
    std::uint32_t n = 1;
    for (std::size_t i = 1; i < w.size(); ++i) {
      const std::string& a = w[i];
      if (a == "allframes") {
        rate = Client::Rate::all;
        rate_given = true;
      } else if (auto d = positive_after(a, "frequencydivisor:")) {
        rate = Client::Rate::divisor;
        n = *d;
        rate_given = true;
      } else if (auto f = positive_after(a, "frequency:")) {
        rate = Client::Rate::frequency;
        n = *f;
        rate_given = true;
      } else if (a.rfind("udp", 0) == 0) {
        return send_string(c, PacketType::error, "UDP streaming is not simulated: stream over TCP");
      } else if (a == "3d") {
        d3 = true;
      } else if (a == "3dnolabels") {
        nl = true;
      } else if (a == "all") {
        d3 = nl = true;
      }  // other components: QTM would send them; the simulator has none
    }
    if (!rate_given) return send_string(c, PacketType::error, "Parse Error");
    c.streaming = true;
    c.rate = rate;
    c.n = n;
    c.counter = 0;
    c.credit = 1.0;  // the first frame goes out
    c.want_3d = d3;
    c.want_3d_no_labels = nl;
    if (ended) send_no_more_data(c);  // doc: no measurement, an empty data frame
  }

  void read_client(Client& c) {
    std::array<std::uint8_t, 8192> buf;
    for (;;) {
      const long n = bridges::read_some(c.fd.get(), buf);
      if (n == -1) break;
      if (n <= 0) {
        c.dead = true;
        return;
      }
      c.in.feed(std::span(buf.data(), static_cast<std::size_t>(n)));
    }
    PacketView p;
    for (;;) {
      const Status s = c.in.next(p);
      if (s == Status::need_more) return;
      if (s != Status::ok) {  // framing lost: nothing after it can be read
        c.dead = true;
        return;
      }
      std::string_view text;
      if (p.raw_type == static_cast<std::uint32_t>(PacketType::command) &&
          read_string(p, PacketType::command, text) == Status::ok)
        command(c, text);
      else if (p.raw_type == static_cast<std::uint32_t>(PacketType::xml))
        send_string(c, PacketType::error, "Setting parameters failed");
      else
        send_string(c, PacketType::error, "Parse Error");
    }
  }

  void accept_from(int listener, ByteOrder order) {
    for (;;) {
      bridges::Fd fd = bridges::accept_tcp(listener);
      if (!fd.valid()) return;
      Client& c = clients.emplace_back(std::move(fd), order);
      if (static_cast<int>(clients.size()) > kMaxClients) {
        send_string(c, PacketType::error, "Connection refused. Max number of clients reached.");
        c.closing = true;
        continue;
      }
      // QTM's welcome. The document prints it with a full stop; QTM sends it
      // without (Qualisys's Python SDK compares the exact string, the C++ SDK a prefix).
      send_string(c, PacketType::command, "QTM RT Interface connected");
    }
  }

  // --- the measurement -----------------------------------------------------
  std::int64_t frames_in_file() const { return static_cast<std::int64_t>(rec.p_mm.size()); }

  bool script_over(std::int64_t g) const {
    if (script.max_frames >= 0 && g >= script.max_frames) return true;
    return !script.loop && g >= frames_in_file();
  }

  void build_frame(std::int64_t g) {
    const auto& row = rec.p_mm[static_cast<std::size_t>(g % frames_in_file())];
    current.timestamp_us = static_cast<std::uint64_t>(std::llround(static_cast<double>(g) * 1e6 / rec.rate_hz));
    current.frame_number = static_cast<std::uint32_t>(g + 1);  // recordings number frames from 1
    current.component_count = 0;
    current.drop_rate_2d_permille = current.out_of_sync_rate_2d_permille = 0;
    current.labelled_p_qtm_mm.resize(row.size());
    current.unlabelled.clear();
    for (std::size_t i = 0; i < row.size(); ++i) current.labelled_p_qtm_mm[i] = row[i].cast<float>();
    for (const auto& d : script.drops)
      if (g >= d.from_frame && g < d.to_frame)
        for (std::size_t i = 0; i < rec.names.size(); ++i)
          if (rec.names[i] == d.marker || labels[i] == d.marker)
            current.labelled_p_qtm_mm[i].setConstant(std::numeric_limits<float>::quiet_NaN());
    have_frame = true;
  }

  void serve_frame(std::int64_t g) {
    for (const auto& r : script.renames)
      if (r.at_frame == g) {
        bool changed = false;
        for (std::string& l : labels)
          if (l == r.from) {
            l = r.to;
            changed = true;
          }
        // The labels changed: the playback restarts with them (events 9, 8),
        // and a client reads the new 3D parameters when it asks.
        if (changed)
          for (Client& c : clients) {
            send_event(c, Event::rt_from_file_stopped);
            send_event(c, Event::rt_from_file_started);
          }
      }
    build_frame(g);
    const double serve_hz = rec.rate_hz * script.rate_scale;
    bool sent_any = false;
    Clock::time_point send_start;
    for (Client& c : clients) {
      if (!c.streaming || c.closing || c.dead) continue;
      bool send = true;
      if (c.rate == Client::Rate::divisor) {
        send = c.counter++ % c.n == 0;
      } else if (c.rate == Client::Rate::frequency) {
        send = c.credit >= 1.0 - 1e-9;  // n / rate summed in binary: 10 x 0.1 is just below 1
        if (send) c.credit -= 1.0;
        c.credit += static_cast<double>(c.n) / serve_hz;
      }
      if (!send) continue;
      if (!sent_any) send_start = Clock::now();
      sent_any = true;
      send_frame(c, c.want_3d, c.want_3d_no_labels);
    }
    if (sent_any && options.on_frame_sent) options.on_frame_sent(current.frame_number, send_start);
    frames_served.store(static_cast<std::uint64_t>(g + 1));
  }

  void drop_dead() {
    for (auto it = clients.begin(); it != clients.end();) {
      if (it->closing && it->out.empty()) it->dead = true;
      it = it->dead ? clients.erase(it) : std::next(it);
    }
    client_count.store(static_cast<int>(clients.size()));
  }

  // Sends what is queued for up to `seconds`, then closes every client.
  void close_all(double seconds, const std::stop_token& stop) {
    const auto deadline = bridges::deadline_after(seconds);
    for (Client& c : clients) {
      while (!c.dead && !c.out.empty()) {
        if (bridges::wait_fd(c.fd.get(), POLLOUT, deadline, stop) != bridges::WaitResult::ready) break;
        flush(c);
      }
    }
    clients.clear();
    client_count.store(0);
  }

  void run(const std::stop_token& stop) {
    const double serve_hz = rec.rate_hz * script.rate_scale;
    const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / serve_hz));
    auto next_due = Clock::now();
    std::int64_t paused_at = -1, restarted_at = -1;  // each pause and restart once
    std::vector<pollfd> fds;
    while (!stop.stop_requested()) {
      // Frames that are due: a late loop catches up rather than drifts, a
      // burst at a time so that commands and new clients are still served.
      for (int burst = 0; burst < 64 && Clock::now() >= next_due; ++burst) {
        const std::int64_t g = next_index;
        if (script_over(g)) {
          ended = true;
          state = Event::rt_from_file_stopped;
          for (Client& c : clients) {
            if (c.streaming) send_no_more_data(c);
            send_event(c, Event::rt_from_file_stopped);
          }
          close_all(1.0, stop);
          return;
        }
        bool paused = false;
        for (const auto& p : script.pauses)
          if (p.at_frame == g && paused_at != g) {
            paused_at = g;
            next_due += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(p.seconds));
            paused = true;
          }
        if (paused) continue;
        bool restarted = false;
        for (const auto& r : script.restarts)
          if (r.at_frame == g && restarted_at != g) {
            restarted_at = g;
            for (Client& c : clients) send_event(c, Event::qtm_shutting_down);
            close_all(0.5, stop);
            listen_le.reset();
            listen_be.reset();
            const auto up = bridges::deadline_after(r.down_seconds);
            while (!stop.stop_requested() && Clock::now() < up)
              std::this_thread::sleep_for(std::min<Clock::duration>(bridges::kPollSlice, up - Clock::now()));
            if (!rebind(stop)) return;
            next_due = Clock::now();
            restarted = true;
          }
        if (restarted) continue;
        serve_frame(g);
        ++next_index;
        next_due += period;
      }
      drop_dead();
      fds.clear();
      fds.push_back({listen_le.get(), POLLIN, 0});
      fds.push_back({listen_be.get(), POLLIN, 0});
      for (Client& c : clients)
        fds.push_back({c.fd.get(), static_cast<short>(POLLIN | (c.out.empty() ? 0 : POLLOUT)), 0});
      const auto wait = std::clamp<Clock::duration>(next_due - Clock::now(), Clock::duration::zero(),
                                                     bridges::kPollSlice);
      const int ms = static_cast<int>(std::chrono::ceil<std::chrono::milliseconds>(wait).count());
      if (::poll(fds.data(), fds.size(), ms) < 0 && errno != EINTR) break;
      std::size_t i = 2;
      for (Client& c : clients) {
        const short ev = fds[i++].revents;
        if (ev & (POLLIN | POLLHUP | POLLERR)) read_client(c);
        if (ev & POLLOUT) flush(c);
      }
      if (fds[0].revents & POLLIN) accept_from(listen_le.get(), ByteOrder::little);
      if (fds[1].revents & POLLIN) accept_from(listen_be.get(), ByteOrder::big);
    }
    close_all(0.2, stop);
  }
};

QtmSimServer::QtmSimServer(bridges::SimRecording recording, bridges::SimScript script, Options options)
    : impl_(std::make_unique<Impl>()) {
  if (recording.names.empty() || recording.p_mm.empty())
    throw std::runtime_error("QTM simulator: the recording has no markers or no frames");
  for (const auto& row : recording.p_mm)
    if (row.size() != recording.names.size())
      throw std::runtime_error("QTM simulator: a frame of the recording has " + std::to_string(row.size()) +
                               " positions for " + std::to_string(recording.names.size()) + " names");
  if (!(recording.rate_hz > 0.0) || !(script.rate_scale > 0.0) || !std::isfinite(recording.rate_hz * script.rate_scale))
    throw std::runtime_error("QTM simulator: the rate and rate_scale must be positive");
  impl_->labels = recording.names;
  impl_->rec = std::move(recording);
  impl_->script = std::move(script);
  impl_->options = std::move(options);
  impl_->bind_ports();
}

QtmSimServer::~QtmSimServer() = default;

std::uint16_t QtmSimServer::port_little_endian() const { return impl_->port_le; }
std::uint16_t QtmSimServer::port_big_endian() const { return impl_->port_be; }

void QtmSimServer::run(std::stop_token stop) { impl_->run(stop); }

QtmSimServer::Progress QtmSimServer::progress() const {
  return {impl_->frames_served.load(), impl_->client_count.load()};
}

}  // namespace fabrik::qtm
