#include "daemon.hpp"

#include <spdlog/spdlog.h>

#include <cerrno>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace fabrik::wire {

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kMaxBatch =
    4096;  // messages drained per wake-up: bounds the time before a pose goes out
constexpr std::size_t kMaxUnknownLogged = 256;

double us_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

zmq::socket_t open_socket(zmq::context_t& context, zmq::socket_type type, const Endpoint& e,
                          const char* role) {
  zmq::socket_t s(context, type);
  s.set(zmq::sockopt::linger, 0);
  if (type == zmq::socket_type::sub) s.set(zmq::sockopt::subscribe, "markers");
  try {
    if (e.mode == SocketMode::bind)
      s.bind(e.address);
    else
      s.connect(e.address);
  } catch (const zmq::error_t& err) {
    throw std::runtime_error(
        std::string("cannot ") + (e.mode == SocketMode::bind ? "bind" : "connect") + " the " +
        role + " socket to '" + e.address + "': " + err.what() +
        (err.num() == EADDRINUSE
             ? " (another fabrikd running? choose another port with --" + std::string(role) + ")"
             : ""));
  }
  return s;
}

}  // namespace

struct Daemon::State {
  DaemonConfig config;
  zmq::socket_t sub, pub;
  std::unique_ptr<Tracker> tracker;
  std::unique_ptr<MarkerDecoder> decoder;
  std::unique_ptr<PoseEncoder> encoder;
  // Valid frames waiting to be solved, oldest first, in a ring with one
  // slot more than the backlog limit: the spare one is decoded into.
  std::vector<MarkerFrame> ring;
  std::vector<Clock::time_point> received_at;
};

std::unique_ptr<Daemon::State> Daemon::make_state(DaemonConfig config, State* old) {
  auto s = std::make_unique<State>();
  s->tracker = std::make_unique<Tracker>(config.tracker);
  std::vector<std::string> names;
  for (const MarkerTarget& m : config.tracker.markers) names.push_back(m.marker);
  s->decoder =
      std::make_unique<MarkerDecoder>(names, config.input_m_per_unit, config.max_payload_bytes);
  s->encoder = std::make_unique<PoseEncoder>(*s->tracker, config.output_units,
                                             config.output_encoding == Encoding::msgpack
                                                 ? PayloadEncoding::msgpack
                                                 : PayloadEncoding::json);
  s->ring.resize(config.max_backlog_frames + 1);
  for (MarkerFrame& f : s->ring) f = s->decoder->make_frame();
  s->received_at.resize(s->ring.size());
  // Sockets are reopened only when their endpoint changed, so a reload of
  // the solver settings does not disturb connected clients. New sockets are
  // opened before old ones are taken over: if one fails, the old state is whole.
  auto same = [](const Endpoint& a, const Endpoint& b) {
    return a.address == b.address && a.mode == b.mode;
  };
  const bool keep_sub = old && same(old->config.input, config.input);
  const bool keep_pub = old && same(old->config.output, config.output);
  if (!keep_sub) s->sub = open_socket(context_, zmq::socket_type::sub, config.input, "input");
  if (!keep_pub) s->pub = open_socket(context_, zmq::socket_type::pub, config.output, "output");
  if (keep_sub) s->sub = std::move(old->sub);
  if (keep_pub) s->pub = std::move(old->pub);
  s->config = std::move(config);
  return s;
}

Daemon::Daemon(zmq::context_t& context, DaemonConfig config)
    : context_(context), started_(Clock::now()) {
  state_ = make_state(std::move(config), nullptr);
  out_.reserve(1 << 16);
}

Daemon::~Daemon() = default;

const DaemonConfig& Daemon::config() const {
  return state_->config;
}

std::string Daemon::input_endpoint() const {
  return state_->sub.get(zmq::sockopt::last_endpoint);
}
std::string Daemon::output_endpoint() const {
  return state_->pub.get(zmq::sockopt::last_endpoint);
}

