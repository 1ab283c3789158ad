#include "bridges/qtm/client.hpp"

#include <poll.h>

#include <array>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <vector>

#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "bridges/tcp.hpp"

namespace fabrik::qtm {

namespace {

using bridges::Clock;

// Versions we ask for, best first. 1.8 is the oldest whose 3D component we
// decode (32-bit floats, no padding: changelog 1.8).
constexpr std::array<ProtocolVersion, 2> kVersions{{{1, 19}, {1, 8}}};
constexpr ProtocolVersion kOldestDecoded{1, 8};
// A welcome packet is short; a Size field outside this range in either byte
// order is not a QTM packet header.
constexpr std::uint32_t kMaxWelcomeBytes = 4096;
constexpr std::size_t kMaxMarkers = 1u << 16;

std::string version_text(ProtocolVersion v) { return std::to_string(v.major) + "." + std::to_string(v.minor); }

std::string seconds_text(double s) {
  std::string t = std::to_string(s);
  return t.substr(0, t.find('.') + 2) + " s";
}

// Printable start of bytes a non-QTM peer sent, for the error text.
std::string printable(std::span<const std::uint8_t> bytes) {
  std::string s;
  for (std::size_t i = 0; i < bytes.size() && i < 24; ++i) {
    const char c = static_cast<char>(bytes[i]);
    s += (c >= 32 && c < 127) ? c : '.';
  }
  return s;
}

bool version_less(ProtocolVersion a, ProtocolVersion b) {
  return a.major != b.major ? a.major < b.major : a.minor < b.minor;
}

struct Failure {
  std::string what;
  bool bad_packet = false;
  bool stopped = false;
  bool timeout = false;  // nothing at all arrived before the deadline
};

// Events after which the 3D labels may differ (doc, "Events"): QTM connected
// to the cameras, a capture or RT from file started, camera settings changed.
bool relabels(Event e) {
  return e == Event::connected || e == Event::capture_started || e == Event::rt_from_file_started ||
         e == Event::camera_settings_changed;
}

// One connection, from connect to the failure that ends it.
class Session {
 public:
  Session(const QtmClientOptions& o, bridges::FrameSink& sink, bridges::SourceStatus& status,
          const std::stop_token& stop)
      : o_(o),
        sink_(sink),
        status_(status),
        stop_(stop),
        where_(bridges::host_port(o.host, o.port)) {}

  Failure run(bridges::Backoff& backoff) {
    std::string error;
    fd_ = bridges::connect_tcp(o_.host, o_.port, o_.policy.connect_timeout_s, stop_, error);
    if (stop_.stop_requested()) return stopped();
    if (!fd_.valid())
      return fail(
          "QTM at " + where_ + ": cannot connect (" + error + ")" +
          (error.starts_with("no host is named")
               ? std::string("; check the host's name in the source URL, or give its address")
           : error.starts_with("cannot resolve host")
               ? std::string("; the network's name service did not answer: check it, or give "
                             "the host's address")
               : std::string("; is QTM running with its RT server on? Its little-endian RT "
                             "port is base + 1, 22223 by default")));
    if (auto f = read_welcome()) return *f;
    if (auto f = negotiate_version()) return *f;
    if (auto f = check_byte_order()) return *f;
    if (auto f = request_labels()) return *f;
    if (auto f = await_labels(bridges::deadline_after(o_.policy.reply_timeout_s))) return *f;
    const StreamRate rate{static_cast<std::uint32_t>(std::max(1, o_.frequency_divisor))};
    if (auto f = send_command(stream_frames_command(rate, Components::labelled_3d))) return *f;
    status_.connected("QTM RT protocol " + version_text(version_));
    connected_ = true;
    backoff.reset();
    return stream();
  }

  bool connected() const { return connected_; }

 private:
  Failure fail(std::string what, bool bad = false) const { return Failure{std::move(what), bad, false}; }
  Failure stopped() const { return Failure{"stopped", false, true}; }

