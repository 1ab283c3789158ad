// C3D reader: the header, the parameter section (groups and parameters), then the 3D points of
// every frame (see c3d_format.hpp). Where the header and the parameters disagree (data start,
// frame count), the reader takes what the file's data support and says so in a warning.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/c3d_format.hpp"
#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::io {

namespace {
using c3d::kBlockBytes;
using c3d::Numbers;

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
  std::size_t data = 0;   // offset of the values in the section (== its size when empty)
  std::size_t count = 0;  // number of values (product of dims)
};

// A frame count one source declares, and how it was read.
struct FrameCount {
  std::string source;  // "TRIAL:ACTUAL_*_FIELD", "POINT:FRAMES", "the header"
  std::uint64_t frames = 0;
};

std::string str(std::uint64_t v) { return std::to_string(v); }

class C3dReader {
 public:
  C3dReader(const std::string& path, const ReadOptions& options)
      : path_(path), options_(options), in_(detail::open_input(path)) {}

  MarkerTrial read() {
    in_.seekg(0, std::ios::end);
    file_bytes_ = static_cast<std::uint64_t>(in_.tellg());
    if (file_bytes_ < kBlockBytes) {
      fail("header: the file has " + str(file_bytes_) +
           " bytes, fewer than the 512 of a C3D header");
    }
    read_at(0, header_, kBlockBytes, "header");
    if (header_[1] != c3d::kKey) {
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
      fail(std::string(part) + ": truncated (needs bytes " + str(offset) + " to " +
           str(offset + bytes) + ", the file has " + str(file_bytes_) + ")");
    }
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(bytes));
    if (!in_) fail(std::string(part) + ": read error");
  }

  std::uint16_t header_word(std::size_t offset) const { return num_.u16(&header_[offset]); }

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
    if (processor < c3d::kProcessorBase + 1 || processor > c3d::kProcessorBase + 3) {
      fail("parameter section: unknown processor type " + std::to_string(processor) +
           " (expected 84 Intel, 85 DEC or 86 MIPS)");
    }
    processor_ = static_cast<C3dProcessor>(processor - c3d::kProcessorBase - 1);
    num_ = Numbers(processor_);
    if (head[2] == 0) fail("parameter section: its block count is 0");
    section_.resize(head[2] * kBlockBytes);
    read_at(param_start_, section_.data(), section_.size(), "parameter section");

    std::vector<std::pair<int, std::string>> groups;
    std::size_t pos = 4;
    const std::size_t size = section_.size();
    const auto need = [&](std::size_t end, const std::string& what) {
      if (end > size) {
        fail("parameter section: " + what + " at byte " + str(pos) +
             " runs past the end of the section's " + str(size / kBlockBytes) + " blocks");
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
          upper({reinterpret_cast<const char*>(section_.data() + pos + 2), std::size_t(name_len)});
      const int next = num_.i16(section_.data() + offset_pos);
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
          fail("parameter section: parameter " + name + " has " + str(ndims) +
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
        p.data = q;  // may equal the section's size when the values are empty
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

  // The values of `p`: a pointer, never an index, so that an empty parameter ending exactly at
  // the end of the section is not an out-of-range element.
  const std::uint8_t* values(const Parameter* p) const { return section_.data() + p->data; }

  // Element `i` of a numeric parameter.
  std::optional<double> number(const Parameter* p, std::size_t i = 0) const {
    if (p == nullptr || i >= p->count) return std::nullopt;
    const std::uint8_t* b = values(p);
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
    if (p != nullptr && p->type == 2 && i < p->count) return num_.u16(values(p) + 2 * i);
    const std::optional<double> v = number(p, i);
    if (!v || !(*v >= 0.0) || *v > 4294967295.0) return std::nullopt;
    return static_cast<std::uint32_t>(std::lround(*v));
  }

  // A character parameter as strings: dims[0] is the length of each.
  std::vector<std::string> strings(const Parameter* p) const {
    std::vector<std::string> out;
    if (p == nullptr || p->type != -1) return out;
    const auto* chars = reinterpret_cast<const char*>(values(p));
    if (p->dims.size() <= 1) {
      out.emplace_back(detail::trim({chars, p->count}));
      return out;
    }
    const std::size_t len = p->dims[0];
    const std::size_t n = len == 0 ? 0 : p->count / len;
    for (std::size_t i = 0; i < n; ++i) out.emplace_back(detail::trim({chars + i * len, len}));
    return out;
  }

  // GROUP:LABELS, then LABELS2, LABELS3, ... (a dimension holds at most 255), up to `n`.
  std::vector<std::string> labels_of(std::string_view group, std::size_t n) const {
    std::vector<std::string> out = strings(find(group, "LABELS"));
    for (int k = 2; out.size() < n; ++k) {
      const Parameter* more = find(group, "LABELS" + std::to_string(k));
      if (more == nullptr) break;
      for (std::string& s : strings(more)) out.push_back(std::move(s));
    }
    if (out.size() > n) out.resize(n);
    return out;
  }

  // A frame number stored as two int16 words, low word first (TRIAL:ACTUAL_*_FIELD).
  std::optional<std::uint32_t> field_number(const Parameter* p) const {
    if (p == nullptr || p->type != 2 || p->count < 2) return std::nullopt;
    return std::uint32_t{num_.u16(values(p))} | std::uint32_t{num_.u16(values(p) + 2)} << 16;
  }

  // The byte where the 3D data start: POINT:DATA_START, or the header's word when the parameter
  // cannot be right (a DEC exporter writes 0 there).
  std::uint64_t data_offset(MarkerTrial& trial) const {
    const std::uint32_t header_block = header_word(c3d::kHeaderDataStart);
    const std::optional<std::uint32_t> param_block = count(find("POINT", "DATA_START"));
    const auto after_parameters = [&](std::uint32_t block) {
      return block >= 2 && (block - 1) * std::uint64_t{kBlockBytes} > param_start_;
    };
    std::uint32_t block = header_block;
    if (param_block && after_parameters(*param_block)) {
      block = *param_block;
      if (header_block != block) {
        trial.warnings.push_back("POINT:DATA_START is block " + str(block) +
                                 " but the header's data start is block " + str(header_block) +
                                 ": read the 3D data from block " + str(block));
      }
    } else if (after_parameters(header_block)) {
      if (param_block) {
        trial.warnings.push_back("POINT:DATA_START is block " + str(*param_block) +
                                 ", not after the parameter section: read the 3D data from the "
                                 "header's data start, block " +
                                 str(header_block));
      }
    } else {
      fail("the 3D data start at block " + str(param_block.value_or(header_block)) +
           (param_block ? " (POINT:DATA_START; the header says block " + str(header_block) + ")"
                        : " (the header's data start word)") +
           ", not after the parameter section");
    }
    return (block - 1) * std::uint64_t{kBlockBytes};
  }

  // The number of frames. The header stores the first and last frame numbers in 16 bits (they
  // wrap past 65535), POINT:FRAMES the count in 16 bits (ezc3d writes -1 for more), and
  // TRIAL:ACTUAL_START/END_FIELD, when present, 32-bit frame numbers. A 16-bit count may stand
  // for that count plus any multiple of 65536: the data the file holds (`complete` frames)
  // decides. Preferred in that order among the counts the data can hold, as ezc3d prefers
  // POINT:FRAMES to the header; any disagreement is a warning that says which was used.
  std::uint64_t frame_count(std::uint64_t complete, MarkerTrial& trial) const {
    const auto unwrap = [&](std::uint64_t count16) {
      if (complete == std::numeric_limits<std::uint64_t>::max() || complete < count16) {
        return count16;
      }
      return count16 + (complete - count16) / 65536 * 65536;
    };
    std::vector<FrameCount> counts;
    const auto trial_first = field_number(find("TRIAL", "ACTUAL_START_FIELD"));
    const auto trial_last = field_number(find("TRIAL", "ACTUAL_END_FIELD"));
    const bool trial_range = trial_first && trial_last && std::uint64_t{*trial_last} + 1 >= *trial_first;
    if (trial_range) {
      counts.push_back({"TRIAL:ACTUAL_START_FIELD/END_FIELD (" + str(*trial_first) + " to " +
                            str(*trial_last) + ")",
                        std::uint64_t{*trial_last} + 1 - *trial_first});
    }
    const Parameter* frames_param = find("POINT", "FRAMES");
    const std::optional<std::uint32_t> point_frames = count(frames_param);
    if (point_frames && !(frames_param->type == 2 && *point_frames == 0xFFFF)) {
      counts.push_back({"POINT:FRAMES (" + str(*point_frames) + ")",
                        frames_param->type == 2 ? unwrap(*point_frames) : *point_frames});
    }
    const std::uint32_t first = header_word(c3d::kHeaderFirstFrame);
    const std::uint32_t last = header_word(c3d::kHeaderLastFrame);
    const std::uint64_t header_frames = unwrap((last + 65536u - first + 1u) % 65536u);
    counts.push_back(
        {"the header's frame range (" + str(first) + " to " + str(last) + ")", header_frames});

    const auto fits = std::find_if(counts.begin(), counts.end(),
                                   [&](const FrameCount& c) { return c.frames <= complete; });
    const FrameCount& used = fits != counts.end() ? *fits : counts.front();
    const bool agree = std::all_of(counts.begin(), counts.end(),
                                   [&](const FrameCount& c) { return c.frames == used.frames; });
    if (!agree) {
      std::string all;
      for (const FrameCount& c : counts) {
        all += (all.empty() ? "" : ", ") + c.source + ": " + str(c.frames) + " frames";
      }
      trial.warnings.push_back("frame counts disagree (" + all + "): read " + str(used.frames) +
                               " as " + used.source + " says" +
                               (fits != counts.end() ? "" : " (none fits the data)"));
    } else if (!trial_range && (last + 1u < first || header_frames > 65535)) {
      trial.warnings.push_back("the header's 16-bit frame numbers wrap past 65535 (first " +
                               str(first) + ", last " + str(last) + "): read " +
                               str(header_frames) + " frames");
    }
    return used.frames;
  }

  MarkerTrial read_points() {
    MarkerTrial trial;
    RecordingFacts& facts = trial.source;
    facts.format = "C3D";
    const std::uint32_t points =
        count(find("POINT", "USED")).value_or(header_word(c3d::kHeaderPoints));

    const double scale =
        number(find("POINT", "SCALE")).value_or(num_.f32(&header_[c3d::kHeaderScale]));
    if (points > 0 && (!std::isfinite(scale) || scale == 0.0)) {
      fail("parameter section: POINT:SCALE is " + std::to_string(scale) +
           " (it must be non-zero: positive for int16 data, negative for float data)");
    }
    const bool float_data = scale < 0.0;
    const std::size_t word_bytes = float_data ? 4 : 2;
    facts.number_format =
        std::string(c3d::processor_name(processor_)) + (float_data ? " float" : " int16");

    double rate_hz = number(find("POINT", "RATE")).value_or(0.0);
    if (!plausible_frame_rate(rate_hz)) rate_hz = num_.f32(&header_[c3d::kHeaderRate]);
    if (!plausible_frame_rate(rate_hz)) {
      // A file without points may have no point rate; it has no markers to time either.
      if (points > 0)
        fail(
            "parameter section: POINT:RATE and the header's frame rate are not frame rates (0.001 "
            "Hz to 1 MHz)");
      rate_hz = 0.0;
    }
    trial.rate_hz = rate_hz;

    const std::uint64_t data_at = data_offset(trial);
    const std::uint64_t analog = analog_values_per_frame(rate_hz, facts);
    read_rotation_facts(facts);
    const std::uint64_t frame_bytes = (std::uint64_t{points} * 4 + analog) * word_bytes;
    const std::uint64_t available = file_bytes_ > data_at ? file_bytes_ - data_at : 0;
    const std::uint64_t complete =
        frame_bytes > 0 ? available / frame_bytes : std::numeric_limits<std::uint64_t>::max();
    std::uint64_t frames = frame_count(complete, trial);

    // Frame numbers: TRIAL:ACTUAL_*_FIELD hold 32 bits, the header words only 16.
    const auto trial_first = field_number(find("TRIAL", "ACTUAL_START_FIELD"));
    const auto trial_last = field_number(find("TRIAL", "ACTUAL_END_FIELD"));
    const std::uint32_t first = trial_first && trial_last
                                    ? *trial_first
                                    : std::uint32_t{header_word(c3d::kHeaderFirstFrame)};
    if (first > static_cast<std::uint32_t>(std::numeric_limits<int>::max())) {
      fail("header: first frame " + str(first) + " is too large");
    }
    trial.first_frame = static_cast<int>(first);

    // Check the size before allocating anything: absurd counts end here.
    if (complete < frames) {
      const std::string held = "the file holds " + str(complete) + " complete of the " +
                               str(frames) + " frames it declares (" + str(frame_bytes) +
                               " bytes each from byte " + str(data_at) + "; the file has " +
                               str(file_bytes_) + " bytes)";
      if (!options_.allow_truncated_data)
        fail("3D data: truncated: " + held +
             ". Fix: export or copy the file again (it was cut short); `fabrik info` shows "
             "what the complete frames hold");
      if (complete == 0) fail("3D data: " + held);
      trial.warnings.push_back("3D data: " + held + ": read " + str(complete));
      frames = complete;
    }
    facts.frames = frames;

    const std::vector<std::string> units = strings(find("POINT", "UNITS"));
    // Absent or blank means the format's default, mm.
    facts.units = units.empty() || units[0].empty() ? "mm" : units[0];
    if (points == 0) return trial;
    const std::optional<double> to_m = detail::metres_per_unit(facts.units);
    if (!to_m) {
      fail("parameter section: POINT:UNITS '" + facts.units +
           "' is not supported (expected mm, cm or m)");
    }
    trial.labels = labels_of("POINT", points);
    if (find("POINT", "LABELS") == nullptr) fail("parameter section: POINT:LABELS missing");
    if (trial.labels.size() < points) {
      fail("parameter section: POINT:LABELS holds " + str(trial.labels.size()) + " labels for " +
           str(points) + " points");
    }
    detail::check_repeated_labels(
        trial, path_, options_, "parameter section: POINT:LABELS", "entries",
        [](std::size_t m) { return m + 1; },
        "rename one of them in POINT:LABELS (a C3D editor such as Mokka does it)");

    trial.positions_m.resize(frames * points);
    facts.zero_samples.assign(points, 0);
    const Eigen::Vector3d missing = Eigen::Vector3d::Constant(std::nan(""));
    const std::uint64_t chunk_frames = std::max<std::uint64_t>(1, (1u << 20) / frame_bytes);
    std::vector<std::uint8_t> buffer;
    for (std::uint64_t f0 = 0; f0 < frames; f0 += chunk_frames) {
      const std::uint64_t n = std::min(chunk_frames, frames - f0);
      buffer.resize(n * frame_bytes);
      read_at(data_at + f0 * frame_bytes, buffer.data(), buffer.size(), "3D data");
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
          if (valid && p.isZero(0.0)) {
            ++facts.zero_samples[m];
            valid = !options_.zeros_are_missing;
          }
          trial.positions_m[(f0 + f) * points + m] = valid && p.allFinite() ? p * *to_m : missing;
        }
      }
    }
    detail::warn_about_zeros(trial, options_);
    detail::warn_about_units(trial, "POINT:UNITS");
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

  // Analog values stored after each frame's points; the channels' count, rate and names go to
  // `facts`.
  std::uint64_t analog_values_per_frame(double point_rate_hz, RecordingFacts& facts) const {
    std::uint64_t analog = header_word(c3d::kHeaderAnalogValues);
    const std::uint32_t samples = header_word(c3d::kHeaderAnalogSamples);
    std::uint64_t channels = samples > 0 ? analog / samples : analog;
    double analog_rate_hz = point_rate_hz * samples;
    const std::optional<std::uint32_t> used = count(find("ANALOG", "USED"));
    if (used) {
      channels = *used;
      const double rate = number(find("ANALOG", "RATE")).value_or(0.0);
      const double ratio = rate / point_rate_hz;
      if (*used == 0) {
        analog = 0;
      } else if (ratio >= 0.5 && ratio < 1e6 && std::abs(ratio - std::round(ratio)) < 1e-3) {
        analog = *used * static_cast<std::uint64_t>(std::llround(ratio));
      }
      if (rate > 0.0 && std::isfinite(rate)) analog_rate_hz = rate;
    }
    facts.analog_channels = channels;
    facts.analog_rate_hz = channels > 0 && std::isfinite(analog_rate_hz) ? analog_rate_hz : 0.0;
    facts.analog_labels = labels_of("ANALOG", channels);
    return analog;
  }

  void read_rotation_facts(RecordingFacts& facts) const {
    facts.rotations = count(find("ROTATION", "USED")).value_or(0);
    facts.rotation_labels = labels_of("ROTATION", facts.rotations);
  }

  const std::string& path_;
  ReadOptions options_;
  std::ifstream in_;
  std::uint64_t file_bytes_ = 0;
  std::uint8_t header_[kBlockBytes] = {};
  std::uint64_t param_start_ = 0;
  C3dProcessor processor_ = C3dProcessor::intel;
  Numbers num_{C3dProcessor::intel};
  std::vector<std::uint8_t> section_;
  std::vector<Parameter> params_;
};
}  // namespace

MarkerTrial read_c3d(const std::string& path, const ReadOptions& options) {
  return C3dReader(path, options).read();
}

}  // namespace fabrik::io