DaemonCounters Daemon::counters() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

void Daemon::send(const char* topic, const std::string& payload) {
  // dontwait: PUB never blocks, but be explicit; a failed send is logged, never fatal.
  try {
    State& s = *state_;
    s.pub.send(zmq::buffer(std::string_view(topic)),
               zmq::send_flags::sndmore | zmq::send_flags::dontwait);
    s.pub.send(zmq::buffer(payload), zmq::send_flags::dontwait);
  } catch (const zmq::error_t& e) {
    send_log_.warn("could not publish {}: {}", topic, e.what());
  }
}

void Daemon::drain_and_solve() {
  State& s = *state_;
  const int ring_size = static_cast<int>(s.ring.size());
  const int backlog_limit = ring_size - 1;
  int first = 0, count = 0;  // the valid frames: ring[first, first + count)
  std::string error;
  for (int n = 0; n < kMaxBatch; ++n) {
    if (!s.sub.recv(parts_[0], zmq::recv_flags::dontwait)) break;
    const Clock::time_point received = Clock::now();
    ++counters_.frames_in;
    int parts = 1;
    for (bool more = parts_[0].more(); more; ++parts) {
      zmq::message_t& m = parts == 1 ? parts_[1] : extra_;
      if (!s.sub.recv(m, zmq::recv_flags::dontwait)) break;  // parts arrive together
      more = m.more();
    }
    if (parts != 2) {
      ++counters_.decode_errors;
      last_error_ = "expected 2 message frames [topic, payload], got " + std::to_string(parts);
      bad_input_log_.warn("bad input: {}", last_error_);
      continue;
    }
    if (parts_[0].to_string_view() != "markers") {
      ++counters_.decode_errors;
      last_error_ = "unknown topic '" + std::string(parts_[0].to_string_view().substr(0, 64)) + "'";
      bad_input_log_.warn("bad input: {}", last_error_);
      continue;
    }
    const int slot = (first + count) % ring_size;
    MarkerFrame& f = s.ring[slot];
    const std::span<const std::uint8_t> payload(static_cast<const std::uint8_t*>(parts_[1].data()),
                                                parts_[1].size());
    if (!s.decoder->decode(payload, f, error)) {
      ++counters_.decode_errors;
      last_error_ = error;
      bad_input_log_.warn("bad marker frame: {}", error);
      continue;
    }
    if (f.unknown_count > 0) {
      counters_.unknown_markers += static_cast<std::uint64_t>(f.unknown_count);
      for (int k = 0; k < f.unknown_listed; ++k) {
        const std::string& name = f.unknown_names[k];
        // Look up first: only a name not seen before costs an allocation.
        if (unknown_seen_.size() < kMaxUnknownLogged && !unknown_seen_.contains(name)) {
          unknown_seen_.insert(name);
          spdlog::warn("marker '{}' is not in the model: ignored (reported once)", name);
        }
      }
    }
    s.received_at[slot] = received;
    if (count == backlog_limit) {
      first = (first + 1) % ring_size;  // the oldest waiting frame gives way
      ++counters_.frames_dropped;
    } else {
      ++count;
    }
  }
  for (int k = 0; k < count; ++k) {
    const int slot = (first + k) % ring_size;
    const MarkerFrame& f = s.ring[slot];
    const double time_s =
        f.has_time ? f.time_s
                   : std::chrono::duration<double>(s.received_at[slot] - started_).count();
    const TrackResult& r = s.tracker->track(time_s, f.p_world_m, f.visible);
    s.encoder->encode({f.frame, f.has_time, f.time_s, f.has_stamp, f.stamp_us}, r, out_);
    ++counters_.frames_out;
    ++interval_frames_out_;
    {
      // Counters first, so whoever has seen a pose sees the counts that include it.
      std::lock_guard lock(snapshot_mutex_);
      snapshot_ = counters_;
    }
    send("pose", out_);
    solve_us_.add(r.solve_us);
    queue_us_.add(us_between(s.received_at[slot], Clock::now()));
  }
  std::lock_guard lock(snapshot_mutex_);
  snapshot_ = counters_;
}