  // Reads bytes into the splitter (or the raw pre-welcome buffer) until the
  // deadline. nullopt when bytes arrived.
  std::optional<Failure> read_more(Clock::time_point deadline, std::string_view expecting) {
    const auto w = bridges::wait_fd(fd_.get(), POLLIN, deadline, stop_);
    if (w == bridges::WaitResult::stopped) return stopped();
    if (w == bridges::WaitResult::failed) return fail("QTM at " + where_ + ": poll failed");
    if (w == bridges::WaitResult::timeout) {
      const std::size_t partial = splitter_ ? splitter_->buffered_bytes() : raw_.size();
      if (partial > 0)
        return fail("QTM at " + where_ + ": stalled mid-packet (" + std::to_string(partial) +
                    " bytes of a packet, then nothing) while waiting for " + std::string(expecting));
      Failure f = fail("QTM at " + where_ + ": no " + std::string(expecting) + " within " +
                       seconds_text(timeout_of_wait_));
      f.timeout = true;
      return f;
    }
    const long n = bridges::read_some(fd_.get(), rx_);
    if (n == -1) return std::nullopt;
    if (n <= 0) {
      const std::size_t partial = splitter_ ? splitter_->buffered_bytes() : raw_.size();
      return fail("QTM at " + where_ + (n == 0 ? ": the server closed the connection" : ": connection lost") +
                  (partial > 0 ? " in the middle of a packet (truncated)" : "") + " while waiting for " +
                  std::string(expecting));
    }
    const std::span<const std::uint8_t> got(rx_.data(), static_cast<std::size_t>(n));
    if (splitter_)
      splitter_->feed(got);
    else
      raw_.insert(raw_.end(), got.begin(), got.end());
    return std::nullopt;
  }

  // The next whole packet before the deadline; a mid-packet stall is bounded
  // by reply_timeout_s from the first byte of that packet.
  std::optional<Failure> next_packet(PacketView& out, Clock::time_point deadline, std::string_view expecting) {
    for (;;) {
      const Status s = splitter_->next(out);
      if (s == Status::ok) {
        partial_since_.reset();
        if (!out.type())
          return fail("QTM at " + where_ + ": packet type " + std::to_string(out.raw_type) +
                          " is not in the RT protocol (not a QTM server, or a corrupt stream)",
                      true);
        return std::nullopt;
      }
      if (s != Status::need_more)
        return fail("QTM at " + where_ + ": " + to_string(s) + " (" +
                        std::to_string(o_.policy.max_packet_bytes) +
                        " bytes; no QTM packet is that large: a corrupt stream, or not a QTM server)",
                    true);
      auto until = deadline;
      if (splitter_->buffered_bytes() > 0) {
        if (!partial_since_) partial_since_ = Clock::now();
        until = std::min(until, *partial_since_ + std::chrono::duration_cast<Clock::duration>(
                                                      std::chrono::duration<double>(o_.policy.reply_timeout_s)));
      }
      if (auto f = read_more(until, expecting)) return f;
    }
  }

  std::optional<Failure> send_command(const std::string& command) {
    write_command_packet(command, order_, tx_);
    std::string error;
    if (!bridges::send_all(fd_.get(), tx_, bridges::deadline_after(o_.policy.reply_timeout_s), stop_, error))
      return stop_.stop_requested() ? stopped() : fail("QTM at " + where_ + ": sending '" + command + "': " + error);
    return std::nullopt;
  }

