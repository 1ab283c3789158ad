// fabrikd's loop: marker frames in on a SUB socket, poses and stats out on a
// PUB socket (../shared/wire-contract.md, proto/). One thread serves frames:
// before each solve it drains whatever ZeroMQ has queued (cheaply, without
// decoding) into a ring of at most `max_backlog_frames` messages, then
// decodes, solves and publishes the oldest one. A short stall of the thread
// loses nothing; when more frames pile up than the ring holds, the daemon is
// behind: it drops what is queued and answers the newest frame it has, until
// it has caught up (every dropped frame is counted). Publishing never blocks
// (PUB drops for a slow subscriber), stats go out every interval, and a
// config reload is read and validated on a thread of its own, so frames are
// answered throughout. Nothing one message does (bad bytes, absurd numbers,
// an exception, an allocation failure) leaves the loop: it is counted,
// logged at most once a second, and the next frame is served.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <unordered_set>
#include <vector>
#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "config/topics.hpp"
#include "frame_stages.hpp"
#include "interval_stats.hpp"
#include "marker_codec.hpp"
#include "name_mismatch.hpp"
#include "pose_codec.hpp"
#include "rate_limited_log.hpp"
#include "safe_text.hpp"
#include "source_input.hpp"

namespace fabrik::wire {

class RevivalRule;

struct DaemonCounters {
  std::uint64_t frames_in = 0;        // messages received on the input
  std::uint64_t frames_out = 0;       // poses made (encoded and sent only while pose_subscribers > 0)
  std::uint64_t frames_dropped = 0;   // frames superseded by newer ones before solving
  std::uint64_t decode_errors = 0;    // messages refused (format, types, size, parts, topic)
  std::uint64_t unknown_markers = 0;  // marker entries whose name is not in the model
  std::uint64_t reloads = 0, reload_errors = 0;
  std::uint64_t rejected_coordinates = 0;  // markers beyond input.max_abs_coordinate_mm
  std::uint64_t zero_markers = 0;          // markers at exactly (0, 0, 0), taken as missing
  std::uint64_t internal_errors = 0;       // exceptions caught in the loop (frame, stats)
  std::uint64_t input_disconnects = 0;     // input peers gone (quit, or dropped by ZeroMQ)
  std::uint64_t accept_failures = 0;       // input connections ZeroMQ could not accept
  std::uint64_t rejected_orientations = 0;  // sensor quaternions not usable (length, NaN, not unit)
  std::uint64_t unknown_sensors = 0;        // orientation entries whose sensor is not in the config
  std::uint64_t unmatched_frames = 0;  // frames whose marker names are all unknown to the config
  bool config_mismatch = false;        // the latest such frames share no name with the config
  std::uint64_t outliers = 0;          // measured markers left out of a solve as outliers
  std::uint64_t poor_frames = 0;       // poses whose residual.quality was poor
  std::uint64_t subscriptions_refused = 0;  // output subscriptions to no topic of ours (peer dropped)
  std::uint64_t unsubscriptions_ignored = 0;  // of nothing counted, or not its sender's (SubscriptionBook)
  std::uint64_t output_reconnects = 0;  // a connected output connected again after ZeroMQ gave up its peer
  std::uint64_t input_reconnects = 0;   // a connected input, likewise
  std::uint64_t other_subject_frames = 0;  // frames whose "subject" the config does not list
  std::uint64_t pose_subscribers = 0;  // live output subscriptions that receive poses (a gauge)
};

// One subject's counts (multi-subject configs; DaemonConfig::subjects order).
struct SubjectCounters {
  std::uint64_t frames_out = 0;   // its poses published
  std::uint64_t appearances = 0;  // times it was seen after being absent (or never seen): cold starts
  std::uint64_t departures = 0;   // times it was unseen for longer than subject_timeout_s
  bool present = false;           // getting poses
};

// Signals to the loop, set from another thread or a signal handler (the
// atomics are lock-free, so storing to them is async-signal-safe).
struct DaemonControl {
  std::atomic<bool> stop{false};
  std::atomic<bool> reload{false};
  // Written to (8 bytes, as to an eventfd) by whoever sets a flag, so that
  // the loop wakes at once whichever thread the signal landed on; -1: none,
  // the loop then looks at the flags every 100 ms.
  int wake_fd = -1;
};
static_assert(std::atomic<bool>::is_always_lock_free);

// Transport limits (docs/overload.md).
// Each subscriber's queue in the PUB socket (ZMQ_SNDHWM), in messages: the
// poses of one catch-up burst (max_backlog_frames) and a stats message, times
// two because a PUB socket learns what its subscriber has read only in
// batches of half its queue. A stalled subscriber holds up at most this many
// stale poses here (plus a few in kernel buffers), then PUB drops for it.
inline int pose_queue_messages(int max_backlog_frames) {
  return 2 * (max_backlog_frames + 4);
}
// Kernel send buffer per subscriber connection (bytes; the kernel doubles
// it): small, so that a stalled subscriber does not have seconds of poses
// waiting in the kernel, large enough for 1 kHz of full-body poses over a
// link with a few milliseconds of round trip.
constexpr int kPoseSendBufferBytes = 16 * 1024;
// Memory for messages waiting on the input (ZeroMQ's queue, and the ring):
// ZMQ_RCVHWM is this over ZMQ_MAXMSGSIZE (twice input.max_payload_bytes),
// within [16, 1000].
constexpr std::size_t kInputQueueBytes = std::size_t{64} << 20;
// Kernel receive buffer per input connection (bytes): frames that wait in
// front of ZeroMQ's queue are bounded too (the source's own queue is its
// business: docs/overload.md).
constexpr int kInputReceiveBufferBytes = 256 * 1024;
// What a subscriber may send to the output socket (docs/overload.md).
// fabrikd publishes only these topics, so a subscription that is
// not a prefix of one of them can never match: it is refused and its
// connection dropped. ZeroMQ keeps every subscription it is sent in a tree
// (about 32 bytes per subscribed byte, never given back while connected), so
// refusing them is what bounds a subscriber's memory.
// (kPublishedTopics: config/topics.hpp.)
bool subscribes_to_our_topics(std::string_view prefix);
// The same with a config's other topics too: a multi-subject config's
// (pose/NAME, model/NAME) and its views' (output.views).
bool subscribes_to_our_topics(std::string_view prefix, std::span<const std::string> extra_topics);
// Whether a subscription to `prefix` receives the topic `model` (sent to it
// when the subscription arrives: Daemon::read_subscriptions).
inline bool subscribes_to_model(std::string_view prefix) {
  return std::string_view("model").starts_with(prefix);
}
// Whether `fd` is still a connection to the socket bound at `endpoint` (as
// ZeroMQ reports it: tcp://host:port or ipc://path), and not a listener:
// the descriptor a refused message came from may have been reused since.
bool connected_to(int fd, std::string_view endpoint);
// Messages larger than this from a subscriber make ZeroMQ drop it before
// buffering. ZeroMQ checks the frame on the wire: libzmq 4.3 sends a subscription
// as ZMTP 3.1's SUBSCRIBE command, "\x09SUBSCRIBE" and the prefix (19 bytes for
// "stats"); older peers send "\x01" and the prefix. Room for the longest topic.
constexpr std::int64_t kMaxSubscriptionBytes = static_cast<std::int64_t>(kLongestTopicBytes) + 10;
// What ZeroMQ reads ahead of the loop from one subscriber: at most this many
// messages in its queue (ZMQ_RCVHWM of the output socket) and this many
// bytes in the kernel (ZMQ_RCVBUF; the kernel doubles it). ZeroMQ stores the
// subscriptions it reads before the loop can refuse them, so these bound
// what a hostile subscriber costs before it is dropped.
constexpr int kSubscriptionQueueMessages = 1;
constexpr int kSubscriberReceiveBufferBytes = 2048;
// A connection that has not completed ZeroMQ's handshake by then is closed
// (idle or foreign TCP connections do not hold file descriptors for long).
constexpr int kHandshakeTimeoutMs = 5000;

class Daemon {
 public:
  // Opens the sockets (bind or connect per config). Throws ConfigError
  // (at /input/endpoint or /output/endpoint, with a fix) when one cannot be opened.
  // `source_client` makes the client of the config's source (tests and
  // benchmarks hand in their own); empty: make_source_client.
  using SourceClientFactory = std::function<SourceClient(const SourceConfig&)>;
  Daemon(zmq::context_t& context, DaemonConfig config, SourceClientFactory source_client = {});
  ~Daemon();

