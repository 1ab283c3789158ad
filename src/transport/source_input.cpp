#include "source_input.hpp"

#include <atomic>

#include "safe_text.hpp"
#include "source_frames.hpp"

namespace fabrik::wire {

namespace {

// The client's side: each frame encoded and pushed, never blocking the client.
class PushSink final : public bridges::FrameSink {
 public:
  PushSink(zmq::socket_t& push, SourceFrames& frames, bridges::SourceStatus& status,
           std::atomic<std::uint64_t>& dropped, PendingNames& taken)
      : push_(push), frames_(frames), status_(status), dropped_(dropped), taken_(taken) {
    payload_.reserve(1 << 16);
  }
  void labels(std::span<const std::string> names) override {
    try {
      taken_.apply_to(frames_);
      frames_.labels(names);
    } catch (const std::exception& e) {
      status_.error(std::string("could not take the server's names: ") + e.what());
    }
  }
  void up_axis(std::string_view axis) override {
    try {
      if (std::string note = frames_.server_up(axis); !note.empty()) status_.notice(note);
    } catch (const std::exception& e) {
      status_.error(std::string("could not take the server's up axis: ") + e.what());
    }
  }
  void frame(std::uint64_t frame_number, double time_s,
             std::span<const Eigen::Vector3d> p_server_mm) override {
    try {
      taken_.apply_to(frames_);
      frames_.encode(frame_number, time_s, p_server_mm, payload_);
      if (!push_.send(zmq::buffer(std::string_view("markers")),
                      zmq::send_flags::sndmore | zmq::send_flags::dontwait)) {
        ++dropped_;
        return;
      }
      (void)push_.send(zmq::buffer(payload_), zmq::send_flags::dontwait);  // parts go together
      // Not counted here: the client counts each frame it hands over
      // (SourceStatus::frame_delivered); counting again doubled stats' frames.
    } catch (const std::exception& e) {
      status_.error(std::string("could not hand a frame to the loop: ") + e.what());
    }
  }

 private:
  zmq::socket_t& push_;
  SourceFrames& frames_;
  bridges::SourceStatus& status_;
  std::atomic<std::uint64_t>& dropped_;
  PendingNames& taken_;
  std::string payload_;
};

std::string fresh_endpoint() {
  static std::atomic<int> sources{0};
  return "inproc://fabrikd-source-" + std::to_string(++sources);
}

}  // namespace

SourceInput::SourceInput(zmq::context_t& context, const SourceConfig& source, const LabAxes& lab,
                         std::vector<std::string> taken, SourceClient client)
    : config_(source),
      lab_(lab),
      endpoint_(fresh_endpoint()),
      pull_(context, zmq::socket_type::pull) {
  taken_.put(std::move(taken));  // before the thread starts: it takes them first
  pull_.set(zmq::sockopt::linger, 0);
  pull_.set(zmq::sockopt::rcvhwm, kSourceQueueMessages);
  pull_.bind(endpoint_);
  thread_ = std::jthread([this, &context, client = std::move(client)](std::stop_token stop) {
    run(stop, context, client);
  });
}

SourceInput::~SourceInput() {
  thread_.request_stop();
  if (thread_.joinable()) thread_.join();
}

void SourceInput::run(std::stop_token stop, zmq::context_t& context, SourceClient client) {
  try {
    zmq::socket_t push(context, zmq::socket_type::push);
    push.set(zmq::sockopt::linger, 0);
    push.set(zmq::sockopt::sndhwm, kSourceQueueMessages);
    push.connect(endpoint_);
    SourceFrames frames(config_, lab_, taken_.take());
    PushSink sink(push, frames, status_, frames_dropped_, taken_);
    client(sink, status_, stop);
  } catch (const std::exception& e) {  // the context went away, or no memory for the socket
    status_.error(std::string("source stopped: ") + e.what());
  }
}

void SourceInput::retake(std::vector<std::string> taken) {
  taken_.put(std::move(taken));
}

void PendingNames::put(std::vector<std::string> names) {
  std::lock_guard lock(mutex_);
  names_.swap(names);  // the names replaced leave with `names`, after the lock
  pending_.store(true, std::memory_order_release);
}

std::vector<std::string> PendingNames::take() {
  std::vector<std::string> names;
  std::lock_guard lock(mutex_);
  names.swap(names_);
  pending_.store(false, std::memory_order_relaxed);
  return names;
}

// Mapped outside the lock: the loop's put waits for no more than a swap.
void PendingNames::apply_to(SourceFrames& frames) {
  if (!pending_.load(std::memory_order_acquire)) return;
  std::vector<std::string> names = take();
  try {
    frames.retake(names);
  } catch (...) {
    std::lock_guard lock(mutex_);
    if (!pending_.load(std::memory_order_relaxed)) {
      names_.swap(names);
      pending_.store(true, std::memory_order_release);
    }
    throw;
  }
}

SourceInput::Status SourceInput::status() const {
  return {status_.snapshot(), frames_dropped_.load()};
}

void SourceInput::log_changes() {
  const bridges::SourceStatus::Snapshot now = status_.snapshot();
  const std::string url = safe_text(config_.url, 128);
  // Motive says nothing of its axes over NatNet: a Z-up Motive read as Y-up gives pelvis
  // angles at gimbal lock with a "good" fit. Said once, where the user looks.
  const bool axes_assumed = config_.kind == SourceKind::natnet && !config_.axes;
  if (now.connections != logged_.connections && now.connected)
    spdlog::info("source {}: connected to {}{}{}", url, safe_text(now.server, 128),
                 now.reconnects > 0 ? fmt::format(" (reconnect {})", now.reconnects) : "",
                 axes_assumed && now.connections == 1
                     ? "; Motive's axes taken as its default, Y up and forward +x (NatNet does "
                       "not state them): if Motive streams Z up, set source_options.axes"
                     : "");
  else if (logged_.connected && !now.connected)
    spdlog::warn("source {}: connection lost: {}", url, safe_text(now.last_error, 240));
  if (now.notices != logged_.notices && now.last_notice != logged_.last_notice)
    spdlog::warn("source {}: {}", url, safe_text(now.last_notice, 400));
  if (now.errors != logged_.errors && !(logged_.connected && !now.connected))
    error_log_.warn("source {}: {}", url, safe_text(now.last_error, 240));
  logged_ = now;
}

}  // namespace fabrik::wire