  // The welcome packet; its Size field also tells the byte order the server
  // chose for this port (the header is the first thing it writes).
  std::optional<Failure> read_welcome() {
    timeout_of_wait_ = o_.policy.connect_timeout_s;
    const auto deadline = bridges::deadline_after(o_.policy.connect_timeout_s);
    while (raw_.size() < kHeaderBytes)
      if (auto f = read_more(deadline, "welcome message (is this a QTM RT port?)")) return f;
    auto size_in = [&](ByteOrder order) {
      ByteReader r(raw_, order);
      return r.u32();
    };
    const std::uint32_t little = size_in(ByteOrder::little), big = size_in(ByteOrder::big);
    const bool little_ok = little >= kHeaderBytes && little <= kMaxWelcomeBytes;
    const bool big_ok = big >= kHeaderBytes && big <= kMaxWelcomeBytes;
    if (!little_ok && !big_ok)
      return fail("QTM at " + where_ + ": not a QTM RT server (first bytes \"" + printable(raw_) +
                      "\" are no packet header); QTM's little-endian RT port is base + 1, 22223 by default",
                  true);
    order_ = little_ok ? ByteOrder::little : ByteOrder::big;
    splitter_.emplace(order_, o_.policy.max_packet_bytes);
    splitter_->feed(raw_);
    raw_.clear();
    PacketView p;
    if (auto f = next_packet(p, deadline, "welcome message")) return f;
    std::string_view text;
    if (p.type() == PacketType::error && read_string(p, PacketType::error, text) == Status::ok)
      return fail("QTM at " + where_ + " refused the connection: \"" + std::string(text) + "\"");
    if (read_string(p, PacketType::command, text) != Status::ok || !is_welcome(text))
      return fail("QTM at " + where_ + ": the first packet is not QTM's welcome message (a " +
                      to_string(*p.type()) + " packet); is this a QTM RT port?",
                  true);
    return std::nullopt;
  }

  // The reply to a command: a command/XML string or an error string. Events
  // are skipped (a shutdown ends the session); data is not expected yet.
  std::optional<Failure> reply(std::string_view command, PacketType& type, std::string& text) {
    timeout_of_wait_ = o_.policy.reply_timeout_s;
    const auto deadline = bridges::deadline_after(o_.policy.reply_timeout_s);
    const std::string expecting = "reply to '" + std::string(command) + "'";
    for (;;) {
      PacketView p;
      if (auto f = next_packet(p, deadline, expecting)) return f;
      type = *p.type();
      if (type == PacketType::event) {
        if (auto f = on_event(p)) return f;
        continue;
      }
      if (type == PacketType::no_more_data || type == PacketType::data) continue;
      std::string_view s;
      if (type != PacketType::error && type != PacketType::command && type != PacketType::xml)
        return fail("QTM at " + where_ + ": a " + std::string(to_string(type)) + " packet as " + expecting, true);
      if (const Status st = read_string(p, type, s); st != Status::ok)
        return fail("QTM at " + where_ + ": " + expecting + ": " + to_string(st), true);
      text.assign(s);
      return std::nullopt;
    }
  }

  std::optional<Failure> negotiate_version() {
    std::string refused;
    for (const ProtocolVersion v : kVersions) {
      const std::string command = version_command(v);
      if (auto f = send_command(command)) return f;
      PacketType type;
      std::string text;
      if (auto f = reply(command, type, text)) return f;
      if (type == PacketType::error) {
        refused += (refused.empty() ? "" : ", ") + version_text(v);
        continue;
      }
      const auto got = parse_version_reply(text);
      if (!got)
        return fail("QTM at " + where_ + ": unexpected reply to '" + command + "': \"" + text + "\"", true);
      if (got->major != 1 || version_less(*got, kOldestDecoded))
        return fail("QTM at " + where_ + " speaks RT protocol " + version_text(*got) +
                    "; fabrikd decodes 1.8 and later: update QTM");
      version_ = *got;
      return std::nullopt;
    }
    return fail("QTM at " + where_ + " refused RT protocol versions " + refused +
                " (\"Version NOT supported\"); fabrikd decodes 1.8 and later: update QTM (2.8 or newer)");
  }

  std::optional<Failure> check_byte_order() {
    const std::string command = byte_order_command();
    if (auto f = send_command(command)) return f;
    PacketType type;
    std::string text;
    if (auto f = reply(command, type, text)) return f;
    const auto order = parse_byte_order_reply(text);
    if (type != PacketType::command || !order)
      return fail("QTM at " + where_ + ": unexpected reply to 'ByteOrder': \"" + text + "\"", true);
    if (*order != order_)
      return fail("QTM at " + where_ + " says its byte order is other than its packets' (\"" + text + "\")", true);
    return std::nullopt;
  }

