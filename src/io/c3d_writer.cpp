// C3D writer (see c3d_format.hpp): any processor's number format, int16 or float data, and the
// quirks of other writers on request (C3dWriteOptions), so the reader is tested on files the
// tests make.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/c3d_format.hpp"
#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"

namespace fabrik::io {

namespace {
using c3d::kBlockBytes;
using c3d::Numbers;

// Builds a parameter section's records; each record's "next" offset is patched when the
// following record starts, and the last keeps 0, which ends the list.
class ParameterWriter {
 public:
  explicit ParameterWriter(Numbers num) : num_(num) {}

  void group(int id, std::string_view name) {
    start(static_cast<std::int8_t>(-id), name);
    bytes_.push_back(0);  // no description
  }
  void int16s(int group, std::string_view name, const std::vector<std::uint16_t>& values,
              bool scalar) {
    start(static_cast<std::int8_t>(group), name);
    bytes_.push_back(2);
    dims(scalar ? std::vector<std::size_t>{} : std::vector<std::size_t>{values.size()});
    for (std::uint16_t v : values) {
      bytes_.resize(bytes_.size() + 2);
      num_.put_u16(&bytes_[bytes_.size() - 2], v);
    }
    bytes_.push_back(0);
  }
  void float32(int group, std::string_view name, float value) {
    start(static_cast<std::int8_t>(group), name);
    bytes_.push_back(4);
    dims({});
    bytes_.resize(bytes_.size() + 4);
    num_.put_f32(&bytes_[bytes_.size() - 4], value);
    bytes_.push_back(0);
  }
  // Strings padded with spaces to the longest; one string is stored 1-D.
  void chars(int group, std::string_view name, const std::vector<std::string>& values) {
    start(static_cast<std::int8_t>(group), name);
    bytes_.push_back(static_cast<std::uint8_t>(-1));
    std::size_t len = 1;
    for (const std::string& s : values) len = std::max(len, s.size());
    dims(values.size() == 1 ? std::vector<std::size_t>{len}
                            : std::vector<std::size_t>{len, values.size()});
    for (const std::string& s : values) {
      bytes_.insert(bytes_.end(), s.begin(), s.end());
      bytes_.insert(bytes_.end(), len - s.size(), ' ');
    }
    bytes_.push_back(0);
  }

  // The last record keeps its 0 offset.
  std::vector<std::uint8_t> finish() { return std::move(bytes_); }

 private:
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);

  void start(std::int8_t id, std::string_view name) {
    patch_previous();
    bytes_.push_back(static_cast<std::uint8_t>(name.size()));
    bytes_.push_back(static_cast<std::uint8_t>(id));
    bytes_.insert(bytes_.end(), name.begin(), name.end());
    last_offset_ = bytes_.size();
    bytes_.resize(bytes_.size() + 2);  // "next" offset, 0 until another record follows
  }
  void dims(const std::vector<std::size_t>& d) {
    bytes_.push_back(static_cast<std::uint8_t>(d.size()));
    for (std::size_t v : d) bytes_.push_back(static_cast<std::uint8_t>(v));
  }
  void patch_previous() {
    if (last_offset_ == kNone) return;
    const std::size_t distance = bytes_.size() - last_offset_;
    if (distance > 32767) throw std::invalid_argument("write_c3d: a parameter is too long");
    num_.put_u16(&bytes_[last_offset_], static_cast<std::uint16_t>(distance));
  }

  Numbers num_;
  std::vector<std::uint8_t> bytes_;
  std::size_t last_offset_ = kNone;
};

std::vector<std::uint16_t> split32(std::uint64_t v) {
  return {static_cast<std::uint16_t>(v & 0xFFFF), static_cast<std::uint16_t>(v >> 16)};
}

// LABELS, LABELS2, ... of a group: at most 255 strings per parameter (a dimension is one byte),
// and a record's size must fit its 16-bit offset.
void write_labels(ParameterWriter& w, int group, const std::vector<std::string>& labels) {
  std::size_t len = 1;
  for (const std::string& s : labels) len = std::max(len, s.size());
  const std::size_t per_param = std::min<std::size_t>(255, 32000 / len);
  for (std::size_t i = 0, k = 1; i < labels.size(); i += per_param, ++k) {
    const std::size_t end = std::min(labels.size(), i + per_param);
    w.chars(group, k == 1 ? "LABELS" : "LABELS" + std::to_string(k),
            {labels.begin() + static_cast<std::ptrdiff_t>(i),
             labels.begin() + static_cast<std::ptrdiff_t>(end)});
  }
  if (labels.empty()) w.chars(group, "LABELS", {});
}

std::vector<std::string> numbered(const char* prefix, std::size_t n) {
  std::vector<std::string> out;
  for (std::size_t i = 1; i <= n; ++i) out.push_back(prefix + std::to_string(i));
  return out;
}

void pad_to_block(std::ofstream& out, std::uint64_t bytes_written) {
  const std::vector<char> padding((kBlockBytes - bytes_written % kBlockBytes) % kBlockBytes, 0);
  out.write(padding.data(), static_cast<std::streamsize>(padding.size()));
}
}  // namespace

