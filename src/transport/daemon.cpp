#include "daemon.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <type_traits>

#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "common/ascii_case.hpp"
#include "config/closest_names.hpp"
#include "config/config_error.hpp"
#include "config/endpoint_check.hpp"
#include "model_codec.hpp"
#include "open_socket.hpp"
#include "session_revival.hpp"
#include "socket_monitor.hpp"
#include "socket_options.hpp"
#include "subscription_book.hpp"
#include "wire_writer.hpp"

namespace fabrik::wire {

namespace {

using Clock = std::chrono::steady_clock;
// Messages taken off the input per wake-up, and the time spent serving them,
// at most: stats, reloads and a stop request are looked at in between.
constexpr int kMaxBatch = 4096;
constexpr auto kMaxServe = std::chrono::milliseconds(20);
constexpr std::size_t kMaxUnknownLogged = 256;
// How long a start or reload waits to learn whether a connected endpoint's host exists (a
// resolver that does not answer would hold the start for its own timeout, seconds).
constexpr std::chrono::milliseconds kHostLookupWait{500};
// How long a stop waits for a reload being read before leaving it behind:
// short, so that a stop is honoured within 100 ms at any moment.
constexpr auto kReloadGraceAtStop = std::chrono::milliseconds(20);

double us_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

std::string_view view(const zmq::message_t& m) {
  return {static_cast<const char*>(m.data()), m.size()};
}

// The input (a SUB) or the output (an XPUB), with its options, not yet bound
// or connected: a monitor must be watching before the socket connects, or the
// events of a session ZeroMQ gives up at once can be missed (session_revival.hpp).
zmq::socket_t make_socket(zmq::context_t& context, zmq::socket_type type, const DaemonConfig& c) {
  zmq::socket_t s(context, type);
  if (type == zmq::socket_type::sub)
    set_input_options(s, c);
  else
    set_output_options(s, c);
  return s;
}

// Binds or connects `s`, made by make_socket.
void open_endpoint(zmq::socket_t& s, zmq::socket_type type, const DaemonConfig& c) {
  const bool input = type == zmq::socket_type::sub;
  const Endpoint& e = input ? c.input : c.output;
  const std::string role = input ? "input" : "output";
  const std::string connect =
      e.option.empty() ? "use \"mode\": \"connect\"" : "write connect: before it";
  // A taken port is most often a second fabrikd; where the holder is the program to reach (a
  // source or recorder that binds), connecting is the fix: to an address, not a wildcard.
  const std::string wildcard =
      binds_any_address(e.address) ? ", with its host's address for the wildcard" : "";
  const OpenAdvice advice{"the " + role + " socket", "here or with --" + role, connect,
                          std::string(input ? "if the program that sends the markers binds it"
                                            : "if the program that takes the poses binds it") +
                              ", connect to it: " + connect + wildcard};
  const auto failure = open_socket(s, e.address, e.mode, advice);
  if (!failure) return;
  if (!e.option.empty())  // given on the command line: not the config file's fault
    throw std::invalid_argument(failure->message(e.option));
  throw ConfigError(c.file, "/" + role + "/endpoint", failure->problem, failure->fix);
}

// Whether every number of a result can be written: a pose never carries
// NaN, infinity or null where the schema wants a number.
bool all_finite(const TrackResult& r) {
  if (!std::isfinite(r.residual_rms_m) || !std::isfinite(r.residual_max_m) ||
      !std::isfinite(r.solve_us))
    return false;
  for (const Eigen::Vector3d& p : r.joints_world_m)
    if (!p.allFinite()) return false;
  for (const Eigen::Vector3d& p : r.markers_world_m)
    if (!p.allFinite()) return false;
  return true;
}

// What a stats payload carries (proto/stats.schema.json).
struct StatsFields {
  double uptime_s, interval_s, pose_rate_hz;
  const DaemonCounters& c;
  IntervalSamples &solve_us, &queue_us;
  StageSamples& stages_us;
  std::string_view last_error, config;  // both already safe (safe_text)
  const SourceInput* source = nullptr;  // null: the config names no source
  // Multi-subject configs: writes stats.subjects (a map) when set.
  std::function<void(JsonWriter&)> subjects_json;
  std::function<void(MsgpackWriter&)> subjects_msgpack;
  // Pose views (output.views): writes stats.views (a map by topic) when set.
  std::function<void(JsonWriter&)> views_json;
  std::function<void(MsgpackWriter&)> views_msgpack;
};

// stats.source (proto/stats.schema.json): the vendor server's connection.
template <class Writer>
void write_source_stats(Writer& w, const SourceInput& source) {
  const SourceInput::Status st = source.status();
  const bridges::SourceStatus::Snapshot& c = st.connection;
  const auto count = [&](const char* key, std::uint64_t v) {
    w.key(key);
    w.uint(v);
  };
  const auto text_or_null = [&](const char* key, const std::string& text) {
    w.key(key);
    if (text.empty())
      w.null();
    else
      w.string(safe_text(text, 240));
  };
  w.begin_map(10);
  w.key("url");
  w.string(safe_text(source.config().url, 240));
  w.key("connected");
  w.boolean(c.connected);
  text_or_null("server", c.server);
  count("connections", c.connections);
  count("reconnects", c.reconnects);
  count("errors", c.errors);
  count("bad_packets", c.bad_packets);
  count("frames", c.frames);
  count("frames_dropped", st.frames_dropped);
  text_or_null("last_error", c.last_error);
  w.end_map();
}

template <class Writer>
void write_stats(Writer& w, const StatsFields& s) {
  const auto count = [&](const char* key, std::uint64_t v) {
    w.key(key);
    w.uint(v);
  };
  const auto quantiles = [&](const char* key, IntervalSamples& q) {
    w.key(key);
    w.begin_map(3);
    w.key("p50");
    w.number(q.quantile(0.5), 2);
    w.key("p99");
    w.number(q.quantile(0.99), 2);
    w.key("max");
    w.number(q.max(), 2);
    w.end_map();
  };
  constexpr bool is_json = std::is_same_v<Writer, JsonWriter>;
  const bool subjects = is_json ? bool(s.subjects_json) : bool(s.subjects_msgpack);
  const bool views = is_json ? bool(s.views_json) : bool(s.views_msgpack);
  // MessagePack needs the exact count of the keys below
  w.begin_map(31 + (s.source ? 1 : 0) + (subjects ? 2 : 0) + (views ? 1 : 0));
  w.key("uptime_s");
  w.number(s.uptime_s, 3);
  count("frames_in", s.c.frames_in);
  count("frames_out", s.c.frames_out);
  count("frames_dropped", s.c.frames_dropped);
  count("decode_errors", s.c.decode_errors);
  count("unknown_markers", s.c.unknown_markers);
  quantiles("solve_us", s.solve_us);
  quantiles("queue_latency_us", s.queue_us);
  // Additions to the contract's minimum:
  w.key("interval_s");
  w.number(s.interval_s, 6);
  w.key("pose_rate_hz");
  w.number(s.pose_rate_hz, 3);
  w.key("last_error");
  if (s.last_error.empty())
    w.null();
  else
    w.string(s.last_error);
  count("reloads", s.c.reloads);
  count("reload_errors", s.c.reload_errors);
  w.key("config");
  w.string(s.config);
  count("rejected_coordinates", s.c.rejected_coordinates);
  count("zero_markers", s.c.zero_markers);
  count("internal_errors", s.c.internal_errors);
  count("input_disconnects", s.c.input_disconnects);
  count("accept_failures", s.c.accept_failures);
  count("rejected_orientations", s.c.rejected_orientations);
  count("unknown_sensors", s.c.unknown_sensors);
  count("unmatched_frames", s.c.unmatched_frames);
  w.key("config_mismatch");
  w.boolean(s.c.config_mismatch);
  count("outliers", s.c.outliers);
  count("poor_frames", s.c.poor_frames);
  count("subscriptions_refused", s.c.subscriptions_refused);
  count("unsubscriptions_ignored", s.c.unsubscriptions_ignored);
  count("output_reconnects", s.c.output_reconnects);
  count("input_reconnects", s.c.input_reconnects);
  count("pose_subscribers", s.c.pose_subscribers);
  w.key("stages_us");
  w.begin_map(kStageNames.size());
  for (std::size_t k = 0; k < kStageNames.size(); ++k) quantiles(kStageNames[k], s.stages_us[k]);
  w.end_map();
  if (s.source) {
    w.key("source");
    write_source_stats(w, *s.source);
  }
  if (subjects) {
    count("other_subject_frames", s.c.other_subject_frames);
    w.key("subjects");
    if constexpr (is_json)
      s.subjects_json(w);
    else
      s.subjects_msgpack(w);
  }
  if (views) {
    w.key("views");
    if constexpr (is_json)
      s.views_json(w);
    else
      s.views_msgpack(w);
  }
  w.end_map();
}

}  // namespace

bool subscribes_to_our_topics(std::string_view prefix) {
  return std::any_of(std::begin(kPublishedTopics), std::end(kPublishedTopics),
                     [&](std::string_view topic) { return topic.starts_with(prefix); });
}

bool subscribes_to_our_topics(std::string_view prefix, std::span<const std::string> extra_topics) {
  return subscribes_to_our_topics(prefix) ||
         std::any_of(extra_topics.begin(), extra_topics.end(),
                     [&](const std::string& topic) { return topic.starts_with(prefix); });
}

// One pose view (output.views) of one tracker: its topic (TOPIC/NAME for a
// subject's), its encoder, the live subscriptions that select it (it is
// encoded only while there are some) and the poses it has sent.
struct Daemon::ViewState {
  std::string topic;
  std::unique_ptr<PoseEncoder> encoder;
  int subscribers = 0;
  std::uint64_t frames_out = 0;
};

// One subject of a multi-subject config: its tracker, its pose encoder, its
// slice of the combined frame (names NAME:Marker) and a decoder of its bare
// names (frames with "subject"), and whether it is present.
struct Daemon::SubjectState {
  std::string name, pose_topic, model_topic, model_out;
  std::unique_ptr<Tracker> tracker;
  std::unique_ptr<PoseEncoder> encoder;
  std::unique_ptr<MarkerDecoder> decoder;
  std::vector<ViewState> views;
  int pose_subscribers = 0;  // live subscriptions that receive pose_topic
  MarkerFrame frame;  // decoded into by `decoder`
  std::size_t marker_first = 0, marker_count = 0, sensor_first = 0, sensor_count = 0;
  bool present = false;
  double last_seen_s = 0.0;  // frame time
  Clock::time_point last_seen_at{};
};

struct Daemon::State {
  DaemonConfig config;
  std::string config_name;  // config.file made safe for any output
  std::unique_ptr<Tracker> tracker;
  std::unique_ptr<MarkerDecoder> decoder;
  std::unique_ptr<PoseEncoder> encoder;
  std::vector<ViewState> views;  // one subject's (multi-subject: each subject has its own)
  // Live subscriptions that receive `pose` (multi-subject: some subject's
  // pose/NAME; each subject counts its own). No one: no pose is encoded.
  int pose_subscribers = 0;
  std::string model_out;  // the `model` payload of this config, made once
  MarkerFrame frame;  // decoded into, one at a time
  NameMismatchWatch names;  // does the stream use the config's marker names?
  // Messages waiting to be served, oldest first: [first, first + count) of a
  // ring of max_backlog_frames payloads, holding `bytes` at most kInputQueueBytes.
  std::vector<zmq::message_t> waiting;
  std::vector<Clock::time_point> received_at;
  int first = 0, count = 0;
  std::size_t bytes = 0;
  zmq::socket_t sub, pub;
  SubscriptionBook subscriptions;  // pub's live ones (kept with pub across a reload)
  OutputRevival revival;  // a connected output's connection events (declared after pub: stops first)
  SocketMonitor monitor;  // sub's disconnect and accept-failure events (declared after sub: stops first)
  RevivalRule input_revival;  // fed by `monitor` when the input connects
  std::unique_ptr<SourceInput> source;  // a QTM or NatNet server, when the config names one
  // The names `decoder` takes, sorted (a source keeps them whole; only the set matters).
  std::vector<std::string> marker_names;
  // Multi-subject configs: one per subject (empty: tracker, encoder and
  // model_out above serve the one subject).
  std::vector<SubjectState> subjects;
  // The topics published besides pose, stats and model: the subjects' (pose/NAME,
  // model/NAME) and the views'.
  std::vector<std::string> extra_topics;
  // A connected endpoint whose host no resolver knows, one line each: ZeroMQ retries it
  // silently. Looked up here, off the frame loop, waiting kHostLookupWait at most.
  std::vector<std::string> unknown_hosts;
};

struct Daemon::ReloadJob {
  std::function<DaemonConfig()> load;
  std::thread thread;
  std::mutex mutex;
  std::condition_variable finished;
  std::atomic<bool> done{false};
  std::unique_ptr<State> state;  // the result, or
  std::string error;             // why there is none
};

// Whether `name` is SUBJECT:MARKER of a subject a multi-subject config does not list.
bool Daemon::other_subject(const State& s, std::string_view name) {
  const std::size_t colon = name.find(':');
  if (s.subjects.empty() || colon == std::string_view::npos || colon == 0) return false;
  return std::none_of(s.subjects.begin(), s.subjects.end(), [&](const SubjectState& subject) {
    return subject.name == name.substr(0, colon);
  });
}

std::unique_ptr<Daemon::State> Daemon::prepare_state(DaemonConfig config) {
  // The loader refuses such a config; one built in code (a library user's) is refused here.
  if (const auto p = source_lab_problem(config))
    throw std::invalid_argument(p->problem + ". Fix: " + p->fix);
  auto s = std::make_unique<State>();
  const PlausibleMarkers plausible{config.max_abs_coordinate_m, config.zero_is_missing,
                                   config.quaternion_tolerance};
  const PayloadEncoding encoding = config.output_encoding == Encoding::msgpack
                                       ? PayloadEncoding::msgpack
                                       : PayloadEncoding::json;
  const auto make_encoder = [&](const Tracker& tracker) {
    return std::make_unique<PoseEncoder>(tracker, config.output_units, encoding,
                                         config.output_measured_markers,
                                         config.output_pose_content);
  };
  // A tracker's views; `subject`: its name in a multi-subject config (topic
  // TOPIC/NAME, poses carry "subject"), empty otherwise.
  const auto make_views = [&](const Tracker& tracker, const std::string& subject) {
    std::vector<ViewState> views;
    for (const PoseViewConfig& v : config.output_views) {
      ViewState view;
      view.topic = subject.empty() ? v.topic : v.topic + "/" + subject;
      view.encoder = std::make_unique<PoseEncoder>(
          tracker, v.units,
          v.encoding == Encoding::msgpack ? PayloadEncoding::msgpack : PayloadEncoding::json,
          v.measured_markers, v.content);
      if (!subject.empty()) view.encoder->set_subject(subject);
      if (v.axes) view.encoder->set_axes(*v.axes);
      s->extra_topics.push_back(view.topic);
      views.push_back(std::move(view));
    }
    return views;
  };
  // The names a decoder takes for one subject's setup, each after `prefix`.
  const auto names_of = [](const TrackerSetup& setup, const std::string& prefix,
                           std::vector<std::string>& names, std::vector<std::string>& sensors) {
    for (const MarkerTarget& m : setup.markers) names.push_back(prefix + m.marker);
    for (const SensorTarget& t : setup.sensors.sensors) sensors.push_back(prefix + t.sensor);
  };
  std::vector<std::string> names, sensor_names;
  if (config.subjects.empty()) {
    s->tracker = std::make_unique<Tracker>(config.tracker);
    s->encoder = make_encoder(*s->tracker);
    s->views = make_views(*s->tracker, "");
    names_of(config.tracker, "", names, sensor_names);
  }
  s->subjects.resize(config.subjects.size());
  for (std::size_t k = 0; k < config.subjects.size(); ++k) {
    const SubjectConfig& c = config.subjects[k];
    SubjectState& subject = s->subjects[k];
    subject.name = c.name;
    subject.pose_topic = "pose/" + c.name;
    subject.model_topic = "model/" + c.name;
    s->extra_topics.push_back(subject.pose_topic);
    s->extra_topics.push_back(subject.model_topic);
    subject.tracker = std::make_unique<Tracker>(c.tracker);
    subject.encoder = make_encoder(*subject.tracker);
    subject.encoder->set_subject(c.name);
    subject.views = make_views(*subject.tracker, c.name);
    std::vector<std::string> bare, bare_sensors;
    names_of(c.tracker, "", bare, bare_sensors);
    subject.decoder = std::make_unique<MarkerDecoder>(bare, config.input_m_per_unit,
                                                      config.max_payload_bytes, plausible,
                                                      bare_sensors);
    subject.frame = subject.decoder->make_frame();
    subject.marker_first = names.size();
    subject.sensor_first = sensor_names.size();
    names_of(c.tracker, c.name + ":", names, sensor_names);
    subject.marker_count = names.size() - subject.marker_first;
    subject.sensor_count = sensor_names.size() - subject.sensor_first;
    subject.model_out = encode_model(c.tracker, safe_text(c.file), config.output_units, encoding);
  }
  s->marker_names = names;
  std::sort(s->marker_names.begin(), s->marker_names.end());
  s->decoder = std::make_unique<MarkerDecoder>(names, config.input_m_per_unit,
                                               config.max_payload_bytes, plausible, sensor_names);
  s->decoder->set_of_subjects(!config.subjects.empty());
  s->frame = s->decoder->make_frame();
  s->waiting.resize(static_cast<std::size_t>(config.max_backlog_frames));
  s->received_at.resize(s->waiting.size());
  s->config_name = safe_text(config.file);
  for (const auto& [e, role, what] : {std::tuple{&config.input, "input", "no markers arrive"},
                                      std::tuple{&config.output, "output", "no poses leave"}})
    if (e->mode == SocketMode::connect)
      if (const auto unknown = unknown_host_within(e->address, kHostLookupWait))
        s->unknown_hosts.push_back(
            safe_text("the " + std::string(role) + " socket connects to '" + e->address +
                      "', but " + unknown->problem.substr(unknown->problem.find("no host")) +
                      ": ZeroMQ keeps trying it, and " + what + " until the name resolves. " +
                      "Fix: check the host name (" +
                      (e->option.empty() ? "/" + std::string(role) + "/endpoint" : e->option) +
                      "), or give the host's address"));
  if (config.subjects.empty())
    s->model_out = encode_model(config.tracker, s->config_name, config.output_units, encoding);
  s->config = std::move(config);
  return s;
}

// Sockets are reopened only when their endpoint changed, so a reload of the
// solver settings does not disturb connected clients. New sockets are opened
// before old ones are taken over: if one fails, the old state is whole.
void Daemon::attach_sockets(State& next, State* old) {
  auto same = [](const Endpoint& a, const Endpoint& b) {
    return a.address == b.address && a.mode == b.mode;
  };
  const bool keep_sub = old && same(old->config.input, next.config.input);
  const bool keep_pub = old && same(old->config.output, next.config.output);
  // A source keeps its connection while neither it nor the lab's axes changed; names taken
  // that changed are mapped again on its thread, from its next frame.
  const SourceConfig& source = next.config.source;
  const LabAxes& lab = next.config.tracker.model->lab_axes;
  const bool keep_source = old && old->source && old->source->config() == source &&
                           old->config.tracker.model->lab_axes == lab;
  // Each monitor watches before its socket connects. Should the bind or connect throw,
  // the State goes with its sockets, each monitor first (declared after its socket).
  if (!keep_sub) {
    next.sub = make_socket(context_, zmq::socket_type::sub, next.config);
    const bool connects = next.config.input.mode == SocketMode::connect;
    next.monitor = SocketMonitor(context_, next.sub,
                                 ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_ACCEPT_FAILED |
                                     (connects ? RevivalRule::kEvents : 0));
    open_endpoint(next.sub, zmq::socket_type::sub, next.config);
  }
  if (!keep_pub) {
    next.pub = make_socket(context_, zmq::socket_type::xpub, next.config);
    if (next.config.output.mode == SocketMode::connect) next.revival = OutputRevival(context_, next.pub);
    open_endpoint(next.pub, zmq::socket_type::xpub, next.config);
  }
  // What may throw (a copy, a new source's thread and bind) before anything is taken over.
  std::vector<std::string> source_names;
  if (source.kind != SourceKind::none) source_names = next.marker_names;
  std::unique_ptr<SourceInput> new_source;
  if (!keep_source && source.kind != SourceKind::none)
    new_source = std::make_unique<SourceInput>(
        context_, source, lab, std::move(source_names),
        source_client_ ? source_client_(source) : make_source_client(source));
  if (keep_sub) {
    // New limits hold for connections made from now on; the decoder checks
    // the payload limit on every message anyway.
    set_input_limits(old->sub, next.config);
    next.sub = std::move(old->sub);
    next.monitor = std::move(old->monitor);
    next.input_revival = old->input_revival;
  }
  if (keep_pub) {
    set_output_limits(old->pub, next.config);
    next.pub = std::move(old->pub);
    next.revival = std::move(old->revival);
    next.subscriptions = std::move(old->subscriptions);
    next.subscriptions.revalidate(
        [&](std::string_view prefix) { return subscribes_to_our_topics(prefix, next.extra_topics); });
  }
  count_subscribers(next);
  if (keep_source) {
    next.source = std::move(old->source);
    next.source->retake(std::move(source_names));
  } else if (new_source) {
    next.source = std::move(new_source);
    spdlog::info("source {}: connecting", safe_text(source.url, 128));
  }
}

Daemon::Daemon(zmq::context_t& context, DaemonConfig config, SourceClientFactory source_client)
    : context_(context), source_client_(std::move(source_client)), started_(Clock::now()) {
  auto s = prepare_state(std::move(config));
  attach_sockets(*s, nullptr);
  state_ = std::move(s);
  subject_counts_.assign(state_->subjects.size(), {});
  subject_snapshot_ = subject_counts_;
  out_.reserve(1 << 16);
  view_out_.reserve(1 << 16);
  stats_out_.reserve(4096);
}

Daemon::~Daemon() {
  // A reload thread still running owns its job; it must not be joined here.
  if (reload_ && reload_->thread.joinable()) reload_->thread.detach();
}

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

std::vector<SubjectCounters> Daemon::subject_counters() const {
  std::lock_guard lock(snapshot_mutex_);
  return subject_snapshot_;
}

void Daemon::update_snapshot() {
  std::lock_guard lock(snapshot_mutex_);
  snapshot_ = counters_;
  // Same size except right after a reload: copying then allocates nothing.
  subject_snapshot_ = subject_counts_;
}

void Daemon::send(const char* topic, const std::string& payload) {
  // dontwait: PUB never blocks, but be explicit; a failed send is logged, never fatal.
  try {
    State& s = *state_;
    // Reading ZMQ_EVENTS makes the socket take in what its I/O thread told it
    // (how much each subscriber has read), which send() does at most about
    // once a millisecond: without it a short queue looks full to a
    // subscriber that keeps up, when poses go out faster than that.
    (void)s.pub.get(zmq::sockopt::events);
    s.pub.send(zmq::buffer(std::string_view(topic)),
               zmq::send_flags::sndmore | zmq::send_flags::dontwait);
    s.pub.send(zmq::buffer(payload), zmq::send_flags::dontwait);
  } catch (const zmq::error_t& e) {
    send_log_.warn("could not publish {}: {}", topic, e.what());
  }
}

// Every text that quotes input goes through safe_text before it is stored
// or logged: last_error is fixed-size, so recording it cannot fail.
void Daemon::bad_input(std::string_view what, std::string_view detail,
                       std::string_view after) noexcept {
  ++counters_.decode_errors;
  char text[256];
  std::size_t n = std::min(what.size(), sizeof text - 16);
  if (n > 0) std::memcpy(text, what.data(), n);
  n += safe_text(detail, text + n, sizeof text - 8 - n);
  const std::size_t tail = std::min(after.size(), sizeof text - n);
  if (tail > 0) std::memcpy(text + n, after.data(), tail);  // an empty view may hold nullptr
  last_error_.assign_safe({text, n + tail});
  bad_input_log_.warn("bad input: {}", last_error_.view());
}

void Daemon::internal_error(std::string_view where, std::string_view what) noexcept {
  ++counters_.internal_errors;
  char text[256];
  std::size_t n = std::min(where.size(), sizeof text - 8);
  std::memcpy(text, where.data(), n);
  n += safe_text(what, text + n, sizeof text - n);
  last_error_.assign_safe({text, n});
  internal_log_.warn("internal error, carrying on: {}", last_error_.view());
}

// Takes what ZeroMQ has queued, without decoding, into the ring of waiting
// messages. Returns how many messages it received.
int Daemon::drain_input(zmq::socket_t& in, int budget) {
  State& s = *state_;
  const int capacity = static_cast<int>(s.waiting.size());
  int received = 0;
  for (; received < budget; ++received) {
    if (!in.recv(topic_, zmq::recv_flags::dontwait)) break;
    const Clock::time_point now = Clock::now();
    ++counters_.frames_in;
    int parts = 1;
    for (bool more = topic_.more(); more; ++parts) {
      zmq::message_t& m = parts == 1 ? payload_ : extra_;
      if (!in.recv(m, zmq::recv_flags::dontwait)) break;  // parts arrive together
      more = m.more();
    }
    if (parts != 2) {
      bad_input("expected 2 message frames [topic, payload], got ", std::to_string(parts));
      continue;
    }
    if (view(topic_) != kMarkersTopic) {
      bad_input("unknown topic '", view(topic_).substr(0, 64), "'");
      continue;
    }
    // Behind: more frames waiting than the ring holds. Drop what waits and
    // answer only the newest frames until a drain finds nothing new.
    if (s.count == capacity || s.bytes + payload_.size() > kInputQueueBytes) overloaded_ = true;
    if (overloaded_) {
      counters_.frames_dropped += static_cast<std::uint64_t>(s.count);
      s.first = (s.first + s.count) % capacity;
      s.count = 0;
      s.bytes = 0;
    }
    const int slot = (s.first + s.count) % capacity;
    s.waiting[slot].swap(payload_);
    s.received_at[slot] = now;
    s.bytes += s.waiting[slot].size();
    ++s.count;
  }
  if (received == 0) overloaded_ = false;
  return received;
}

void Daemon::serve_input(zmq::socket_t& in) {
  const Clock::time_point until = Clock::now() + kMaxServe;
  int budget = kMaxBatch;
  for (;;) {
    State& s = *state_;
    budget -= drain_input(in, budget);
    if (s.count == 0) break;
    const int slot = s.first;
    s.first = (s.first + 1) % static_cast<int>(s.waiting.size());
    --s.count;
    s.bytes -= s.waiting[slot].size();
    try {
      const zmq::message_t& m = s.waiting[slot];
      serve_frame({static_cast<const std::uint8_t*>(m.data()), m.size()}, s.received_at[slot]);
    } catch (const std::exception& e) {
      internal_error("while serving a frame: ", e.what());
    } catch (...) {
      internal_error("while serving a frame: ", "unknown exception");
    }
    if (budget <= 0 || Clock::now() >= until) break;
  }
  update_snapshot();
}

FrameStages Daemon::serve_payload(std::span<const std::uint8_t> payload) {
  read_subscriptions();  // as the loop would: poses go to those who subscribe
  serve_frame(payload, Clock::now());
  return last_stages_;
}

void Daemon::serve_frame(std::span<const std::uint8_t> payload, Clock::time_point received) {
  State& s = *state_;
  last_stages_ = {};
  const Clock::time_point decode_start = Clock::now();
  if (!s.decoder->decode(payload, s.frame, decode_error_)) {
    bad_input("bad marker frame: ", decode_error_);
    return;
  }
  // A multi-subject frame with "subject": its bare names are that subject's.
  SubjectState* only = nullptr;
  if (!s.subjects.empty() && s.frame.has_subject) {
    for (SubjectState& subject : s.subjects)
      if (subject.name == s.frame.subject) only = &subject;
    if (!only) {
      ++counters_.other_subject_frames;
      // Most often a spelling ("alice" for "Alice"): said, as a prefix's unknown subject is.
      char text[96];
      const std::size_t n = safe_text(s.frame.subject, text, 64);
      other_subject_log_.warn(
          "frames for subject '{}' are not answered: it is not one of the config's {} subjects "
          "(names are case-sensitive; stats: other_subject_frames)",
          std::string_view(text, n), s.subjects.size());
      return;
    }
    if (!only->decoder->decode(payload, only->frame, decode_error_)) {
      bad_input("bad marker frame: ", decode_error_);
      return;
    }
  }
  MarkerFrame& decoded = only ? only->frame : s.frame;
  const MarkerFrame& f = decoded;
  // This decoder's next frame lists the unknown names after this one's list (a prop's 8
  // markers first in every frame hid a subject's misnamed ones from the log and from the
  // mismatch's closest names). The list holds unknown_names.size() names at most.
  const int next_skip = f.unknown_skip + static_cast<int>(f.unknown_names.size());
  decoded.unknown_skip = next_skip < f.unknown_count ? next_skip : 0;
  counters_.rejected_coordinates += static_cast<std::uint64_t>(f.rejected_count);
  counters_.zero_markers += static_cast<std::uint64_t>(f.zero_count);
  counters_.unknown_markers += static_cast<std::uint64_t>(f.unknown_count);
  counters_.rejected_orientations += static_cast<std::uint64_t>(f.rejected_orientations);
  counters_.unknown_sensors += static_cast<std::uint64_t>(f.unknown_sensor_count);
  // In a split, a frame of only other processes' subjects (while ours are
  // out of the volume) is expected: not a mismatch of names. Judged from every unknown name,
  // not the few listed for the log (a subject's misnamed markers after 8 of another's were
  // once taken for that).
  const bool others_only = !s.subjects.empty() && f.known_count == 0 && f.unknown_count > 0 &&
                           f.unknown_foreign == f.unknown_count;
  if (f.known_count == 0 && f.unknown_count > 0 && !others_only) ++counters_.unmatched_frames;
  const bool warn_mismatch = !others_only && s.names.observe(f.known_count, f.unknown_count);
  counters_.config_mismatch = s.names.mismatched();
  if (s.subjects.empty())
    publish_pose(f, received, decode_start);
  else
    publish_subjects(f, only, received, decode_start);
  try {
    // Look up first: only a name not seen before costs an allocation.
    const auto first_time = [&](std::string_view name) {
      if (unknown_seen_.size() >= kMaxUnknownLogged || unknown_seen_.contains(name)) return false;
      unknown_seen_.emplace(name);
      return true;
    };
    const auto report_once = [&](std::string_view name, const char* what) {
      if (first_time(name))
        spdlog::warn("{} '{}' is not in the {}: ignored (reported once)", what,
                     safe_text(name, 128), *what == 'm' ? "model" : "config");
    };
    // Markers: the frame's new ones on one line (a misnamed stream's 40 would be 40 lines).
    // Another subject's markers (another fabrikd's, in a split): reported
    // once per subject, not once per marker.
    std::string fresh;
    for (int k = 0; k < f.unknown_listed; ++k) {
      const std::string& name = f.unknown_names[k];
      if (!other_subject(s, name)) {
        if (first_time(name)) fresh += (fresh.empty() ? "'" : ", '") + safe_text(name, 128) + "'";
        continue;
      }
      const std::string_view subject = std::string_view(name).substr(0, name.find(':'));
      const auto listed =
          std::find_if(s.subjects.begin(), s.subjects.end(),
                       [&](const SubjectState& c) { return iequals(c.name, subject); });
      if (listed == s.subjects.end()) {
        report_once(subject, "subject");
      } else if (first_time(subject)) {  // most often a spelling: said with the config's name
        spdlog::warn(
            "subject '{}' is not in the config: ignored (reported once; the config has "
            "'{}': names are case-sensitive)",
            safe_text(subject, 128), safe_text(listed->name, 128));
      }
    }
    if (!fresh.empty())
      spdlog::warn("markers not in the model: {}: ignored (each reported once)", fresh);
    for (int k = 0; k < f.unknown_sensors_listed; ++k)
      report_once(f.unknown_sensor_names[k], "orientation sensor");
    if (warn_mismatch) warn_config_mismatch(f);
  } catch (const std::exception&) {  // a log line lost when memory is short, nothing more
  }
}

void Daemon::warn_config_mismatch(const MarkerFrame& f) {
  std::vector<std::string> config_names, stream_names;
  if (state_->subjects.empty())
    for (const MarkerTarget& m : state_->config.tracker.markers)
      config_names.push_back(safe_text(m.marker, 64));
  for (const SubjectState& subject : state_->subjects)  // as the stream must name them
    for (const MarkerTarget& m : subject.tracker->setup().markers)
      config_names.push_back(safe_text(subject.name + ":" + m.marker, 64));
  for (int k = 0; k < f.unknown_listed; ++k) stream_names.push_back(safe_text(f.unknown_names[k], 64));
  for (const std::string& name : unknown_seen_)
    if (std::find(stream_names.begin(), stream_names.end(), name) == stream_names.end())
      stream_names.push_back(safe_text(name, 64));
  spdlog::error(
      "the stream's marker names share none with the config {} ({} frames in a row): every "
      "frame is solved without targets.{}\nFix: start fabrikd with a config made for this "
      "marker set (fabrik calibrate), or map the stream's names onto the model's markers in "
      "the config's targets.markers ({{\"STREAM_NAME\": {{\"point\": \"MODEL_MARKER\"}}}})"
      "{} (stats: config_mismatch, unmatched_frames)",
      state_->config_name, NameMismatchWatch::kFramesInARow,
      names_beside(config_names, "stream:", stream_names),
      state_->config.source.kind == SourceKind::none
          ? ""
          : "; names behind a subject prefix the source keeps: source_options.subject_prefix "
            "(docs/vendor-sources.md)");
}

namespace {
// A frame's confidences reach the tracker only when it carried some (the tracker skips them then).
std::span<const float> confidence_of(const MarkerFrame& f) {
  return f.confidence_count > 0 ? std::span<const float>(f.confidence) : std::span<const float>();
}
}  // namespace

void Daemon::publish_pose(const MarkerFrame& f, Clock::time_point received,
                          Clock::time_point decode_start) {
  State& s = *state_;
  const double time_s = f.has_time ? f.time_s
                                   : std::chrono::duration<double>(received - started_).count();
  track_and_publish(*s.tracker, *s.encoder, "pose", s.pose_subscribers, s.views, f, time_s,
                    {f.p_world_m, f.visible, f.q_sensor, f.sensor_visible, confidence_of(f)},
                    received, decode_start);
}

// Presence (docs/multi-subject.md): a subject is seen in a frame when one of
// its markers (at or above the confidence threshold) or sensors is measured. Unseen for longer than
// subject_timeout_s (frame time; or a clock that went back), it is absent:
// no poses, and its tracker is reset so that it starts cold when seen again.
// Unseen for less, it is tracked on (an occlusion: the tracker's gap rules).
void Daemon::publish_subjects(const MarkerFrame& f, SubjectState* only, Clock::time_point received,
                              Clock::time_point decode_start) {
  State& s = *state_;
  const double time_s = f.has_time ? f.time_s
                                   : std::chrono::duration<double>(received - started_).count();
  const double timeout_s = s.config.subject_timeout_s;
  for (std::size_t k = 0; k < s.subjects.size(); ++k) {
    SubjectState& subject = s.subjects[k];
    if (only && &subject != only) continue;
    const Measurements m =
        only ? Measurements{f.p_world_m, f.visible, f.q_sensor, f.sensor_visible, confidence_of(f)}
             : Measurements{
                   std::span(f.p_world_m).subspan(subject.marker_first, subject.marker_count),
                   std::span(f.visible).subspan(subject.marker_first, subject.marker_count),
                   std::span(f.q_sensor).subspan(subject.sensor_first, subject.sensor_count),
                   std::span(f.sensor_visible).subspan(subject.sensor_first, subject.sensor_count),
                   f.confidence_count > 0 ? std::span<const float>(f.confidence)
                                                .subspan(subject.marker_first, subject.marker_count)
                                          : std::span<const float>()};
    const auto any = [](std::span<const std::uint8_t> flags) {
      return std::find(flags.begin(), flags.end(), std::uint8_t{1}) != flags.end();
    };
    // A marker under the confidence threshold is occluded (the tracker's own
    // rule, `c >= threshold`; a NaN confidence fails it), so it does not keep
    // a subject present either.
    const auto any_trusted = [&](std::span<const std::uint8_t> flags,
                                 std::span<const float> confidence) {
      if (confidence.empty()) return any(flags);
      const double threshold = subject.tracker->setup().confidence.threshold;
      for (std::size_t i = 0; i < flags.size(); ++i)
        if (flags[i] && i < confidence.size() && confidence[i] >= threshold) return true;
      return false;
    };
    const bool seen = any_trusted(m.visible, m.confidence) || any(m.sensor_visible);
    SubjectCounters& c = subject_counts_[k];
    const double age_s = time_s - subject.last_seen_s;
    if (subject.present && (age_s > timeout_s || age_s < 0.0)) {
      subject.present = c.present = false;
      subject.tracker->reset();
      ++c.departures;
    }
    if (seen) {
      if (!subject.present) ++c.appearances;
      subject.present = c.present = true;
      subject.last_seen_s = time_s;
      subject.last_seen_at = received;
    }
    if (!subject.present) continue;
    track_and_publish(*subject.tracker, *subject.encoder, subject.pose_topic.c_str(),
                      subject.pose_subscribers, subject.views, f, time_s, m, received,
                      decode_start, &c.frames_out);
    decode_start = Clock::now();  // the next subject's stages start here
  }
}

bool Daemon::track_and_publish(Tracker& tracker, const PoseEncoder& encoder, const char* topic,
                               int pose_subscribers, std::span<ViewState> views,
                               const MarkerFrame& f, double time_s, const Measurements& m,
                               Clock::time_point received, Clock::time_point decode_start,
                               std::uint64_t* subject_frames_out) {
  FrameStages stages;
  const Clock::time_point solve_start = Clock::now();
  stages[Stage::decode] = us_between(decode_start, solve_start);
  const TrackResult* r =
      &tracker.track(time_s, m.p_world_m, m.visible, m.q_sensor, m.sensor_visible, m.confidence);
  if (!all_finite(*r)) {
    // A degenerate solve must not poison the warm start of every later frame.
    internal_error("solve gave a non-finite pose: ", "restarted from the rest posture");
    tracker.reset();
    r = &tracker.track(time_s, m.p_world_m, m.visible, m.q_sensor, m.sensor_visible, m.confidence);
    if (!all_finite(*r)) return false;
  }
  Clock::time_point encode_start = Clock::now();
  const PoseHeader header{f.frame, f.has_time, f.time_s, f.has_stamp, f.stamp_us};
  counters_.outliers += static_cast<std::uint64_t>(r->outlier_count);
  counters_.poor_frames += r->quality == FitQuality::poor ? 1 : 0;
  ++counters_.frames_out;
  if (subject_frames_out) ++*subject_frames_out;  // before the snapshot the pose's send takes
  ++interval_frames_out_;
  // The frame's first message out ends its stages and its latency: the pose,
  // or, when no subscription receives it, the first view one selects. What
  // no one receives is not made (ZeroMQ would drop it unsent).
  Clock::time_point send_start = encode_start, sent = encode_start;
  bool first = true;
  const auto publish = [&](const PoseEncoder& e, std::string& payload, const char* t) {
    const Clock::time_point e0 = Clock::now();
    e.encode(header, *r, payload, {m.p_world_m, m.visible});
    const Clock::time_point e1 = Clock::now();
    if (first) update_snapshot();  // counters first: whoever has seen a pose sees the counts that include it
    send(t, payload);
    if (first) encode_start = e0, send_start = e1, sent = Clock::now();
    first = false;
  };
  if (pose_subscribers > 0) publish(encoder, out_, topic);
  // After the pose, so that the pose's latency does not grow with its views.
  for (ViewState& view : views) {
    if (view.subscribers == 0) continue;
    publish(*view.encoder, view_out_, view.topic.c_str());
    ++view.frames_out;
  }
  if (first) {  // nothing made: encode 0, send the counts' update
    update_snapshot();
    sent = Clock::now();
  }
  stages[Stage::solve] = us_between(solve_start, encode_start);
  stages[Stage::encode] = us_between(encode_start, send_start);
  stages[Stage::send] = us_between(send_start, sent);
  stages.solver_us = r->solve_us;
  stages.iterations = r->solve.iterations;
  solve_us_.add(r->solve_us);
  queue_us_.add(us_between(received, sent));
  stages_us_.add(stages);
  last_stages_ = stages;
  return true;
}

void Daemon::count_subscribers(State& s) {
  const SubscriptionBook& book = s.subscriptions;
  if (s.subjects.empty()) {
    s.pose_subscribers = book.receiving("pose");
  } else {
    s.pose_subscribers = book.count_if([&](std::string_view prefix) {
      return std::any_of(s.subjects.begin(), s.subjects.end(), [&](const SubjectState& subject) {
        return subject.pose_topic.starts_with(prefix);
      });
    });
    for (SubjectState& subject : s.subjects) subject.pose_subscribers = book.receiving(subject.pose_topic);
  }
  counters_.pose_subscribers = static_cast<std::uint64_t>(s.pose_subscribers);
  for (ViewState& view : s.views) view.subscribers = book.selecting(view.topic);
  for (SubjectState& subject : s.subjects)
    for (ViewState& view : subject.views) view.subscribers = book.selecting(view.topic);
}

// ZeroMQ gave up a connecting socket's session (session_revival.hpp): a
// disconnection with no reconnection after it. The socket keeps the endpoint
// all the same, so it is disconnected (ending nothing live) and connected
// again: one pipe at a time, as the output's subscription book expects.
void Daemon::reconnect(zmq::socket_t& socket, const std::string& endpoint, RevivalRule& rule,
                       std::uint64_t& count, std::string_view what, std::string_view why) {
  rule.reconnected();
  (void)zmq_disconnect(socket.handle(), endpoint.c_str());  // ENOENT where it was forgotten
  if (zmq_connect(socket.handle(), endpoint.c_str()) != 0) {
    internal_error("cannot connect again to " + safe_text(endpoint, 128) + ": ",
                   zmq_strerror(zmq_errno()));
    rule.connect_failed(Clock::now());
    return;
  }
  ++count;
  peer_log_.warn("{} at {} ended the session, and ZeroMQ gave it up ({}): connected again, and "
                 "again after {} s should this session end within a second",
                 what, safe_text(endpoint, 128), why,
                 std::chrono::duration_cast<std::chrono::seconds>(rule.retry()).count());
  update_snapshot();
}

void Daemon::read_monitor() {
  State& s = *state_;
  for (int n = 0; n < kMaxBatch; ++n) {
    const std::optional<SocketMonitor::Event> event = s.monitor.next();
    if (!event) break;
    if (s.config.input.mode == SocketMode::connect) s.input_revival.on_event(event->id, Clock::now());
    if (event->id == ZMQ_EVENT_DISCONNECTED) {
      ++counters_.input_disconnects;
      peer_log_.info("an input peer disconnected (a source quit, or it sent a message over "
                     "twice max_payload_bytes plus 4096)");
    } else if (event->id == ZMQ_EVENT_ACCEPT_FAILED) {
      ++counters_.accept_failures;
      peer_log_.warn("cannot accept a connection on the input: {}",
                     std::strerror(static_cast<int>(event->value)));
    }
  }
  update_snapshot();
}

bool connected_to(int fd, std::string_view endpoint) {
  sockaddr_storage local{}, peer{};
  socklen_t local_n = sizeof local, peer_n = sizeof peer;
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_n) != 0 ||
      getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &peer_n) != 0)
    return false;  // not a socket, or not a connected one (a listener)
  if (local.ss_family == AF_INET || local.ss_family == AF_INET6) {
    if (!endpoint.starts_with("tcp://")) return false;
    const auto colon = endpoint.rfind(':');
    const std::uint16_t port = local.ss_family == AF_INET
                                   ? reinterpret_cast<const sockaddr_in&>(local).sin_port
                                   : reinterpret_cast<const sockaddr_in6&>(local).sin6_port;
    return colon != std::string_view::npos &&
           endpoint.substr(colon + 1) == std::to_string(ntohs(port));
  }
  if (local.ss_family == AF_UNIX) {
    const auto& un = reinterpret_cast<const sockaddr_un&>(local);
    return endpoint.starts_with("ipc://") && endpoint.substr(6) == std::string_view(un.sun_path);
  }
  return false;
}