  std::optional<Failure> request_labels() {
    ++labels_pending_;
    labels_asked_ = Clock::now();
    return send_command(get_parameters_3d_command());
  }

  // An XML or error reply to GetParameters 3D.
  std::optional<Failure> on_parameters(PacketType type, std::string_view text) {
    --labels_pending_;
    if (type == PacketType::error)
      return fail("QTM at " + where_ + " has no 3D parameters (\"" + std::string(text) +
                  "\"); open a measurement or start RT in QTM");
    if (type != PacketType::xml)
      return fail("QTM at " + where_ + ": unexpected reply to 'GetParameters 3D': \"" + std::string(text) + "\"",
                  true);
    Parameters3d params;
    std::string error;
    if (!read_parameters_3d(text, params, error))
      return fail("QTM at " + where_ + ": 3D parameters refused: " + error, true);
    if (labels_pending_ == 0) {
      labels_ = std::move(params.labels);
      if (!params.axis_upwards.empty()) sink_.up_axis(params.axis_upwards);
      sink_.labels(labels_);
      labels_fresh_ = true;
    }
    return std::nullopt;
  }

  std::optional<Failure> await_labels(Clock::time_point deadline) {
    while (labels_pending_ > 0) {
      PacketType type;
      std::string text;
      if (auto f = reply(get_parameters_3d_command(), type, text)) return f;
      if (auto f = on_parameters(type, text)) return f;
      if (Clock::now() > deadline) return fail("QTM at " + where_ + ": no 3D parameters");
    }
    return std::nullopt;
  }

  std::optional<Failure> on_event(const PacketView& p) {
    Event e;
    if (read_event(p, e) != Status::ok) return fail("QTM at " + where_ + ": malformed event packet", true);
    if (e == Event::qtm_shutting_down) return fail("QTM at " + where_ + " is shutting down (event 12)");
    if (relabels(e) && connected_ && labels_pending_ == 0) return request_labels();
    return std::nullopt;
  }

  std::optional<Failure> on_data(const PacketView& p) {
    if (const Status s = read_data(p, order_, kMaxMarkers, frame_); s != Status::ok)
      return fail("QTM at " + where_ + ": data packet refused: " + to_string(s), true);
    if (!frame_.has_3d) return std::nullopt;
    last_frame_ = Clock::now();
    if (labels_pending_ > 0) return std::nullopt;  // labels are changing: drop until they are known
    const auto& p_mm = frame_.labelled_p_qtm_mm;
    if (p_mm.size() != labels_.size()) {
      // Labels read since the last frame and still another count: the server
      // contradicts itself. Else a change we were not told of: read them again.
      if (labels_fresh_)
        return fail("QTM at " + where_ + ": the 3D component has " + std::to_string(p_mm.size()) +
                        " markers but the 3D parameters " + std::to_string(labels_.size()) + " labels",
                    true);
      return request_labels();
    }
    labels_fresh_ = false;
    p_server_mm_.resize(p_mm.size());
    for (std::size_t i = 0; i < p_mm.size(); ++i) p_server_mm_[i] = p_mm[i].cast<double>();
    status_.frame_delivered();  // first: a stats message must not show fewer frames than poses
    sink_.frame(frame_.frame_number, static_cast<double>(frame_.timestamp_us) * 1e-6, p_server_mm_);
    saw_no_more_data_ = false;
    return std::nullopt;
  }

