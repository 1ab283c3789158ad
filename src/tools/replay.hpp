// `fabrik replay`: streams a marker recording into fabrikd per the wire contract, at the
// recording's own rate (scaled by `speed`), on deadlines from one steady_clock origin so that
// late frames do not accumulate drift.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "io/marker_trial.hpp"
#include "io/orientation_table.hpp"
#include "wire.hpp"

namespace fabrik::tools {

// `--drop NAME:T0:T1`: marker NAME is sent as null for recording times in [T0, T1) seconds.
struct DropSpec {
  std::string marker;
  double t0_s = 0.0;
  double t1_s = 0.0;
};
// A command-line time field ("--drop 'A:x:2': T0 'x' is not a time in seconds >= 0 (expected
// NAME:T0:T1)"): throws std::invalid_argument unless `text` is a whole finite number >= 0.
double parse_seconds_field(const std::string& text, const std::string& option, const std::string& spec,
                           const std::string& field, const std::string& expected);

// Splits at the last two colons (Vicon labels look like "Subject:RASI"). Throws
// std::invalid_argument with a message that quotes the spec and says what is wrong.
DropSpec parse_drop_spec(const std::string& spec);

struct ReplayProgress {
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_total = 0;  // 0 when looping without --frames
  double elapsed_s = 0.0;
  double behind_ms = 0.0;  // how late the last frame left relative to its deadline
};

struct ReplayOptions {
  std::string endpoint;
  bool bind = false;   // default: connect (fabrikd binds its input)
  double speed = 1.0;  // 0: as fast as possible
  bool loop = false;
  std::vector<DropSpec> drops;
  WireEncoding encoding = WireEncoding::json;
  std::uint64_t max_frames = 0;  // 0: every frame (once, or forever with loop)
  // Wait until a subscriber to `markers` shows up before the first frame (PUB/SUB drops what
  // is sent before the subscription arrives). Negative: do not wait.
  double wait_subscriber_s = -1.0;
  // Sensor orientations sent with every frame (`orientations`), joined on
  // time: each marker frame takes the table's orientations at its file time
  // (MarkerTrial::file_time_s, interpolated), as `fabrik solve` does.
  // With a trial without markers, the table's rows are the frames, at its
  // times. Not owned; may be null.
  const io::OrientationTable* orientations = nullptr;
  std::function<bool()> stop_requested;                 // polled between frames
  std::function<void()> opened;                         // once the socket is bound or connected
  std::function<void(const ReplayProgress&)> progress;  // called at most once per interval
  std::chrono::milliseconds progress_interval{500};
};

struct ReplaySummary {
  std::uint64_t frames_sent = 0;
  std::uint64_t loops = 0;           // complete passes over the recording
  std::uint64_t markers_nulled = 0;   // null entries sent: missing + dropped
  std::uint64_t markers_missing = 0;  // null because the recording has no sample there
  std::uint64_t markers_dropped = 0;  // null because of --drop (the recording has a sample)
  std::uint64_t orientations_nulled = 0;  // null orientation entries sent (missing in the table)
  std::uint64_t late_frames = 0;     // left more than 1 ms after their deadline
  double max_behind_ms = 0.0;
  double elapsed_s = 0.0;
  bool stopped = false;  // by stop_requested
};

// Throws std::invalid_argument for bad options (unknown drop marker, empty recording, ...) and
// std::runtime_error when no subscriber showed up in time.
ReplaySummary replay_trial(zmq::context_t& context, const io::MarkerTrial& trial,
                           const ReplayOptions& options);

}  // namespace fabrik::tools
