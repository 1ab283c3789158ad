// C3D files (c3d.org, "C3D file format user guide"): 512-byte blocks; a header block; a
// parameter section of groups and parameters; then per frame, every point's X, Y, Z and residual
// word (int16 scaled by POINT:SCALE, or float when POINT:SCALE < 0) followed by the frame's
// analog samples in the same number type. The processor byte of the parameter section says how
// numbers are stored: 84 Intel (little-endian IEEE), 85 DEC (little-endian integers, VAX
// F-floating), 86 MIPS (big-endian IEEE).
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::io {

namespace {
static_assert(std::numeric_limits<float>::is_iec559, "IEEE floats are assumed");

constexpr std::size_t kBlockBytes = 512;
constexpr std::uint8_t kKey = 0x50;
constexpr int kProcessorBase = 83;  // processor byte = 83 + 1 (Intel), 2 (DEC), 3 (MIPS)

// Reads and writes 16-bit integers and 32-bit floats in one processor's format.
class Numbers {
 public:
  explicit Numbers(C3dProcessor p) : p_(p) {}

  std::uint16_t u16(const std::uint8_t* b) const {
    return p_ == C3dProcessor::mips ? static_cast<std::uint16_t>(b[0] << 8 | b[1])
                                    : static_cast<std::uint16_t>(b[1] << 8 | b[0]);
  }
  std::int16_t i16(const std::uint8_t* b) const { return static_cast<std::int16_t>(u16(b)); }

  double f32(const std::uint8_t* b) const {
    const std::uint32_t b0 = b[0], b1 = b[1], b2 = b[2], b3 = b[3];
    switch (p_) {
      case C3dProcessor::intel:
        return std::bit_cast<float>(b0 | b1 << 8 | b2 << 16 | b3 << 24);
      case C3dProcessor::mips:
        return std::bit_cast<float>(b0 << 24 | b1 << 16 | b2 << 8 | b3);
      case C3dProcessor::dec:
        break;
    }
    // VAX F-floating: the first little-endian word holds the sign (bit 15), the exponent
    // (bits 14-7, excess 128) and the top 7 fraction bits; the second word the low 16 bits.
    // Value = 0.1fff...(binary) x 2^(exponent - 128): IEEE's layout read 4 times too large, so
    // decode it exactly rather than by the divide-by-4 trick, which fails at the extremes.
    const std::uint32_t high = b0 | b1 << 8, low = b2 | b3 << 8;
    const int exponent = static_cast<int>((high >> 7) & 0xFF);
    const bool negative = (high & 0x8000) != 0;
    if (exponent == 0) return negative ? std::nan("") : 0.0;  // reserved operand, or zero
    const std::uint32_t fraction = (high & 0x7F) << 16 | low;
    const double v = std::ldexp(1.0 + static_cast<double>(fraction) / 8388608.0, exponent - 129);
    return negative ? -v : v;
  }

  void put_u16(std::uint8_t* b, std::uint16_t v) const {
    const auto hi = static_cast<std::uint8_t>(v >> 8), lo = static_cast<std::uint8_t>(v & 0xFF);
    b[0] = p_ == C3dProcessor::mips ? hi : lo;
    b[1] = p_ == C3dProcessor::mips ? lo : hi;
  }
  void put_i16(std::uint8_t* b, std::int16_t v) const { put_u16(b, static_cast<std::uint16_t>(v)); }

  // `v` must be finite (callers write missing samples as zeros).
  void put_f32(std::uint8_t* b, float v) const {
    if (p_ != C3dProcessor::dec) {
      const std::uint32_t bits = std::bit_cast<std::uint32_t>(v);
      for (int i = 0; i < 4; ++i) {
        const int shift = p_ == C3dProcessor::mips ? 24 - 8 * i : 8 * i;
        b[i] = static_cast<std::uint8_t>((bits >> shift) & 0xFF);
      }
      return;
    }
    std::uint32_t high = 0, low = 0;
    if (v != 0.0f) {
      int e = 0;
      const double m = std::frexp(std::abs(static_cast<double>(v)), &e);  // m in [0.5, 1)
      const int exponent = e + 128;
      if (exponent > 255) throw std::invalid_argument("write_c3d: value too large for DEC");
      if (exponent >= 1) {  // smaller values flush to zero, as DEC has no denormals
        const auto fraction = static_cast<std::uint32_t>(std::ldexp(m, 24)) - 0x800000u;
        high =
            (v < 0.0f ? 0x8000u : 0u) | static_cast<std::uint32_t>(exponent) << 7 | fraction >> 16;
        low = fraction & 0xFFFF;
      }
    }
    b[0] = static_cast<std::uint8_t>(high & 0xFF);
    b[1] = static_cast<std::uint8_t>(high >> 8);
    b[2] = static_cast<std::uint8_t>(low & 0xFF);
    b[3] = static_cast<std::uint8_t>(low >> 8);
  }

 private:
  C3dProcessor p_;
};

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  }
  return out;
}

