#include "replay.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "transport/marker_codec.hpp"
#include "wire.hpp"

namespace fabrik::tools {

double parse_seconds_field(const std::string& text, const std::string& option, const std::string& spec,
                           const std::string& field, const std::string& expected) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v) || v < 0.0)
    throw std::invalid_argument(option + " '" + spec + "': " + field + " '" + text +
                                "' is not a time in seconds >= 0 (expected " + expected + ")");
  return v;
}

DropSpec parse_drop_spec(const std::string& spec) {
  const std::size_t c2 = spec.rfind(':');
  const std::size_t c1 =
      c2 == std::string::npos || c2 == 0 ? std::string::npos : spec.rfind(':', c2 - 1);
  if (c1 == std::string::npos)
    throw std::invalid_argument("--drop '" + spec +
                                "': expected NAME:T0:T1 (marker name, start and end in seconds)");
  DropSpec d;
  d.marker = spec.substr(0, c1);
  if (d.marker.empty())
    throw std::invalid_argument("--drop '" + spec + "': the marker name is empty");
  d.t0_s = parse_seconds_field(spec.substr(c1 + 1, c2 - c1 - 1), "--drop", spec, "T0", "NAME:T0:T1");
  d.t1_s = parse_seconds_field(spec.substr(c2 + 1), "--drop", spec, "T1", "NAME:T0:T1");
  if (!(d.t1_s > d.t0_s))
    throw std::invalid_argument("--drop '" + spec + "': T1 must be greater than T0");
  return d;
}

