/// @file
/// Marker recordings in memory and the files that hold them: TRC (OpenSim, Mokka) text and C3D
/// binary (Intel, DEC or MIPS number formats, int16 or float data). Readers convert to metres
/// once, when they read, and mark missing samples NaN. Every problem with a file is a
/// FormatError whose message starts with the file's path; what a reader noticed and worked
/// around is returned in MarkerTrial::warnings (the library does not log).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

/// Files: marker recordings (TRC, C3D) read into metres, and OpenSim tables (.sto, .mot).
namespace fabrik::io {

/// A label written on two markers: which one a model marker of that name means is ambiguous.
struct RepeatedLabel {
  std::string label;  ///< the label, as written
  /// As the file numbers them: TRC columns of the two X values (Frame# is column 1, so the first
  /// marker's X is 3); C3D entries of POINT:LABELS (from 1).
  std::size_t first = 0, second = 0;
  /// @var second
  /// The second of the two markers, numbered as `first` is.
};

/// TRC rows whose Time is not after the previous row's.
struct TimeSteps {
  std::size_t rows = 0;                   ///< how many
  long long first_frame = 0;              ///< Frame# of the first of them
  std::size_t first_line = 0;             ///< and its line in the file
  /// Its Time, seconds.
  double time_s = 0.0, previous_s = 0.0;  ///< its Time and the previous row's
};

/// No marker set on people spans this in one frame (a gym is 30 m): a file whose markers do is
/// in another unit than it says (mm labelled m).
inline constexpr double kLargestMarkerSpan_m = 100.0;
/// Nor this little (a hand's cluster spreads over 50 mm): metres labelled mm.
inline constexpr double kSmallestMarkerSpan_m = 0.01;

/// What a file says about itself beyond the markers' positions: for messages and `fabrik info`.
struct RecordingFacts {
  std::string format;         ///< "TRC" or "C3D" (empty for trials made in memory)
  std::string number_format;  ///< "text", or the C3D processor and type: "Intel float", "DEC int16"
  std::string units;          ///< the file's length unit as written ("mm", "MM", "m", "cm")
  std::size_t frames = 0;     ///< frames the file holds, also when it holds no 3D points
  /// Per marker: samples that were exactly (0, 0, 0), which several exporters write for "not
  /// seen". Read as missing unless ReadOptions::zeros_are_missing is false.
  std::vector<std::size_t> zero_samples;
  /// The markers' spread in a typical frame (metres): twice their median distance from the
  /// frame's per-axis median, the median over up to 200 frames with 3 markers or more (one
  /// marker or a few frames of garbage do not move it); NaN when none has. Past
  /// kLargestMarkerSpan_m or below kSmallestMarkerSpan_m the file's unit is wrong (the commands
  /// refuse it).
  double typical_span_m = std::numeric_limits<double>::quiet_NaN();
  /// Set (a sentence with its fix, also among the warnings) when typical_span_m is past
  /// kLargestMarkerSpan_m or below kSmallestMarkerSpan_m: the commands refuse the file.
  std::string unit_problem;
  /// C3D analog channels and rotations: counted and named, their data is not read.
  std::size_t analog_channels = 0;
  double analog_rate_hz = 0.0;               ///< analog samples per second (0: no channels)
  std::vector<std::string> analog_labels;    ///< ANALOG:LABELS, per channel
  std::size_t rotations = 0;                 ///< ROTATION:USED: rotations per frame
  std::vector<std::string> rotation_labels;  ///< ROTATION:LABELS, per rotation
  /// Labels on more than one marker (each repetition once), TRC or C3D.
  std::vector<RepeatedLabel> repeated_labels;
  /// A TRC Time column that goes back (OpenSim refuses the file) or stands still (repeated
  /// values, e.g. times rounded at a high rate: harmless here, time comes from the rate).
  TimeSteps time_backwards, time_standing;
  /// @var time_standing
  /// TRC rows whose Time equals the previous row's (a warning only).
};

/// The lowest frame rate a recording may have (a frame every 17 minutes); below it a header is
/// corrupt, not a capture.
inline constexpr double kMinFrameRateHz = 1e-3;
/// The highest frame rate a recording may have (100 times the fastest mocap camera).
inline constexpr double kMaxFrameRateHz = 1e6;
/// Whether `rate_hz` is within [kMinFrameRateHz, kMaxFrameRateHz] (false for NaN).
inline bool plausible_frame_rate(double rate_hz) {
  return rate_hz >= kMinFrameRateHz && rate_hz <= kMaxFrameRateHz;
}

/// How a source numbers and times its frames, to name them in outputs as the source does.
struct FrameClock {
  int first_frame = 1;  ///< number of the first frame
  /// The source's time of the first frame in frame periods; NaN: first_frame - 1 (MarkerTrial).
  double first_time_frames = std::numeric_limits<double>::quiet_NaN();
  double rate_hz = 0.0;  ///< frames per second