namespace {
// Who sent a subscription message (SubscriptionBook): ZeroMQ names its descriptor,
// the descriptor's socket tells it apart from a later one on the same number.
std::optional<std::uint64_t> inode_of(int fd) {
  struct stat st{};
  if (::fstat(fd, &st) != 0) return std::nullopt;
  return static_cast<std::uint64_t>(st.st_ino);
}
SubscriptionSender subscription_sender(zmq::message_t& message) {
  const int fd = zmq_msg_get(message.handle(), ZMQ_SRCFD);
  if (fd < 0) return {};
  const std::optional<std::uint64_t> inode = inode_of(fd);
  if (!inode) return {SubscriptionSender::Kind::gone, fd, 0};
  return {SubscriptionSender::Kind::connection, fd, *inode};
}
bool descriptor_still_that_socket(const SubscriptionSender& c) { return inode_of(c.fd) == c.inode; }
}  // namespace

// ZeroMQ applies every subscription itself; the loop sees each one too
// (XPUB_VERBOSER) and refuses any that is not a prefix of a topic we
// publish, and any other message: on a bound socket, the connection that
// sent it is shut down, which is what frees what ZeroMQ stored for it. A
// connected output's peer is the operator's own (a proxy), so it is only
// counted there; every message there is that one peer's (SubscriptionBook).
// A subscription that covers `model` has been applied by the
// time the loop sees it, so the model published then reaches it (once per
// batch of subscriptions, however many of them ask).
void Daemon::read_subscriptions() {
  State& s = *state_;
  const bool bound = s.config.output.mode == SocketMode::bind;
  std::string endpoint;
  int shut[16];
  int n_shut = 0;
  bool model_wanted = false;
  int n = 0;
  for (; n < kMaxBatch; ++n) {
    if (!s.pub.recv(subscription_, zmq::recv_flags::dontwait)) break;
    const std::string_view m = view(subscription_);
    const SubscriptionSender sender =
        bound ? subscription_sender(subscription_) : SubscriptionSender{SubscriptionSender::Kind::peer};
    if (!m.empty() && m[0] == 0) {  // an unsubscription (or a subscriber gone): nothing to hold
      if (!s.subscriptions.unsubscribed(m.substr(1), sender, descriptor_still_that_socket))
        ++counters_.unsubscriptions_ignored;
      continue;
    }
    if (!m.empty() && m[0] == 1 && subscribes_to_our_topics(m.substr(1), s.extra_topics)) {
      const std::string_view prefix = m.substr(1);
      s.subscriptions.subscribed(prefix, sender);
      model_wanted = model_wanted ||
                     (s.subjects.empty() ? subscribes_to_model(prefix)
                                         : std::any_of(s.subjects.begin(), s.subjects.end(),
                                                       [&](const SubjectState& subject) {
                                                         return subject.model_topic.starts_with(prefix);
                                                       }));
      continue;
    }
    ++counters_.subscriptions_refused;
    if (!m.empty() && m[0] == 1) s.subscriptions.refused(m.substr(1), sender);
    // The deprecated ZMQ_SRCFD is the only way ZeroMQ names the connection.
    const int fd = zmq_msg_get(subscription_.handle(), ZMQ_SRCFD);
    bool dropped = false;
    if (bound && fd >= 0 && std::find(shut, shut + n_shut, fd) == shut + n_shut) {
      if (endpoint.empty()) endpoint = s.pub.get(zmq::sockopt::last_endpoint);
      if (connected_to(fd, endpoint) && ::shutdown(fd, SHUT_RDWR) == 0) {
        dropped = true;
        if (n_shut < static_cast<int>(std::size(shut))) shut[n_shut++] = fd;
      }
    }
    char text[96];
    const std::size_t n_text = safe_text(m.substr(std::min<std::size_t>(1, m.size())), text, 64);
    subscriber_log_.warn(
        "refused a subscription to '{}' on the output{}: fabrikd publishes only the topics "
        "{}{} (stats: subscriptions_refused)",
        std::string_view(text, n_text), dropped ? ", subscriber disconnected" : "",
        s.subjects.empty() ? "pose, stats and model"
                           : "stats, and pose/NAME and model/NAME of its subjects",
        s.config.output_views.empty() ? "" : ", and its views' topics");
  }
  if (n == 0) return;
  count_subscribers(s);
  update_snapshot();
  if (model_wanted) want_model(Clock::now());
}