ReplaySummary replay_trial(zmq::context_t& context, const io::MarkerTrial& trial,
                           const ReplayOptions& options) {
  using Clock = std::chrono::steady_clock;
  const io::OrientationTable* table = options.orientations;
  // Without markers the orientation table's rows are the frames.
  const bool table_frames = table && trial.labels.empty();
  const std::size_t n = table_frames ? table->rows() : trial.frames();
  const double rate_hz = table_frames ? table->rate_hz : trial.rate_hz;
  if (n == 0) throw std::invalid_argument("the recording has no frames");
  if (!(rate_hz > 0.0)) throw std::invalid_argument("the recording has no frame rate");
  if (!(options.speed >= 0.0) || !std::isfinite(options.speed))
    throw std::invalid_argument("--speed must be >= 0 (0: as fast as possible)");
  struct Drop {
    int marker;
    double t0_s, t1_s;
  };
  std::vector<Drop> drops;
  for (const DropSpec& d : options.drops) {
    const int m = trial.find(d.marker);
    if (m < 0)
      throw std::invalid_argument("--drop: marker '" + d.marker + "' is not in the recording");
    drops.push_back({m, d.t0_s, d.t1_s});
  }

  // XPUB rather than PUB: it behaves the same but tells us when a subscriber arrives.
  zmq::socket_t pub(context, zmq::socket_type::xpub);
  pub.set(zmq::sockopt::linger, 5000);  // let queued frames out when we close
  pub.set(zmq::sockopt::sndhwm, 100000);
  open_endpoint(pub, options.endpoint, options.bind, "--to");
  if (options.opened) options.opened();

  if (options.wait_subscriber_s >= 0.0) {
    const auto deadline =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(options.wait_subscriber_s));
    for (bool subscribed = false; !subscribed;) {
      if (options.stop_requested && options.stop_requested()) return {.stopped = true};
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0)
        throw std::runtime_error("no subscriber to 'markers' on " + options.endpoint +
                                 " within the wait");
      wait_readable(pub, std::min(left, std::chrono::milliseconds(100)));
      zmq::message_t msg;
      while (receive_waiting(pub, msg)) {
        // Subscription messages are 0x01 + prefix; "markers" matches prefixes of it.
        const std::string_view s(msg.data<char>(), msg.size());
        if (!s.empty() && s[0] == 1 && std::string_view("markers").starts_with(s.substr(1)))
          subscribed = true;
      }
    }
  }

  const double duration_s = static_cast<double>(n) / rate_hz;
  const std::size_t n_sensors = table ? table->sensors.size() : 0;
  std::vector<Eigen::Quaterniond> q(n_sensors);
  std::vector<std::uint8_t> q_visible(n_sensors, 0);
  const wire::SensorSamples sensors{table ? std::span<const std::string>(table->sensors)
                                          : std::span<const std::string>(),
                                    q, q_visible};
  const std::uint64_t total = options.max_frames ? options.max_frames : options.loop ? 0 : n;
  std::vector<std::uint8_t> hidden(trial.markers(), 0), visible(trial.markers(), 0);
  std::vector<Eigen::Vector3d> p_m(trial.markers());
  std::string payload;
  ReplaySummary summary;
  const Clock::time_point start = Clock::now();
  Clock::time_point last_progress = start;
  zmq::message_t discard;
  for (std::uint64_t k = 0; total == 0 || k < total; ++k) {
    if (options.stop_requested && options.stop_requested()) {
      summary.stopped = true;
      break;
    }
    const std::size_t index = k % n;
    const std::uint64_t pass = k / n;
    if (pass > 0 && index == 0 && !options.loop) break;
    const double t_trial_s = table_frames ? table->time_s[index] - table->time_s.front()
                                          : trial.time_s(index);
    const double t_stream_s = static_cast<double>(pass) * duration_s + t_trial_s;
    std::fill(hidden.begin(), hidden.end(), 0);
    for (const Drop& d : drops)
      if (t_trial_s >= d.t0_s && t_trial_s < d.t1_s) hidden[d.marker] = 1;

    // Every deadline comes from `start`: a late frame does not delay the ones after it.
    Clock::time_point deadline = start;
    if (options.speed > 0.0) {
      deadline += std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(static_cast<double>(k) / rate_hz / options.speed));
      // In steps of at most 50 ms: Ctrl-C ends a slow replay (--speed 0.001) promptly.
      while (Clock::now() < deadline && !(options.stop_requested && options.stop_requested()))
        std::this_thread::sleep_until(
            std::min(deadline, Clock::now() + std::chrono::milliseconds(50)));
      if (options.stop_requested && options.stop_requested()) {
        summary.stopped = true;
        break;
      }
    }
    for (std::size_t m = 0; m < trial.markers(); ++m) {
      p_m[m] = trial.at(index, m);
      const bool recorded = p_m[m].allFinite();
      visible[m] = !hidden[m] && recorded ? 1 : 0;
      summary.markers_nulled += visible[m] ? 0 : 1;
      summary.markers_missing += recorded ? 0 : 1;
      summary.markers_dropped += recorded && hidden[m] ? 1 : 0;
    }
    if (table) {
      if (table_frames) {
        for (std::size_t k_s = 0; k_s < n_sensors; ++k_s) q[k_s] = table->at(index, k_s);
      } else {
        table->sample(trial.file_time_s(index), q);
      }
      for (std::size_t k_s = 0; k_s < n_sensors; ++k_s) {
        q_visible[k_s] = q[k_s].coeffs().allFinite() ? 1 : 0;
        summary.orientations_nulled += q_visible[k_s] ? 0 : 1;
      }
    }
    // Wall clock at sending, echoed by fabrikd in the pose: watchers on this
    // machine measure end-to-end latency from it.
    const double stamp_us =
        static_cast<double>(std::chrono::duration_cast<std::chrono::microseconds>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count());
    const std::uint64_t first_frame =
        table_frames ? static_cast<std::uint64_t>(
                           1 + std::llround(table->time_s.front() * table->rate_hz))
                     : static_cast<std::uint64_t>(trial.first_frame);
    wire::encode_marker_frame(first_frame + k, &t_stream_s,
                              trial.labels, p_m, visible, "mm",
                              options.encoding == WireEncoding::msgpack
                                  ? wire::PayloadEncoding::msgpack
                                  : wire::PayloadEncoding::json,
                              payload, &stamp_us, table ? &sensors : nullptr);
    send_part(pub, zmq::buffer(std::string_view("markers")), zmq::send_flags::sndmore);
    send_part(pub, zmq::buffer(payload), zmq::send_flags::none);
    while (receive_waiting(pub, discard)) {
    }  // subscription notices: keep XPUB's inbound queue empty

    const Clock::time_point now = Clock::now();
    const double behind_ms = options.speed > 0.0
                                 ? std::chrono::duration<double, std::milli>(now - deadline).count()
                                 : 0.0;
    if (behind_ms > 1.0) ++summary.late_frames;
    summary.max_behind_ms = std::max(summary.max_behind_ms, behind_ms);
    summary.frames_sent = k + 1;
    summary.loops = (k + 1) / n;
    if (options.progress && now - last_progress >= options.progress_interval) {
      last_progress = now;
      options.progress({summary.frames_sent, total,
                        std::chrono::duration<double>(now - start).count(), behind_ms});
    }
  }
  summary.elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

}  // namespace fabrik::tools