  /// The source's number of frame `index` (from 0): first_frame + index.
  long long number(std::size_t index) const {
    return static_cast<long long>(first_frame) + static_cast<long long>(index);
  }
  /// (first_time_frames + index) / rate.
  double time_s(std::size_t index) const {
    const double first = std::isnan(first_time_frames) ? first_frame - 1.0 : first_time_frames;
    return (first + static_cast<double>(index)) / rate_hz;
  }
};

/// A marker recording in memory. Positions are in METRES (converted once, when read), NaN where a
/// marker is missing.
struct MarkerTrial {
  std::vector<std::string> labels;           ///< marker names
  double rate_hz = 0.0;                      ///< frames per second
  int first_frame = 1;                       ///< number of the first frame in the source file
  /// The source's time of the first frame, in frame periods (a TRC's first Time times its
  /// rate, on the frame grid when it is within rounding of it). NaN when the source says
  /// nothing (C3D, trials made in memory): first_frame - 1, so frame 1 is at 0 s as OpenSim
  /// reads a TRC that starts at frame 1.
  double first_time_frames = std::numeric_limits<double>::quiet_NaN();
  std::vector<Eigen::Vector3d> positions_m;  ///< frame-major: [frame * labels.size() + marker]
  RecordingFacts source;                     ///< filled by the readers
  /// What the reader found odd and how it read it, one sentence each, e.g. "header: NumFrames is
  /// 200 but the file has 151 data rows: read 151". Commands print them.
  std::vector<std::string> warnings;

  /// Number of frames (0 when there are no markers).
  std::size_t frames() const { return labels.empty() ? 0 : positions_m.size() / labels.size(); }
  std::size_t markers() const { return labels.size(); }  ///< number of markers
  /// Position of `marker` in `frame` (both from 0), metres; NaN when missing.
  const Eigen::Vector3d& at(std::size_t frame, std::size_t marker) const {
    return positions_m[frame * labels.size() + marker];
  }
  /// The same, writable (metres; NaN marks a missing sample).
  Eigen::Vector3d& at(std::size_t frame, std::size_t marker) {
    return positions_m[frame * labels.size() + marker];
  }
  /// Seconds since the first frame. TRC Time columns are rounded, so time comes from the frame
  /// index and the rate instead.
  double time_s(std::size_t frame) const { return static_cast<double>(frame) / rate_hz; }
  /// The frame's time as the source counts it: (first_time_frames + frame) / rate. Outputs
  /// (.mot, .trc, reports) carry these times, so they line up with the source and OpenSim.
  double file_time_s(std::size_t frame) const { return clock().time_s(frame); }
  /// How the source numbers and times the frames (first_frame, first_time_frames, rate_hz).
  FrameClock clock() const { return {first_frame, first_time_frames, rate_hz}; }
  /// Index of the first marker named `label`, -1 if absent.
  int find(const std::string& label) const;
};

/// A file that cannot be read (missing, truncated, malformed) or written. The message starts
/// with the path and says what is wrong, e.g. "x.c3d: parameter section: POINT:LABELS missing".
class FormatError : public std::runtime_error {
 public:
  /// what() is "PATH: PROBLEM".
  FormatError(const std::string& path, const std::string& problem)
      : std::runtime_error(path + ": " + problem), path_(path) {}
  const std::string& path() const { return path_; }  ///< the file, as given