struct Parameter {
  int group_id = 0;
  std::string group, name;  // upper case
  int type = 0;             // -1 char, 1 byte, 2 int16, 4 float
  std::vector<std::size_t> dims;
  std::size_t data = 0;   // offset of the values in the section
  std::size_t count = 0;  // number of values (product of dims)
};

class C3dReader {
 public:
  C3dReader(const std::string& path, const C3dReadOptions& options)
      : path_(path), options_(options), in_(detail::open_input(path)) {}

  MarkerTrial read() {
    in_.seekg(0, std::ios::end);
    file_bytes_ = static_cast<std::uint64_t>(in_.tellg());
    if (file_bytes_ < kBlockBytes) {
      fail("header: the file has " + std::to_string(file_bytes_) +
           " bytes, fewer than the 512 of a C3D header");
    }
    read_at(0, header_, kBlockBytes, "header");
    if (header_[1] != kKey) {
      fail("header: not a C3D file (its second byte is " + std::to_string(header_[1]) +
           ", expected 80)");
    }
    read_parameters();
    return read_points();
  }

 private:
  [[noreturn]] void fail(const std::string& problem) const { throw FormatError(path_, problem); }

  void read_at(std::uint64_t offset, std::uint8_t* out, std::size_t bytes, const char* part) {
    if (offset > file_bytes_ || bytes > file_bytes_ - offset) {
      fail(std::string(part) + ": truncated (needs bytes " + std::to_string(offset) + " to " +
           std::to_string(offset + bytes) + ", the file has " + std::to_string(file_bytes_) + ")");
    }
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(bytes));
    if (!in_) fail(std::string(part) + ": read error");
  }

  void read_parameters() {
    const unsigned first_block = header_[0];
    if (first_block < 2) {
      fail("header: the parameter section starts at block " + std::to_string(first_block) +
           " (it must be 2 or later)");
    }
    param_start_ = (first_block - 1) * std::uint64_t{kBlockBytes};
    std::uint8_t head[4];
    read_at(param_start_, head, 4, "parameter section");
    const int processor = head[3];
    if (processor < kProcessorBase + 1 || processor > kProcessorBase + 3) {
      fail("parameter section: unknown processor type " + std::to_string(processor) +
           " (expected 84 Intel, 85 DEC or 86 MIPS)");
    }
    num_ = Numbers(static_cast<C3dProcessor>(processor - kProcessorBase - 1));
    if (head[2] == 0) fail("parameter section: its block count is 0");
    section_.resize(head[2] * kBlockBytes);
    read_at(param_start_, section_.data(), section_.size(), "parameter section");

    std::vector<std::pair<int, std::string>> groups;
    std::size_t pos = 4;
    const std::size_t size = section_.size();
    const auto need = [&](std::size_t end, const std::string& what) {
      if (end > size) {
        fail("parameter section: " + what + " at byte " + std::to_string(pos) +
             " runs past the end of the section's " + std::to_string(size / kBlockBytes) +
             " blocks");
      }
    };
    while (true) {
      need(pos + 2, "a record");
      const int name_len = std::abs(static_cast<int>(static_cast<std::int8_t>(section_[pos])));
      const int id = static_cast<std::int8_t>(section_[pos + 1]);
      if (name_len == 0 || id == 0) break;  // end of the list
      const std::size_t offset_pos = pos + 2 + static_cast<std::size_t>(name_len);
      need(offset_pos + 2, "a record");
      const std::string name =
          upper({reinterpret_cast<const char*>(&section_[pos + 2]), std::size_t(name_len)});
      const int next = num_.i16(&section_[offset_pos]);
      if (id < 0) {
        groups.emplace_back(-id, name);
      } else {
        Parameter p;
        p.group_id = id;
        p.name = name;
        std::size_t q = offset_pos + 2;
        need(q + 2, "parameter " + name);
        p.type = static_cast<std::int8_t>(section_[q]);
        const std::size_t ndims = section_[q + 1];
        q += 2;
        if (p.type != -1 && p.type != 1 && p.type != 2 && p.type != 4) {
          fail("parameter section: parameter " + name + " has unknown type " +
               std::to_string(p.type) + " (expected -1, 1, 2 or 4)");
        }
        if (ndims > 7) {
          fail("parameter section: parameter " + name + " has " + std::to_string(ndims) +
               " dimensions (at most 7)");
        }
        need(q + ndims, "parameter " + name);
        p.count = 1;
        for (std::size_t d = 0; d < ndims; ++d) {
          p.dims.push_back(section_[q + d]);
          p.count *= section_[q + d];  // at most 255^7: no overflow
        }
        q += ndims;
        need(q + p.count * static_cast<std::size_t>(std::abs(p.type)), "parameter " + name);
        p.data = q;
        params_.push_back(std::move(p));
      }
      if (next == 0) break;  // the last record
      if (next < 0) {
        fail("parameter section: record " + name + " points backwards (offset " +
             std::to_string(next) + ")");
      }
      pos = offset_pos + static_cast<std::size_t>(next);
      if (pos >= size) break;  // some writers point the last record at the section's end
    }
    for (Parameter& p : params_) {
      for (const auto& [gid, gname] : groups) {
        if (gid == p.group_id) p.group = gname;
      }
    }
  }

  const Parameter* find(std::string_view group, std::string_view name) const {
    for (const Parameter& p : params_) {
      if (p.group == group && p.name == name) return &p;
    }
    return nullptr;
  }

  // Element `i` of a numeric parameter.
  std::optional<double> number(const Parameter* p, std::size_t i = 0) const {
    if (p == nullptr || i >= p->count) return std::nullopt;
    const std::uint8_t* b = &section_[p->data];
    switch (p->type) {
      case 1:
        return b[i];
      case 2:
        return num_.i16(b + 2 * i);
      case 4:
        return num_.f32(b + 4 * i);
      default:
        return std::nullopt;
    }
  }

  // A count or index: int16 values are read unsigned, as the format allows up to 65535.
  std::optional<std::uint32_t> count(const Parameter* p, std::size_t i = 0) const {
    if (p != nullptr && p->type == 2 && i < p->count) return num_.u16(&section_[p->data + 2 * i]);
    const std::optional<double> v = number(p, i);
    if (!v || !(*v >= 0.0) || *v > 4294967295.0) return std::nullopt;
    return static_cast<std::uint32_t>(std::lround(*v));
  }

  // A character parameter as strings: dims[0] is the length of each.
  std::vector<std::string> strings(const Parameter* p) const {
    std::vector<std::string> out;
    if (p == nullptr || p->type != -1) return out;
    const auto* chars = reinterpret_cast<const char*>(&section_[p->data]);
    if (p->dims.size() <= 1) {
      out.emplace_back(detail::trim({chars, p->count}));
      return out;
    }
    const std::size_t len = p->dims[0];
    const std::size_t n = len == 0 ? 0 : p->count / len;
    for (std::size_t i = 0; i < n; ++i) out.emplace_back(detail::trim({chars + i * len, len}));
    return out;
  }

  // A frame number stored as two int16 words, low word first (TRIAL:ACTUAL_*_FIELD).
  std::optional<std::uint32_t> field_number(const Parameter* p) const {
    if (p == nullptr || p->type != 2 || p->count < 2) return std::nullopt;
    return std::uint32_t{num_.u16(&section_[p->data])} |
           std::uint32_t{num_.u16(&section_[p->data + 2])} << 16;
  }

  MarkerTrial read_points() {
    MarkerTrial trial;
    const std::uint32_t points =
        count(find("POINT", "USED")).value_or(num_.u16(&header_[2]));  // header word 2

    const double scale = number(find("POINT", "SCALE")).value_or(num_.f32(&header_[12]));
    if (!std::isfinite(scale) || scale == 0.0) {
      fail("parameter section: POINT:SCALE is " + std::to_string(scale) +
           " (it must be non-zero: positive for int16 data, negative for float data)");
    }
    const bool float_data = scale < 0.0;
    const std::size_t word_bytes = float_data ? 4 : 2;

    double rate_hz = number(find("POINT", "RATE")).value_or(0.0);
    if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) rate_hz = num_.f32(&header_[20]);
    if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
      fail("parameter section: POINT:RATE and the header's frame rate are not positive");
    }
    trial.rate_hz = rate_hz;

    const std::uint32_t data_start =
        count(find("POINT", "DATA_START")).value_or(num_.u16(&header_[16]));
    if (data_start < 2 || (data_start - 1) * std::uint64_t{kBlockBytes} <= param_start_) {
      fail("parameter section: POINT:DATA_START is block " + std::to_string(data_start) +
           ", not after the parameter section");
    }
    const std::uint64_t data_offset = (data_start - 1) * std::uint64_t{kBlockBytes};

    // Frame numbers: TRIAL:ACTUAL_*_FIELD hold 32 bits, the header words only 16.
    std::uint32_t first = num_.u16(&header_[6]), last = num_.u16(&header_[8]);
    const auto trial_first = field_number(find("TRIAL", "ACTUAL_START_FIELD"));
    const auto trial_last = field_number(find("TRIAL", "ACTUAL_END_FIELD"));
    if (trial_first && trial_last) {
      first = *trial_first;
      last = *trial_last;
    }
    if (std::uint64_t{last} + 1 < first) {
      fail("header: the last frame (" + std::to_string(last) + ") is before the first (" +
           std::to_string(first) + ")");
    }
    if (first > static_cast<std::uint32_t>(std::numeric_limits<int>::max())) {
      fail("header: first frame " + std::to_string(first) + " is too large");
    }
    trial.first_frame = static_cast<int>(first);
    std::uint64_t frames = std::uint64_t{last} + 1 - first;

    const std::uint64_t analog = analog_values_per_frame(rate_hz);
    const std::uint64_t frame_bytes = (std::uint64_t{points} * 4 + analog) * word_bytes;

    // Check the size before allocating anything: absurd counts end here.
    if (frames > 0 && frame_bytes > 0) {
      const std::uint64_t available = file_bytes_ > data_offset ? file_bytes_ - data_offset : 0;
      const std::uint64_t complete = available / frame_bytes;
      if (complete < frames) {
        const std::string held = "the file holds " + std::to_string(complete) +
                                 " complete of the " + std::to_string(frames) +
                                 " frames it declares (" + std::to_string(frame_bytes) +
                                 " bytes each from byte " + std::to_string(data_offset) +
                                 "; the file has " + std::to_string(file_bytes_) + " bytes)";
        if (!options_.allow_truncated_data) fail("3D data: truncated: " + held);
        if (complete == 0) fail("3D data: " + held);
        frames = complete;
      }
    }

    trial.labels = labels(points);
    const std::string units = units_of_points();
    double to_m = 0.0;
    if (units == "mm") {
      to_m = 0.001;
    } else if (units == "m") {
      to_m = 1.0;
    } else {
      fail("parameter section: POINT:UNITS '" + units + "' is not supported (expected mm or m)");
    }
    if (points == 0) return trial;

    trial.positions_m.resize(frames * points);
    const Eigen::Vector3d missing = Eigen::Vector3d::Constant(std::nan(""));
    const std::uint64_t chunk_frames = std::max<std::uint64_t>(1, (1u << 20) / frame_bytes);
    std::vector<std::uint8_t> buffer;
    for (std::uint64_t f0 = 0; f0 < frames; f0 += chunk_frames) {
      const std::uint64_t n = std::min(chunk_frames, frames - f0);
      buffer.resize(n * frame_bytes);
      read_at(data_offset + f0 * frame_bytes, buffer.data(), buffer.size(), "3D data");
      for (std::uint64_t f = 0; f < n; ++f) {
        const std::uint8_t* frame = buffer.data() + f * frame_bytes;
        for (std::uint32_t m = 0; m < points; ++m) {
          const std::uint8_t* w = frame + std::size_t{m} * 4 * word_bytes;
          Eigen::Vector3d p;
          bool valid = false;
          if (float_data) {
            p = Eigen::Vector3d(num_.f32(w), num_.f32(w + 4), num_.f32(w + 8));
            valid = residual_valid(num_.f32(w + 12));
          } else {
            p = Eigen::Vector3d(num_.i16(w), num_.i16(w + 2), num_.i16(w + 4)) * scale;
            valid = num_.i16(w + 6) >= 0;
          }
          trial.positions_m[(f0 + f) * points + m] = valid && p.allFinite() ? p * to_m : missing;
        }
      }
    }
    return trial;
  }

  // The float residual word "must be converted to a signed integer": the sign bit of its
  // 16-bit form marks an invalid point.
  static bool residual_valid(double word) {
    if (!std::isfinite(word) || word <= -1.0) return false;
    if (word >= 2147483647.0) return false;
    const auto bits = static_cast<std::uint32_t>(static_cast<std::int64_t>(word));
    return static_cast<std::int16_t>(bits & 0xFFFF) >= 0;
  }

  std::uint64_t analog_values_per_frame(double point_rate_hz) {
    std::uint64_t analog = num_.u16(&header_[4]);  // header word 3
    const std::optional<std::uint32_t> used = count(find("ANALOG", "USED"));
    if (used) {
      const double ratio = number(find("ANALOG", "RATE")).value_or(0.0) / point_rate_hz;
      if (*used == 0) {
        analog = 0;
      } else if (ratio >= 0.5 && ratio < 1e6 && std::abs(ratio - std::round(ratio)) < 1e-3) {
        analog = *used * static_cast<std::uint64_t>(std::llround(ratio));
      }
    }
    return analog;
  }

  std::vector<std::string> labels(std::uint32_t points) const {
    std::vector<std::string> out;
    if (points == 0) return out;
    const Parameter* first = find("POINT", "LABELS");
    if (first == nullptr) fail("parameter section: POINT:LABELS missing");
    out = strings(first);
    // More than 255 points: the rest are in LABELS2, LABELS3, ...
    for (int k = 2; out.size() < points; ++k) {
      const Parameter* more = find("POINT", "LABELS" + std::to_string(k));
      if (more == nullptr) break;
      for (std::string& s : strings(more)) out.push_back(std::move(s));
    }
    if (out.size() < points) {
      fail("parameter section: POINT:LABELS holds " + std::to_string(out.size()) + " labels for " +
           std::to_string(points) + " points");
    }
    out.resize(points);
    return out;
  }

  std::string units_of_points() const {
    const std::vector<std::string> units = strings(find("POINT", "UNITS"));
    // Absent or blank means the format's default, mm.
    return units.empty() || units[0].empty() ? "mm" : units[0];
  }

  const std::string& path_;
  C3dReadOptions options_;
  std::ifstream in_;
  std::uint64_t file_bytes_ = 0;
  std::uint8_t header_[kBlockBytes] = {};
  std::uint64_t param_start_ = 0;
  Numbers num_{C3dProcessor::intel};
  std::vector<std::uint8_t> section_;
  std::vector<Parameter> params_;
};

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
}  // namespace