  // Runs until control.stop. On control.reload, calls load_config() on a
  // thread of its own and switches to the new config when it is ready; if it
  // throws, the old one stays and the error is counted and logged.
  void run(DaemonControl& control, const std::function<DaemonConfig()>& load_config = {});

  // The endpoints as opened (a "tcp://127.0.0.1:*" bind resolves to its port).
  std::string input_endpoint() const;
  std::string output_endpoint() const;
  DaemonCounters counters() const;
  // Per subject of a multi-subject config, in its order (empty: one subject).
  std::vector<SubjectCounters> subject_counters() const;
  // The running config; not to be used across a reload.
  const DaemonConfig& config() const;
  // The frame path alone, for benchmarks: serves `payload` as if it had just
  // been taken off the input (decode, solve, encode, publish, counted in
  // stats) and returns its stages, all zero when it was refused. Only while
  // run() is not running.
  FrameStages serve_payload(std::span<const std::uint8_t> payload);
  // run() returned while a reload was still being read (it waits a little
  // for it): that thread was left running with data of its own; end the
  // process without unwinding (std::_Exit) rather than returning from main.
  bool reload_abandoned() const { return reload_abandoned_; }

 private:
  struct State;      // everything that a reload replaces
  struct ReloadJob;  // a reload in progress, shared with its thread
  static std::unique_ptr<State> prepare_state(DaemonConfig config);
  void attach_sockets(State& next, State* old);
  void switch_to(std::unique_ptr<State> next);
  void log_endpoints() const;  // where markers come in and poses go out
  void start_reload(const std::function<DaemonConfig()>& load_config);
  void finish_reload();
  void wait_for_reload_at_stop();