constexpr auto kModelInterval = std::chrono::milliseconds(100);

void Daemon::want_model(Clock::time_point now) {
  if (now - last_model_ >= kModelInterval)
    publish_model();
  else
    model_pending_ = true;
}

void Daemon::publish_model() {
  // Every subject's model (the subscriber's prefix picks what it receives).
  if (state_->subjects.empty()) send("model", state_->model_out);
  for (const SubjectState& subject : state_->subjects)
    send(subject.model_topic.c_str(), subject.model_out);
  last_model_ = Clock::now();
  model_pending_ = false;
}

void Daemon::publish_stats(double interval_s) {
  const State& s = *state_;
  StatsFields fields{
      std::chrono::duration<double>(Clock::now() - started_).count(),
      interval_s,
      interval_s > 0 ? static_cast<double>(interval_frames_out_) / interval_s : 0.0,
      counters_,
      solve_us_,
      queue_us_,
      stages_us_,
      last_error_.view(),
      s.config_name,
      s.source.get(),
      {},
      {},
      {},
      {}};
  const Clock::time_point now = Clock::now();
  const auto subjects = [&](auto& w) {
    w.begin_map(s.subjects.size());
    for (std::size_t k = 0; k < s.subjects.size(); ++k) {
      const SubjectState& subject = s.subjects[k];
      const SubjectCounters& c = subject_counts_[k];
      w.key(subject.name);  // a checked name: letters, digits, '_', '-', '.'
      w.begin_map(5);
      w.key("present");
      w.boolean(c.present);
      w.key("frames_out");
      w.uint(c.frames_out);
      w.key("appearances");
      w.uint(c.appearances);
      w.key("departures");
      w.uint(c.departures);
      w.key("seen_s_ago");  // by the daemon's clock; null: never seen
      if (c.appearances == 0)
        w.null();
      else
        w.number(std::chrono::duration<double>(now - subject.last_seen_at).count(), 3);
      w.end_map();
    }
    w.end_map();
  };
  if (!s.subjects.empty()) {
    fields.subjects_json = subjects;
    fields.subjects_msgpack = subjects;
  }
  const auto views = [&](auto& w) {
    std::size_t n = s.views.size();
    for (const SubjectState& subject : s.subjects) n += subject.views.size();
    w.begin_map(n);
    const auto write = [&](const ViewState& view) {
      w.key(view.topic);  // a checked topic and subject name
      w.begin_map(2);
      w.key("subscribers");
      w.uint(static_cast<std::uint64_t>(view.subscribers));
      w.key("frames_out");
      w.uint(view.frames_out);
      w.end_map();
    };
    for (const ViewState& view : s.views) write(view);
    for (const SubjectState& subject : s.subjects)
      for (const ViewState& view : subject.views) write(view);
    w.end_map();
  };
  if (!s.config.output_views.empty()) {
    fields.views_json = views;
    fields.views_msgpack = views;
  }
  if (s.config.output_encoding == Encoding::msgpack) {
    MsgpackWriter w(stats_out_);
    write_stats(w, fields);
  } else {
    JsonWriter w(stats_out_, 3);
    write_stats(w, fields);
  }
  solve_us_.clear();
  queue_us_.clear();
  stages_us_.clear();
  interval_frames_out_ = 0;
  send("stats", stats_out_);
}