MarkerTrial read_c3d(const std::string& path, const C3dReadOptions& options) {
  return C3dReader(path, options).read();
}

void write_c3d(const std::string& path, const MarkerTrial& trial, C3dProcessor processor,
               bool float_data, const std::string& units) {
  const double from_m = detail::check_trial_for_writing(trial, units, "write_c3d");
  const std::size_t points = trial.markers(), frames = trial.frames();
  if (points > 65535) throw std::invalid_argument("write_c3d: more than 65535 markers");
  if (trial.first_frame < 1) throw std::invalid_argument("write_c3d: first_frame must be >= 1");
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
  const Numbers num(processor);

  // Groups POINT (1), ANALOG (2: no channels), TRIAL (3: 32-bit frame numbers).
  const auto parameters = [&](std::uint16_t data_start) {
    ParameterWriter w(num);
    w.group(1, "POINT");
    w.int16s(1, "USED", {static_cast<std::uint16_t>(points)}, true);
    w.int16s(1, "FRAMES", {static_cast<std::uint16_t>(std::min<std::size_t>(frames, 65535))}, true);
    w.int16s(1, "DATA_START", {data_start}, true);
    w.float32(1, "SCALE", float_data ? -scale : scale);
    w.float32(1, "RATE", static_cast<float>(trial.rate_hz));
    w.chars(1, "UNITS", {units});
    // At most 255 labels per parameter (a dimension is one byte), and a record's size must fit
    // its 16-bit offset: the rest go to LABELS2, LABELS3, ...
    std::size_t len = 1;
    for (const std::string& s : trial.labels) len = std::max(len, s.size());
    const std::size_t per_param = std::min<std::size_t>(255, 32000 / len);
    for (std::size_t i = 0, k = 1; i < points; i += per_param, ++k) {
      const std::size_t end = std::min(points, i + per_param);
      w.chars(1, k == 1 ? "LABELS" : "LABELS" + std::to_string(k),
              {trial.labels.begin() + static_cast<std::ptrdiff_t>(i),
               trial.labels.begin() + static_cast<std::ptrdiff_t>(end)});
    }
    if (points == 0) w.chars(1, "LABELS", {});
    w.group(2, "ANALOG");
    w.int16s(2, "USED", {0}, true);
    w.float32(2, "RATE", static_cast<float>(trial.rate_hz));
    w.group(3, "TRIAL");
    const auto split = [](std::uint64_t v) {
      return std::vector<std::uint16_t>{static_cast<std::uint16_t>(v & 0xFFFF),
                                        static_cast<std::uint16_t>(v >> 16)};
    };
    w.int16s(3, "ACTUAL_START_FIELD", split(first), false);
    w.int16s(3, "ACTUAL_END_FIELD", split(last), false);
    return w.finish();
  };
  // 4 bytes of section header, the records, and a zero name length after them.
  const std::size_t blocks = (4 + parameters(0).size() + 2 + kBlockBytes - 1) / kBlockBytes;
  if (blocks > 255) throw std::invalid_argument("write_c3d: too many labels for a C3D file");
  const auto data_start = static_cast<std::uint16_t>(2 + blocks);
  const std::vector<std::uint8_t> records = parameters(data_start);

  std::vector<std::uint8_t> head((1 + blocks) * kBlockBytes, 0);
  head[0] = 2;  // parameter section at block 2
  head[1] = kKey;
  num.put_u16(&head[2], static_cast<std::uint16_t>(points));
  num.put_u16(&head[4], 0);  // analog values per frame
  num.put_u16(&head[6], static_cast<std::uint16_t>(std::min<std::uint64_t>(first, 65535)));
  num.put_u16(&head[8], static_cast<std::uint16_t>(std::min<std::uint64_t>(last, 65535)));
  num.put_u16(&head[10], 0);  // max interpolation gap
  num.put_f32(&head[12], float_data ? -scale : scale);
  num.put_u16(&head[16], data_start);
  num.put_u16(&head[18], 0);  // analog samples per frame
  num.put_f32(&head[20], static_cast<float>(trial.rate_hz));
  num.put_u16(&head[298], 12345);  // word 150: event labels are 4 characters
  std::uint8_t* section = &head[kBlockBytes];
  section[0] = 1;
  section[1] = kKey;
  section[2] = static_cast<std::uint8_t>(blocks);
  section[3] = static_cast<std::uint8_t>(kProcessorBase + 1 + static_cast<int>(processor));
  std::copy(records.begin(), records.end(), section + 4);

  std::ofstream out = detail::open_output(path);
  out.write(reinterpret_cast<const char*>(head.data()), static_cast<std::streamsize>(head.size()));
  const std::size_t word_bytes = float_data ? 4 : 2;
  std::vector<std::uint8_t> frame(points * 4 * word_bytes);
  for (std::size_t f = 0; f < frames; ++f) {
    for (std::size_t m = 0; m < points; ++m) {
      std::uint8_t* w = &frame[m * 4 * word_bytes];
      const Eigen::Vector3d& p = trial.at(f, m);
      const bool valid = p.allFinite();
      for (int axis = 0; axis < 3; ++axis) {
        const double v = valid ? p[axis] * from_m : 0.0;
        if (float_data) {
          num.put_f32(w + 4 * axis, static_cast<float>(v));
        } else {
          num.put_i16(w + 2 * axis, static_cast<std::int16_t>(std::lround(v / scale)));
        }
      }
      // Residual word: 0 = valid (not a raw measurement), -1 = missing.
      if (float_data) {
        num.put_f32(w + 12, valid ? 0.0f : -1.0f);
      } else {
        num.put_i16(w + 6, static_cast<std::int16_t>(valid ? 0 : -1));
      }
    }
    out.write(reinterpret_cast<const char*>(frame.data()),
              static_cast<std::streamsize>(frame.size()));
  }
  const std::size_t data_bytes = frames * frame.size();
  const std::vector<char> padding((kBlockBytes - data_bytes % kBlockBytes) % kBlockBytes, 0);
  out.write(padding.data(), static_cast<std::streamsize>(padding.size()));
  out.close();
  detail::check_written(out, path);
}

}  // namespace fabrik::io