  void serve_input(zmq::socket_t& in);
  int drain_input(zmq::socket_t& in, int budget);
  void serve_frame(std::span<const std::uint8_t> payload,
                   std::chrono::steady_clock::time_point received);
  void publish_pose(const MarkerFrame& f, std::chrono::steady_clock::time_point received,
                    std::chrono::steady_clock::time_point decoded);
  struct SubjectState;
  static bool other_subject(const State& s, std::string_view name);
  // A multi-subject frame: each subject seen in it (or only `only`, for a
  // frame with "subject") tracked and published on pose/NAME.
  void publish_subjects(const MarkerFrame& f, SubjectState* only,
                        std::chrono::steady_clock::time_point received,
                        std::chrono::steady_clock::time_point decoded);
  // Tracks one frame of measurements and publishes its pose on `topic`; false
  // when the pose could not be made finite (nothing published).
  struct Measurements {
    std::span<const Eigen::Vector3d> p_world_m;
    std::span<const std::uint8_t> visible;
    std::span<const Eigen::Quaterniond> q_sensor;
    std::span<const std::uint8_t> sensor_visible;
    std::span<const float> confidence;  // empty: the frame carried none (all 1)
  };
  // The pose only while `pose_subscribers` > 0, then each of `views` that a
  // subscription selects, on its own topic. `subject_frames_out` (a subject's
  // count) is raised with the daemon's, before the pose goes out.
  struct ViewState;
  bool track_and_publish(Tracker& tracker, const PoseEncoder& encoder, const char* topic,
                         int pose_subscribers, std::span<ViewState> views,
                         const MarkerFrame& f, double time_s,
                         const Measurements& m,
                         std::chrono::steady_clock::time_point received,
                         std::chrono::steady_clock::time_point decoded,
                         std::uint64_t* subject_frames_out = nullptr);
  void read_monitor();
  void reconnect(zmq::socket_t& socket, const std::string& endpoint, RevivalRule& rule,
                 std::uint64_t& count, std::string_view what, std::string_view why);
  void read_subscriptions();
  // Who receives each pose topic and each view, from the output's live subscriptions.
  void count_subscribers(State& s);
  void publish_stats(double interval_s);
  void publish_model();
  // Publishes the model now, or within kModelInterval of the last one: a
  // subscriber toggling subscriptions cannot make the loop publish at will.
  void want_model(std::chrono::steady_clock::time_point now);
  void send(const char* topic, const std::string& payload);
  void bad_input(std::string_view what, std::string_view detail,
                 std::string_view after = {}) noexcept;
  void internal_error(std::string_view where, std::string_view what) noexcept;
  void update_snapshot();
  // Logs, once, that the stream's names share none with the config, beside the closest ones.
  void warn_config_mismatch(const MarkerFrame& f);

  zmq::context_t& context_;
  SourceClientFactory source_client_;
  std::unique_ptr<State> state_;
  std::shared_ptr<ReloadJob> reload_;
  bool reload_abandoned_ = false;
  DaemonCounters counters_;
  mutable std::mutex snapshot_mutex_;  // counters() may be called from other threads
  DaemonCounters snapshot_;
  std::vector<SubjectCounters> subject_counts_, subject_snapshot_;  // sized at each (re)load
  std::chrono::steady_clock::time_point started_;
  bool model_pending_ = false;  // asked for within kModelInterval of the last one
  std::chrono::steady_clock::time_point last_model_{};
  IntervalSamples solve_us_, queue_us_;
  StageSamples stages_us_;
  FrameStages last_stages_;  // the latest frame's, zero when it was refused
  std::uint64_t interval_frames_out_ = 0;
  FixedText<256> last_error_;  // never allocates: survives an out-of-memory error path
  // Looked up by string_view (transparent): a name already reported costs no allocation.
  struct NameHash {
    using is_transparent = void;
    std::size_t operator()(std::string_view name) const { return std::hash<std::string_view>{}(name); }
  };
  std::unordered_set<std::string, NameHash, std::equal_to<>> unknown_seen_;
  RateLimitedLog bad_input_log_, send_log_, internal_log_, peer_log_, subscriber_log_,
      other_subject_log_;
  bool overloaded_ = false;  // behind the input: answer only the newest frame
  zmq::message_t topic_, payload_, extra_, subscription_;
  std::string out_, view_out_, stats_out_, decode_error_;
};

}  // namespace fabrik::wire