void Daemon::switch_to(std::unique_ptr<State> next) {
  const std::string input_before = input_endpoint(), output_before = output_endpoint();
  attach_sockets(*next, state_.get());
  state_ = std::move(next);
  subject_counts_.assign(state_->subjects.size(), {});
  overloaded_ = false;
  ++counters_.reloads;
  spdlog::set_level(spdlog::level::from_str(state_->config.log_level));
  spdlog::info("config reloaded from {}", state_->config_name);
  // Where the poses went is what a silent subscriber needs to know.
  if (input_endpoint() != input_before || output_endpoint() != output_before) log_endpoints();
}

void Daemon::log_endpoints() const {
  spdlog::info("fabrikd: markers in on {} ({}), poses out on {} ({}), {} markers tracked{}",
               safe_text(input_endpoint()),
               state_->config.input.mode == SocketMode::bind ? "bind" : "connect",
               safe_text(output_endpoint()),
               state_->config.output.mode == SocketMode::bind ? "bind" : "connect",
               state_->frame.p_world_m.size(),
               state_->subjects.empty()
                   ? std::string()
                   : " for " + std::to_string(state_->subjects.size()) + " subjects");
  for (const std::string& line : state_->unknown_hosts) spdlog::warn("{}", line);
}

void Daemon::start_reload(const std::function<DaemonConfig()>& load_config) {
  auto job = std::make_shared<ReloadJob>();
  job->load = load_config;
  // The thread holds the job too: if a stop leaves it behind, it still
  // writes only into memory it owns.
  job->thread = std::thread([job] {
    std::unique_ptr<State> state;
    std::string error;
    try {
      state = prepare_state(job->load());
    } catch (const std::exception& e) {
      error = e.what();
    } catch (...) {
      error = "unknown exception";
    }
    std::lock_guard lock(job->mutex);
    job->state = std::move(state);
    job->error = std::move(error);
    job->done = true;
    job->finished.notify_all();
  });
  reload_ = std::move(job);
}

