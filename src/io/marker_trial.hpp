// Marker recordings in memory and the files that hold them: TRC (OpenSim, Mokka) text and C3D
// binary (Intel, DEC or MIPS number formats, int16 or float data). Readers convert to metres
// once, when they read, and mark missing samples NaN. Every problem with a file is a
// FormatError whose message starts with the file's path.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace fabrik::io {

// A marker recording in memory. Positions are in METRES (converted once, when read), NaN where a
// marker is missing.
struct MarkerTrial {
  std::vector<std::string> labels;           // marker names
  double rate_hz = 0.0;                      // frames per second
  int first_frame = 1;                       // number of the first frame in the source file
  std::vector<Eigen::Vector3d> positions_m;  // frame-major: [frame * labels.size() + marker]

  std::size_t frames() const { return labels.empty() ? 0 : positions_m.size() / labels.size(); }
  std::size_t markers() const { return labels.size(); }
  const Eigen::Vector3d& at(std::size_t frame, std::size_t marker) const {
    return positions_m[frame * labels.size() + marker];
  }
  Eigen::Vector3d& at(std::size_t frame, std::size_t marker) {
    return positions_m[frame * labels.size() + marker];
  }
  // Seconds since the first frame. TRC Time columns are rounded, so time comes from the frame
  // index and the rate instead.
  double time_s(std::size_t frame) const { return static_cast<double>(frame) / rate_hz; }
  // Index of the first marker named `label`, -1 if absent.
  int find(const std::string& label) const;
};

// A file that cannot be read (missing, truncated, malformed) or written. The message starts
// with the path and says what is wrong, e.g. "x.c3d: parameter section: POINT:LABELS missing".
class FormatError : public std::runtime_error {
 public:
  FormatError(const std::string& path, const std::string& problem)
      : std::runtime_error(path + ": " + problem), path_(path) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// TRC: tab-separated text. Units "mm" or "m"; an empty field, a short row or a "NaN" field is a
// missing marker. Throws FormatError.
MarkerTrial read_trc(const std::string& path);
// Writes an OpenSim/Mokka-compatible TRC (PathFileType 4, X/Y/Z), empty fields for missing
// markers, 6 decimals in mm or 9 in m (1 nm either way). Units "mm" or "m"; a label must be
// non-empty without tabs or line breaks (std::invalid_argument otherwise).
void write_trc(const std::string& path, const MarkerTrial& trial, const std::string& units = "mm");

struct C3dReadOptions {
  // Some exporters write a frame count larger than the data they store (the real Optotrak.c3d
  // test file declares 1149 frames and holds 29). By default such a file is rejected as
  // truncated; with this set, the complete frames it holds are returned.
  bool allow_truncated_data = false;
};
// C3D: 3D points only (analog data is skipped). Throws FormatError.
MarkerTrial read_c3d(const std::string& path, const C3dReadOptions& options = {});

// By extension, .trc or .c3d (any case); FormatError for anything else.
MarkerTrial read_trial(const std::string& path);

// Writes a C3D file in any processor's number format, with int16 (scaled) or float data, so
// the reader can be tested on every format without outside files. Missing markers get
// residual -1. Units "mm" or "m" (std::invalid_argument otherwise).
enum class C3dProcessor { intel, dec, mips };
void write_c3d(const std::string& path, const MarkerTrial& trial, C3dProcessor processor,
               bool float_data, const std::string& units = "mm");

}  // namespace fabrik::io