  Failure stream() {
    last_frame_ = Clock::now();
    const auto stall = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(o_.policy.stall_timeout_s));
    const auto reply_wait = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(o_.policy.reply_timeout_s));
    for (;;) {
      auto deadline = last_frame_ + stall;
      if (labels_pending_ > 0) deadline = std::min(deadline, labels_asked_ + reply_wait);
      PacketView p;
      if (auto f = next_packet(p, deadline, "frame")) {
        if (!f->timeout) return *f;
        if (labels_pending_ > 0 && labels_asked_ + reply_wait < last_frame_ + stall)
          return fail("QTM at " + where_ + ": no reply to 'GetParameters 3D' within " +
                      seconds_text(o_.policy.reply_timeout_s));
        return fail("QTM at " + where_ + ": no frame for " + seconds_text(o_.policy.stall_timeout_s) +
                    (saw_no_more_data_ ? " (QTM says no measurement is running: start one, or RT from file)"
                                       : " (stream stalled)"));
      }
      std::optional<Failure> f;
      std::string_view text;
      switch (*p.type()) {
        case PacketType::data: f = on_data(p); break;
        case PacketType::event: f = on_event(p); break;
        case PacketType::no_more_data: saw_no_more_data_ = true; break;
        case PacketType::xml:
        case PacketType::error:
          if (read_string(p, *p.type(), text) != Status::ok) {
            f = fail("QTM at " + where_ + ": malformed string packet", true);
          } else if (labels_pending_ > 0) {
            f = on_parameters(*p.type(), text);
          } else if (p.type() == PacketType::error) {
            f = fail("QTM at " + where_ + " sent an error while streaming: \"" + std::string(text) + "\"");
          }
          break;
        default: break;  // command strings, files, discover: not for us
      }
      if (f) return *f;
    }
  }

  const QtmClientOptions& o_;
  bridges::FrameSink& sink_;
  bridges::SourceStatus& status_;
  const std::stop_token& stop_;
  const std::string where_;

  bridges::Fd fd_;
  ByteOrder order_ = ByteOrder::little;
  ProtocolVersion version_;
  std::optional<PacketSplitter> splitter_;
  std::vector<std::uint8_t> raw_;
  std::array<std::uint8_t, 1 << 16> rx_{};
  std::vector<std::uint8_t> tx_;
  std::optional<Clock::time_point> partial_since_;
  double timeout_of_wait_ = 0.0;

  std::vector<std::string> labels_;
  int labels_pending_ = 0;
  bool labels_fresh_ = false;
  Clock::time_point labels_asked_, last_frame_;
  DataFrame frame_;
  std::vector<Eigen::Vector3d> p_server_mm_;
  bool connected_ = false;
  bool saw_no_more_data_ = false;
};

// Sleeps for `seconds` unless stop is requested first.
void wait_or_stop(double seconds, const std::stop_token& stop) {
  std::mutex m;
  std::condition_variable_any cv;
  std::unique_lock lock(m);
  cv.wait_for(lock, stop, std::chrono::duration<double>(seconds), [] { return false; });
}

}  // namespace

void run_qtm_client(const QtmClientOptions& options, bridges::FrameSink& sink, bridges::SourceStatus& status,
                    std::stop_token stop) {
  bridges::Backoff backoff(options.policy);
  while (!stop.stop_requested()) {
    Failure failure;
    bool was_connected = false;
    try {
      auto session = std::make_unique<Session>(options, sink, status, stop);
      failure = session->run(backoff);
      was_connected = session->connected();
    } catch (const std::exception& e) {
      failure = Failure{std::string("QTM client: internal error: ") + e.what(), false, false};
    } catch (...) {
      failure = Failure{"QTM client: internal error", false, false};
    }
    const bool stopping = failure.stopped || stop.stop_requested();
    if (!stopping && failure.bad_packet)
      status.bad_packet(failure.what);
    else if (!stopping)
      status.error(failure.what);
    // After the error: whoever sees the connection lost also sees why
    // (fabrikd logs "connection lost: <last_error>" on that change).
    if (was_connected) status.disconnected();
    if (stopping) break;
    wait_or_stop(backoff.next_wait_s(), stop);
  }
}

}  // namespace fabrik::qtm