void Daemon::finish_reload() {
  std::shared_ptr<ReloadJob> job = std::move(reload_);
  job->thread.join();
  bool reloaded = false;
  try {
    if (!job->state) throw std::runtime_error(job->error);
    switch_to(std::move(job->state));
    reloaded = true;
  } catch (const std::exception& e) {
    ++counters_.reload_errors;
    static constexpr std::string_view kWhat = "reload failed, keeping the running config: ";
    char text[512];
    const std::size_t n = safe_text(e.what(), text, sizeof text);
    spdlog::error("{}{}", kWhat, std::string_view(text, n));
    // In stats too, for a monitor that reads no log (last_error is the latest of any kind).
    char stats_text[256];
    const std::size_t head = std::min(kWhat.size(), sizeof stats_text);
    std::memcpy(stats_text, kWhat.data(), head);
    const std::size_t tail = std::min(n, sizeof stats_text - head);
    std::memcpy(stats_text + head, text, tail);
    last_error_.assign_safe({stats_text, head + tail});
  }
  update_snapshot();
  // The subscribers' model changes with the config (after the counts: whoever
  // has seen the new model sees the reload counted).
  if (reloaded) publish_model();
}

void Daemon::wait_for_reload_at_stop() {
  if (!reload_) return;
  {
    std::unique_lock lock(reload_->mutex);
    reload_->finished.wait_for(lock, kReloadGraceAtStop, [&] { return reload_->done.load(); });
  }
  if (reload_->done) {
    reload_->thread.join();
  } else {
    spdlog::warn("stopping while a config reload is still being read: left behind");
    reload_->thread.detach();
    reload_abandoned_ = true;
  }
  reload_.reset();
}