void Daemon::publish_stats(double interval_s) {
  const DaemonConfig& c = state_->config;
  nlohmann::json j = {
      {"uptime_s", std::chrono::duration<double>(Clock::now() - started_).count()},
      {"frames_in", counters_.frames_in},
      {"frames_out", counters_.frames_out},
      {"frames_dropped", counters_.frames_dropped},
      {"decode_errors", counters_.decode_errors},
      {"unknown_markers", counters_.unknown_markers},
      {"solve_us",
       {{"p50", solve_us_.quantile(0.5)},
        {"p99", solve_us_.quantile(0.99)},
        {"max", solve_us_.max()}}},
      {"queue_latency_us",
       {{"p50", queue_us_.quantile(0.5)},
        {"p99", queue_us_.quantile(0.99)},
        {"max", queue_us_.max()}}},
      // Additions to the contract's minimum:
      {"interval_s", interval_s},
      {"pose_rate_hz",
       interval_s > 0 ? static_cast<double>(interval_frames_out_) / interval_s : 0.0},
      {"last_error", last_error_.empty() ? nlohmann::json(nullptr) : nlohmann::json(last_error_)},
      {"reloads", counters_.reloads},
      {"reload_errors", counters_.reload_errors},
      {"config", c.file}};
  solve_us_.clear();
  queue_us_.clear();
  interval_frames_out_ = 0;
  if (c.output_encoding == Encoding::msgpack) {
    const std::vector<std::uint8_t> bytes = nlohmann::json::to_msgpack(j);
    send("stats", std::string(bytes.begin(), bytes.end()));
  } else {
    send("stats", j.dump());
  }
}

void Daemon::run(DaemonControl& control, const std::function<DaemonConfig()>& load_config) {
  spdlog::info("fabrikd: markers in on {} ({}), poses out on {} ({}), {} markers tracked",
               input_endpoint(), state_->config.input.mode == SocketMode::bind ? "bind" : "connect",
               output_endpoint(),
               state_->config.output.mode == SocketMode::bind ? "bind" : "connect",
               state_->tracker->marker_count());
  Clock::time_point last_stats = Clock::now();
  while (!control.stop.load()) {
    if (control.reload.exchange(false)) {
      if (!load_config) {
        spdlog::warn("reload requested, but there is no config to reload from");
      } else {
        try {
          state_ = make_state(load_config(), state_.get());
          ++counters_.reloads;
          spdlog::info("config reloaded from {}", state_->config.file);
        } catch (const std::exception& e) {
          ++counters_.reload_errors;
          spdlog::error("reload failed, keeping the running config: {}", e.what());
        }
      }
    }
    const auto interval = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(state_->config.stats_interval_s));
    const auto next_stats = last_stats + interval;
    // Wake at least every 100 ms so a stop request is seen promptly.
    const auto wait =
        std::clamp(std::chrono::duration_cast<std::chrono::milliseconds>(next_stats - Clock::now()),
                   std::chrono::milliseconds(0), std::chrono::milliseconds(100));
    zmq::pollitem_t items[] = {{state_->sub.handle(), 0, ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 1, wait);
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) throw;
      continue;  // a signal: look at the flags
    }
    if (items[0].revents & ZMQ_POLLIN) drain_and_solve();
    const Clock::time_point now = Clock::now();
    if (now >= next_stats) {
      publish_stats(std::chrono::duration<double>(now - last_stats).count());
      last_stats = now;
    }
  }
  spdlog::info("fabrikd: stopping after {} frames in, {} poses out", counters_.frames_in,
               counters_.frames_out);
}

}  // namespace fabrik::wire