 private:
  std::string path_;
};

/// How strictly the readers (read_trc, read_c3d, read_trial) take a file.
struct ReadOptions {
  /// Some exporters write a frame count larger than the data they store (the real Optotrak.c3d
  /// test file declares 1149 frames and holds 29). By default such a C3D file is rejected as
  /// truncated; with this set, the complete frames it holds are returned. (A TRC file's data
  /// rows are always trusted over its NumFrames, with a warning.)
  bool allow_truncated_data = false;
  /// An exact (0, 0, 0) sample is a marker that was not seen (several exporters write it so).
  /// False keeps such samples as positions at the origin.
  bool zeros_are_missing = true;
  /// A label on two markers (TRC or C3D: which column is the marker?) and a TRC Time column that
  /// goes back (OpenSim's TimeSeriesTable refuses it), and a TRC cut short inside its last row,
  /// are FormatErrors naming the columns or the row and the fix. False (`fabrik info`) reads such a
  /// file, records them in `source` and says so in `warnings`. A Time column that stands still is a
  /// warning either way.
  bool refuse_ambiguous = true;
};
/// The former name of ReadOptions, when they were for C3D only.
using C3dReadOptions = ReadOptions;

/// TRC: tab-separated text as OpenSim reads it: header values separated by any run of
/// whitespace; units mm, cm or m in any case; an empty field, a short row or a "NaN" field is a
/// missing marker; the data rows are trusted over NumFrames/NumMarkers (with a warning). What a
/// file can cost is bounded: a row may not be longer than its columns could need
/// (kTrcBytesPerField each, plus slack), and the positions may not take more than 64 times the
/// file's size (16 MiB at least; short rows are cheap to write but cost 24 bytes a marker).
/// Throws FormatError.
MarkerTrial read_trc(const std::string& path, const ReadOptions& options = {});
/// The longest a TRC field may be, in bytes, in read_trc's bound on a row's length.
inline constexpr std::size_t kTrcBytesPerField = 256;
/// Writes an OpenSim/Mokka-compatible TRC (PathFileType 4, X/Y/Z), empty fields for missing
/// markers, 6 decimals in mm or 9 in m (1 nm either way). Units "mm" or "m"; a label must be
/// non-empty without tabs or line breaks (std::invalid_argument otherwise).
void write_trc(const std::string& path, const MarkerTrial& trial, const std::string& units = "mm");

/// C3D: 3D points (analog channels and rotations are counted in `source`, not read). A file
/// whose POINT:DATA_START or POINT:FRAMES disagrees with its header is read as the data allow,
/// with a warning. Throws FormatError.
MarkerTrial read_c3d(const std::string& path, const ReadOptions& options = {});

/// By extension, .trc or .c3d (any case); FormatError for anything else.
MarkerTrial read_trial(const std::string& path, const ReadOptions& options = {});

/// Throws FormatError(path, ...) unless the trial has at least one marker and one frame, saying
/// what the file holds instead, e.g. "the file has no 3D marker data; it has 38 analog channels".
void require_marker_data(const MarkerTrial& trial, const std::string& path);

/// A C3D file's number format, named by its processor: Intel (little-endian IEEE), DEC
/// (little-endian integers, VAX F-floating) or MIPS (big-endian IEEE).
enum class C3dProcessor { intel, dec, mips };
/// How write_c3d writes a file: its number format and units, and for tests of the reader, what
/// other writers do.
struct C3dWriteOptions {
  C3dProcessor processor = C3dProcessor::intel;  ///< the number format
  bool float_data = true;                        ///< float data; false: int16 scaled by POINT:SCALE
  std::string units = "mm";                      ///< the length unit (POINT:UNITS): "mm" or "m"
  /// What other writers do, for tests of the reader:
  /// analog channels sampled `analog_samples_per_frame` times per frame (a ramp per channel);
  std::size_t analog_channels = 0;
  std::size_t analog_samples_per_frame = 1;  ///< analog samples per channel per frame
  /// rotations (ROTATION group, identity matrices after the point data);
  std::size_t rotations = 0;
  /// frames written when the trial has no markers (an analog- or rotation-only file);
  std::size_t frames_without_points = 0;
  /// POINT:DATA_START written as 0 while the header's data-start word stays right (a DEC
  /// exporter does this);
  bool point_data_start_zero = false;
  /// no TRIAL group (so the header's 16-bit frame numbers count), and the header's first frame
  /// word written as this value, the last as first + frames - 1 modulo 65536 (0: first_frame);
  bool trial_group = true;
  unsigned header_first_frame = 0;  ///< the header's first frame word (see trial_group)
  /// POINT:FRAMES written as this value (-1: the number of frames modulo 65536).
  long point_frames = -1;
};
/// Writes a C3D file in any processor's number format, with int16 (scaled) or float data, so
/// the reader can be tested on every format without outside files. Missing markers get
/// residual -1. Units "mm" or "m" (std::invalid_argument otherwise).
void write_c3d(const std::string& path, const MarkerTrial& trial, const C3dWriteOptions& options);
/// The same with the number format and units only (the other options at their defaults).
void write_c3d(const std::string& path, const MarkerTrial& trial, C3dProcessor processor,
               bool float_data, const std::string& units = "mm");

}  // namespace fabrik::io