void Daemon::run(DaemonControl& control, const std::function<DaemonConfig()>& load_config) {
  log_endpoints();
  Clock::time_point last_stats = Clock::now();
  while (!control.stop.load()) {
    if (reload_ && reload_->done) finish_reload();
    if (!reload_ && control.reload.exchange(false)) {
      if (!load_config) {
        spdlog::warn("reload requested, but there is no config to reload from");
      } else {
        try {
          spdlog::info("SIGHUP: reading the config again");
          start_reload(load_config);
        } catch (const std::exception& e) {  // no thread to be had: try again on the next SIGHUP
          internal_error("cannot start a reload: ", e.what());
        }
      }
    }
    const auto interval = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(state_->config.stats_interval_s));
    const auto next_stats = last_stats + interval;
    // Wake at least every 100 ms so a stop request is seen promptly, and
    // every 10 ms while a reload is being read. Frames still waiting in the
    // ring (serving stopped at kMaxServe) are served at once: no more input
    // may come to wake the loop (the end of a burst or of a recording).
    State& s = *state_;
    const bool waiting = s.count > 0;
    const auto wait = waiting ? std::chrono::milliseconds(0)
                              : std::clamp(std::chrono::duration_cast<std::chrono::milliseconds>(
                                               next_stats - Clock::now()),
                                           std::chrono::milliseconds(0),
                                           std::chrono::milliseconds(reload_ ? 10 : 100));
    zmq::pollitem_t items[6] = {{s.sub.handle(), 0, ZMQ_POLLIN, 0},
                                {s.pub.handle(), 0, ZMQ_POLLIN, 0}};
    int n_items = 2;
    if (s.source) items[n_items++] = {s.source->socket().handle(), 0, ZMQ_POLLIN, 0};
    const int fixed_items = n_items;
    if (control.wake_fd >= 0) items[n_items++] = {nullptr, control.wake_fd, ZMQ_POLLIN, 0};
    if (s.monitor) items[n_items++] = {s.monitor.events().handle(), 0, ZMQ_POLLIN, 0};
    if (s.revival) items[n_items++] = {s.revival.events().handle(), 0, ZMQ_POLLIN, 0};
    try {
      zmq::poll(items, n_items, wait);
      if ((items[0].revents & ZMQ_POLLIN) || waiting) serve_input(s.sub);
      if (items[1].revents & ZMQ_POLLIN) read_subscriptions();
      if (fixed_items == 3 && (items[2].revents & ZMQ_POLLIN)) serve_input(state_->source->socket());
      if (state_->source) state_->source->log_changes();
      for (int k = fixed_items; k < n_items; ++k) {
        if (!(items[k].revents & ZMQ_POLLIN)) continue;
        if (items[k].socket == nullptr) {
          std::uint64_t count;
          (void)!::read(control.wake_fd, &count, sizeof count);  // the flags say what happened
        } else if (s.revival && items[k].socket == s.revival.events().handle()) {
          s.revival.read(Clock::now());
        } else {
          read_monitor();
        }
      }
    } catch (const zmq::error_t& e) {
      if (e.num() == ETERM) break;              // the context is going away
      if (e.num() != EINTR) internal_error("on the input: ", e.what());
      continue;  // a signal: look at the flags
    } catch (const std::exception& e) {
      internal_error("on the input: ", e.what());
    }
    const Clock::time_point now = Clock::now();
    if (model_pending_) want_model(now);  // the loop wakes at least every 100 ms
    try {
      if (state_->revival && state_->revival.rule().due(now))
        reconnect(state_->pub, state_->config.output.address, state_->revival.rule(),
                  counters_.output_reconnects, "the output's peer",
                  "not a subscriber socket, or it broke the protocol; stats: output_reconnects");
      if (state_->config.input.mode == SocketMode::connect && state_->input_revival.due(now))
        reconnect(state_->sub, state_->config.input.address, state_->input_revival,
                  counters_.input_reconnects, "the input's peer",
                  "not a publisher socket, a message over twice max_payload_bytes plus 4096, or it broke "
                  "the protocol; stats: input_reconnects");
    } catch (const std::exception& e) {
      internal_error("while connecting again: ", e.what());
    }
    if (now >= next_stats) {
      try {
        publish_stats(std::chrono::duration<double>(now - last_stats).count());
      } catch (const std::exception& e) {
        internal_error("while publishing stats: ", e.what());
      }
      last_stats = now;
    }
  }
  wait_for_reload_at_stop();
  spdlog::info("fabrikd: stopping after {} frames in, {} poses out", counters_.frames_in,
               counters_.frames_out);
}

}  // namespace fabrik::wire