void write_c3d(const std::string& path, const MarkerTrial& trial, C3dProcessor processor,
               bool float_data, const std::string& units) {
  write_c3d(path, trial, C3dWriteOptions{.processor = processor, .float_data = float_data,
                                         .units = units});
}

void write_c3d(const std::string& path, const MarkerTrial& trial, const C3dWriteOptions& o) {
  const double from_m = detail::check_trial_for_writing(trial, o.units, "write_c3d");
  const std::size_t points = trial.markers();
  const std::size_t frames = points > 0 ? trial.frames() : o.frames_without_points;
  if (points > 65535) throw std::invalid_argument("write_c3d: more than 65535 markers");
  if (trial.first_frame < 1) throw std::invalid_argument("write_c3d: first_frame must be >= 1");
  const std::size_t analog_values = o.analog_channels * o.analog_samples_per_frame;
  if (o.analog_channels > 65535 || o.analog_samples_per_frame == 0 || analog_values > 65535) {
    throw std::invalid_argument("write_c3d: too many analog channels or samples per frame");
  }
  if (o.rotations > 65535) throw std::invalid_argument("write_c3d: too many rotations");
  const std::uint64_t first = static_cast<std::uint64_t>(trial.first_frame);
  const std::uint64_t last = first + frames - 1;  // first - 1 when there are no frames
  if (last > 0xFFFFFFFFu) throw std::invalid_argument("write_c3d: too many frames");
  for (const std::string& label : trial.labels) {
    if (label.size() > 255) throw std::invalid_argument("write_c3d: label longer than 255");
  }

  double max_abs = 0.0;
  for (const Eigen::Vector3d& p : trial.positions_m) {
    if (p.allFinite()) max_abs = std::max(max_abs, p.cwiseAbs().maxCoeff() * from_m);
  }
  if (max_abs > 1e37) throw std::invalid_argument("write_c3d: coordinates too large");
  // The spec's choice: the largest coordinate maps to 32000.
  float scale = static_cast<float>(max_abs / 32000.0);
  if (!(scale > 0.0f) || !std::isnormal(scale)) scale = 0.01f;
  const Numbers num(o.processor);
  const std::size_t word_bytes = o.float_data ? 4 : 2;
  const std::size_t frame_bytes = (points * 4 + analog_values) * word_bytes;
  const std::uint64_t data_blocks = (frames * frame_bytes + kBlockBytes - 1) / kBlockBytes;

  // Groups POINT (1), ANALOG (2), TRIAL (3: 32-bit frame numbers), ROTATION (4).
  const auto parameters = [&](std::uint16_t data_start) {
    ParameterWriter w(num);
    w.group(1, "POINT");
    w.int16s(1, "USED", {static_cast<std::uint16_t>(points)}, true);
    w.int16s(1, "FRAMES",
             {static_cast<std::uint16_t>(o.point_frames >= 0 ? o.point_frames : frames & 0xFFFF)},
             true);
    w.int16s(1, "DATA_START", {o.point_data_start_zero ? std::uint16_t{0} : data_start}, true);
    w.float32(1, "SCALE", o.float_data ? -scale : scale);
    w.float32(1, "RATE", static_cast<float>(trial.rate_hz));
    w.chars(1, "UNITS", {o.units});
    write_labels(w, 1, trial.labels);
    w.group(2, "ANALOG");
    w.int16s(2, "USED", {static_cast<std::uint16_t>(o.analog_channels)}, true);
    w.float32(2, "RATE", static_cast<float>(trial.rate_hz * static_cast<double>(o.analog_samples_per_frame)));
    if (o.analog_channels > 0) write_labels(w, 2, numbered("Analog", o.analog_channels));
    if (o.trial_group) {
      w.group(3, "TRIAL");
      w.int16s(3, "ACTUAL_START_FIELD", split32(first), false);
      w.int16s(3, "ACTUAL_END_FIELD", split32(last), false);
    }
    if (o.rotations > 0) {
      w.group(4, "ROTATION");
      w.int16s(4, "USED", {static_cast<std::uint16_t>(o.rotations)}, true);
      w.float32(4, "RATE", static_cast<float>(trial.rate_hz));
      w.int16s(4, "RATIO", {1}, true);
      w.int16s(4, "DATA_START",
               {static_cast<std::uint16_t>(data_start + data_blocks)}, true);
      write_labels(w, 4, numbered("Segment", o.rotations));
    }
    return w.finish();
  };
  // 4 bytes of section header, the records, and a zero name length after them.
  const std::size_t blocks = (4 + parameters(0).size() + 2 + kBlockBytes - 1) / kBlockBytes;
  if (blocks > 255) throw std::invalid_argument("write_c3d: too many labels for a C3D file");
  const auto data_start = static_cast<std::uint16_t>(2 + blocks);
  if (o.rotations > 0 && data_start + data_blocks > 0xFFFF) {
    throw std::invalid_argument("write_c3d: too many frames for rotations");
  }
  const std::vector<std::uint8_t> records = parameters(data_start);

  std::vector<std::uint8_t> head((1 + blocks) * kBlockBytes, 0);
  head[0] = 2;  // parameter section at block 2
  head[1] = c3d::kKey;
  const std::uint64_t header_first = o.header_first_frame != 0 ? o.header_first_frame : first;
  const std::uint64_t header_last =
      o.header_first_frame != 0 ? (header_first + frames + 65535) % 65536
                                : std::min<std::uint64_t>(last, 65535);
  num.put_u16(&head[c3d::kHeaderPoints], static_cast<std::uint16_t>(points));
  num.put_u16(&head[c3d::kHeaderAnalogValues], static_cast<std::uint16_t>(analog_values));
  num.put_u16(&head[c3d::kHeaderFirstFrame],
              static_cast<std::uint16_t>(std::min<std::uint64_t>(header_first, 65535)));
  num.put_u16(&head[c3d::kHeaderLastFrame], static_cast<std::uint16_t>(header_last));
  num.put_u16(&head[10], 0);  // max interpolation gap
  num.put_f32(&head[c3d::kHeaderScale], o.float_data ? -scale : scale);
  num.put_u16(&head[c3d::kHeaderDataStart], data_start);
  num.put_u16(&head[c3d::kHeaderAnalogSamples],
              static_cast<std::uint16_t>(o.analog_channels > 0 ? o.analog_samples_per_frame : 0));
  num.put_f32(&head[c3d::kHeaderRate], static_cast<float>(trial.rate_hz));
  num.put_u16(&head[298], 12345);  // word 150: event labels are 4 characters
  std::uint8_t* section = &head[kBlockBytes];
  section[0] = 1;
  section[1] = c3d::kKey;
  section[2] = static_cast<std::uint8_t>(blocks);
  section[3] = static_cast<std::uint8_t>(c3d::kProcessorBase + 1 + static_cast<int>(o.processor));
  std::copy(records.begin(), records.end(), section + 4);

  std::ofstream out = open_output_file(path);
  out.write(reinterpret_cast<const char*>(head.data()), static_cast<std::streamsize>(head.size()));
  const auto put_word = [&](std::uint8_t* w, double v) {
    if (o.float_data) {
      num.put_f32(w, static_cast<float>(v));
    } else {
      num.put_i16(w, static_cast<std::int16_t>(std::lround(v)));
    }
  };
  std::vector<std::uint8_t> frame(frame_bytes);
  for (std::size_t f = 0; f < frames; ++f) {
    for (std::size_t m = 0; m < points; ++m) {
      std::uint8_t* w = &frame[m * 4 * word_bytes];
      const Eigen::Vector3d& p = trial.at(f, m);
      const bool valid = p.allFinite();
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const double v = valid ? p[static_cast<Eigen::Index>(axis)] * from_m : 0.0;
        put_word(w + axis * word_bytes, o.float_data ? v : v / scale);
      }
      // Residual word: 0 = valid (not a raw measurement), -1 = missing.
      put_word(w + 3 * word_bytes, valid ? 0.0 : -1.0);
    }
    // Analog: a ramp per channel, sample by sample.
    std::uint8_t* a = frame.data() + points * 4 * word_bytes;
    for (std::size_t s = 0; s < o.analog_samples_per_frame && o.analog_channels > 0; ++s) {
      for (std::size_t c = 0; c < o.analog_channels; ++c, a += word_bytes) {
        put_word(a, static_cast<double>((f * o.analog_samples_per_frame + s + c) % 1000));
      }
    }
    out.write(reinterpret_cast<const char*>(frame.data()),
              static_cast<std::streamsize>(frame.size()));
  }
  pad_to_block(out, frames * frame_bytes);
  if (o.rotations > 0) {
    // Per frame and rotation: a 4x4 matrix (identity) and a reliability, as floats.
    std::vector<std::uint8_t> rotation(17 * 4);
    for (int i = 0; i < 17; ++i) {
      num.put_f32(&rotation[static_cast<std::size_t>(i) * 4], i % 5 == 0 && i < 16 ? 1.0f : 0.0f);
    }
    for (std::size_t k = 0; k < frames * o.rotations; ++k) {
      out.write(reinterpret_cast<const char*>(rotation.data()),
                static_cast<std::streamsize>(rotation.size()));
    }
    pad_to_block(out, frames * o.rotations * rotation.size());
  }
  finish_output_file(out, path);
}

}  // namespace fabrik::io
