// TRC marker files: 5 header lines (PathFileType; header keys; header values; Frame# Time and
// marker names; X1 Y1 Z1 ...), then one tab-separated row per frame. Read as OpenSim reads
// them: header keys and values separated by any run of whitespace (OpenSim itself writes
// double tabs), data fields by single tabs.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "common/format_number.hpp"
#include "io/io_detail.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"

namespace fabrik::io {

namespace {
using detail::trim;

// Line 4 may hold thousands of marker names (line 5 their X/Y/Z), but not more than this; the
// other header lines hold a few words.
constexpr std::size_t kMaxNamesLineBytes = std::size_t{16} << 20;
constexpr std::size_t kMaxTrcHeaderLineBytes = std::size_t{64} << 10;
// Short rows are missing markers, so a row's text can be much smaller than what it costs in
// memory (24 bytes a marker): the positions may take this many times the file's size, or
// kMinPositionBudgetBytes, before the file is refused as not a recording.
constexpr std::uint64_t kPositionBytesPerFileByte = 64;
constexpr std::uint64_t kMinPositionBudgetBytes = std::uint64_t{16} << 20;
// Room beyond kTrcBytesPerField per column for a row's line ending and trailing whitespace.
constexpr std::size_t kRowSlackBytes = 4096;

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// Fields of `line` separated by runs of whitespace (header lines).
std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

std::vector<std::string_view> split_tabs(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t tab = line.find('\t', start);
    if (tab == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return fields;
    }
    fields.push_back(line.substr(start, tab - start));
    start = tab + 1;
  }
}

// The tab-separated fields of a data row, one at a time: a row costs no more than its text,
// however many empty fields it holds.
class Fields {
 public:
  explicit Fields(std::string_view line) : rest_(line) {}
  // The next field (trimmed), or nothing after the last.
  std::optional<std::string_view> next() {
    if (done_) return std::nullopt;
    const std::size_t tab = rest_.find('\t');
    const std::string_view field = rest_.substr(0, tab);
    if (tab == std::string_view::npos) {
      done_ = true;
    } else {
      rest_.remove_prefix(tab + 1);
    }
    return trim(field);
  }
  // Whether anything but whitespace is left.
  bool rest_is_blank() const { return done_ || trim(rest_).empty(); }

 private:
  std::string_view rest_;
  bool done_ = false;
};

// The whole (trimmed) field as a number; from_chars is locale-independent, unlike strtod.
std::optional<double> parse_number(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return std::nullopt;
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<std::size_t> parse_count(std::string_view s) {
  s = trim(s);
  std::size_t n = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), n);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return n;
}

bool equal_ci(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c + 32) : c; };
    if (lower(a[i]) != lower(b[i])) return false;
  }
  return true;
}

std::string quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;  // keep messages readable for garbage input
  return "'" + std::string(s.substr(0, kMax)) + (s.size() > kMax ? "...'" : "'");
}

class TrcParser {
 public:
  TrcParser(const std::string& path, std::istream& in, std::uint64_t file_bytes,
            const ReadOptions& options)
      : path_(path), in_(in), file_bytes_(file_bytes), options_(options) {}

  MarkerTrial parse() {
    check_magic();
    std::string line1, keys_line, values_line, names_line, axes_line;
    header_line(line1);
    header_line(keys_line);
    header_line(values_line);
    const Header header = read_header(keys_line, values_line);

    MarkerTrial trial;
    trial.source.format = "TRC";
    trial.source.number_format = "text";
    trial.rate_hz = rate_of(header, trial);
    const std::optional<std::string_view> units = header.value_of("Units");
    if (!units || units->empty()) fail("header: Units missing");
    const std::optional<double> to_m = detail::metres_per_unit(*units);
    if (!to_m) fail("header: Units " + quoted(*units) + " is not supported (expected mm, cm or m)");
    trial.source.units = std::string(*units);

    header_line(names_line, kMaxNamesLineBytes);
    Fields names(names_line);
    if (!equal_ci(names.next().value_or(""), "Frame#")) {
      fail("line 4: expected 'Frame#' and the marker names");
    }
    names.next();  // Time
    while (const std::optional<std::string_view> name = names.next()) {
      if (!name->empty()) trial.labels.emplace_back(*name);
    }
    detail::check_repeated_labels(
        trial, path_, options_, "line 4", "columns", [](std::size_t m) { return 3 + 3 * m; },
        "rename one of them in line 4 (names must be unique, as in OpenSim)");
    const std::size_t num_markers = trial.labels.size();
    const std::optional<std::size_t> declared_markers = header.count_of("NumMarkers", trial);
    if (declared_markers && *declared_markers != num_markers) {
      trial.warnings.push_back("header: NumMarkers is " + std::to_string(*declared_markers) +
                               " but line 4 names " + std::to_string(num_markers) +
                               " markers: read " + std::to_string(num_markers));
    }
    header_line(axes_line, kMaxNamesLineBytes);  // X1 Y1 Z1 ...: nothing to learn from it

    const std::size_t columns = 2 + 3 * num_markers;
    const std::size_t max_row_bytes = columns * kTrcBytesPerField + kRowSlackBytes;
    const std::uint64_t budget_bytes =
        std::max(kMinPositionBudgetBytes, kPositionBytesPerFileByte * file_bytes_);
    trial.source.zero_samples.assign(num_markers, 0);
    const Eigen::Vector3d missing = Eigen::Vector3d::Constant(std::nan(""));
    std::size_t rows = 0;
    std::string line;
    std::size_t most_fields_missing = 0;  // of the rows read so far
    while (next_line(line, max_row_bytes)) {
      if (trim(line).empty()) continue;  // blank separator and trailing lines
      if ((trial.positions_m.size() + num_markers) * sizeof(Eigen::Vector3d) > budget_bytes) {
        fail("line " + std::to_string(line_number_) + ": " + std::to_string(rows + 1) +
             " rows of " + std::to_string(num_markers) + " markers would take more than " +
             std::to_string(budget_bytes >> 20) + " MiB for a file of " +
             std::to_string(file_bytes_) + " bytes: rows this short are not a recording");
      }
      Fields fields(line);
      const std::string_view frame_field = fields.next().value_or("");
      const std::string_view time_field = fields.next().value_or("");
      if (rows == 0) {
        trial.first_frame = frame_number(frame_field);
        trial.first_time_frames = first_time_frames(time_field, trial.rate_hz);
      }
      // Time: rounded in OpenSim's files, so time comes from the rate; only its order is checked.
      check_time(trial, time_field, frame_field, rows);
      std::size_t fields_missing = 0;  // past the row's end: a short row
      for (std::size_t m = 0; m < num_markers; ++m) {
        Eigen::Vector3d p = missing;
        bool complete = true;
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const std::optional<std::string_view> got = fields.next();
          fields_missing += got ? 0 : 1;
          const std::string_view field = got.value_or("");
          if (field.empty()) {
            complete = false;  // a short row or an empty field: missing marker
            continue;
          }
          const std::optional<double> v = parse_number(field);
          if (!v) {
            fail("line " + std::to_string(line_number_) + ", column " +
                 std::to_string(3 + 3 * m + axis) + ": " + quoted(field) + " is not a number");
          }
          p[static_cast<Eigen::Index>(axis)] = *v;
        }
        if (complete && p.isZero(0.0)) {
          ++trial.source.zero_samples[m];
          complete = !options_.zeros_are_missing;
        }
        trial.positions_m.push_back(complete && p.allFinite() ? p * *to_m : missing);
      }
      // A last row without a line ending, shorter than every row before it, is a file cut
      // short (a copy or export interrupted), not a row with its last markers missing (a
      // writer that leaves out trailing empty fields writes its other rows as short).
      if (unterminated_ && fields_missing > most_fields_missing) {
        const std::string what =
            "line " + std::to_string(line_number_) + ", the last: the file ends inside this row, " +
            std::to_string(fields_missing) + " of its " + std::to_string(columns) +
            " columns missing and no line ending: it is truncated";
        const std::string fix = "Fix: copy or export the trial again";
        if (options_.refuse_ambiguous) fail(what + ". " + fix);
        trial.warnings.push_back(what + ": `fabrik solve` refuses the file. " + fix);
      }
      if (!fields.rest_is_blank()) {
        fail("line " + std::to_string(line_number_) + ": values beyond the " +
             std::to_string(columns) + " columns of Frame#, Time and " +
             std::to_string(num_markers) + " markers");
      }
      most_fields_missing = std::max(most_fields_missing, fields_missing);
      ++rows;
    }
    trial.source.frames = rows;
    const std::optional<std::size_t> declared_frames = header.count_of("NumFrames", trial);
    if (declared_frames && *declared_frames != rows) {
      trial.warnings.push_back("header: NumFrames is " + std::to_string(*declared_frames) +
                               " but the file has " + std::to_string(rows) +
                               " data rows: read " + std::to_string(rows));
    }
    report_time(trial);
    if (trial.source.time_backwards.rows == 0) check_rate(trial);
    detail::warn_about_zeros(trial, options_);
    detail::warn_about_units(trial, "Units (line 3)");
    return trial;
  }

 private:
  // Line 2's keys and line 3's values.
  struct Header {
    std::vector<std::string_view> keys, values;

    std::optional<std::string_view> value_of(std::string_view key) const {
      for (std::size_t i = 0; i < keys.size(); ++i) {
        if (equal_ci(trim(keys[i]), key)) {
          return i < values.size() ? trim(values[i]) : std::string_view();
        }
      }
      return std::nullopt;
    }
    // A whole number, or nothing (with a warning) when absent or unreadable: the data decide.
    std::optional<std::size_t> count_of(std::string_view key, MarkerTrial& trial) const {
      const std::optional<std::string_view> text = value_of(key);
      if (!text) return std::nullopt;
      const std::optional<std::size_t> n = parse_count(*text);
      if (!n) {
        trial.warnings.push_back("header: " + std::string(key) + " " + quoted(*text) +
                                 " is not a whole number: ignored");
      }
      return n;
    }
  };

  // Keys and values separated by runs of whitespace, as OpenSim reads them. When that gives a
  // different number of keys and values, an empty value sits between two tabs: then fields are
  // taken tab by tab.
  Header read_header(const std::string& keys_line, const std::string& values_line) const {
    Header h{split_words(keys_line), split_words(values_line)};
    if (h.keys.size() != h.values.size()) {
      std::vector<std::string_view> keys = split_tabs(keys_line), values = split_tabs(values_line);
      while (!keys.empty() && trim(keys.back()).empty()) keys.pop_back();
      while (values.size() > keys.size() && trim(values.back()).empty()) values.pop_back();
      if (keys.size() == values.size()) {
        h.keys = std::move(keys);
        h.values = std::move(values);
      }
    }
    return h;
  }

  // DataRate, or CameraRate when DataRate is absent or not a frame rate.
  double rate_of(const Header& header, MarkerTrial& trial) {
    const auto frame_rate = [](std::optional<std::string_view> text) -> std::optional<double> {
      if (!text) return std::nullopt;
      const std::optional<double> v = parse_number(*text);
      if (!v || !plausible_frame_rate(*v)) return std::nullopt;
      return v;
    };
    const std::optional<std::string_view> data = header.value_of("DataRate");
    const std::optional<std::string_view> camera = header.value_of("CameraRate");
    if (const auto rate = frame_rate(data)) return *rate;
    if (const auto rate = frame_rate(camera)) {
      rate_field_ = "CameraRate";
      // Said either way: the file's times and a solve's rate rest on it.
      trial.warnings.push_back(
          "header: " +
          (data ? "DataRate " + quoted(*data) + " is not a frame rate (0.001 Hz to 1 MHz)"
                : std::string("no DataRate")) +
          ": read the CameraRate, " + std::string(trim(*camera)) + " Hz");
      return *rate;
    }
    if (!data && !camera) fail("header: DataRate missing (line 2 names the header fields)");
    fail("header: DataRate " + quoted(data.value_or("")) + " and CameraRate " +
         quoted(camera.value_or("")) +
         " are not frame rates (0.001 Hz to 1 MHz). Fix: write the capture's rate in Hz as "
         "DataRate (line 3)");
  }

  [[noreturn]] void fail(const std::string& problem) const { throw FormatError(path_, problem); }

  // The first row's Time in frame periods: where the file's clock starts (frame 1 at 0 s in
  // OpenSim's own files, frame 23 at 0.23 s in others). A time within the rounding of the
  // decimals it is written with (0.417 for 25 / 60 s: 0.02 frame off at 60 Hz, 0.12 at
  // 240 Hz), or within a hundredth of a frame, is put on the frame grid, so every later time
  // is exactly (n + index) / rate.
  static double first_time_frames(std::string_view time_field, double rate_hz) {
    const std::optional<double> t = parse_number(time_field);
    if (!t || !std::isfinite(*t)) return std::numeric_limits<double>::quiet_NaN();
    const double frames = *t * rate_hz;
    const double off_frames = std::abs(frames - std::round(frames));
    return off_frames < std::max(0.01, written_rounding_s(time_field) * rate_hz)
               ? std::round(frames)
               : frames;
  }

  // Half the last decimal a number is written with (0.0005 for "0.417"), in its own unit, plus
  // a little for the binary value; 0 for a number with an exponent or without decimals.
  static double written_rounding_s(std::string_view field) {
    field = trim(field);
    const auto point = field.find('.');
    if (point == std::string_view::npos || field.find_first_of("eE") != std::string_view::npos)
      return 0.0;
    std::size_t decimals = 0;
    while (point + 1 + decimals < field.size() &&
           std::isdigit(static_cast<unsigned char>(field[point + 1 + decimals])))
      ++decimals;
    return 0.5 * std::pow(10.0, -static_cast<double>(decimals)) * (1.0 + 1e-9);
  }

  // Counts rows whose Time is before (backwards) or equal to (standing) the previous row's, and
  // keeps the first of each; a Time that is not a number is not compared.
  void check_time(MarkerTrial& trial, std::string_view time_field, std::string_view frame_field,
                  std::size_t row) {
    const std::optional<double> t = parse_number(time_field);
    if (!t || !std::isfinite(*t)) return;
    if (previous_time_ && *t <= *previous_time_) {
      TimeSteps& s =
          *t < *previous_time_ ? trial.source.time_backwards : trial.source.time_standing;
      if (s.rows++ == 0) {
        const std::optional<double> frame = parse_number(frame_field);
        s.first_frame =
            frame && std::abs(*frame) < 1e15
                ? static_cast<long long>(*frame)
                : static_cast<long long>(trial.first_frame) + static_cast<long long>(row);
        s.first_line = line_number_;
        s.time_s = *t;
        s.previous_s = *previous_time_;
      }
    }
    previous_time_ = t;
    const TimedRow timed{*t, row, line_number_, written_rounding_s(time_field)};
    if (!first_timed_) first_timed_ = timed;
    last_timed_ = timed;
  }

  // A Time column whose span disagrees with DataRate's by more than half a frame beyond the
  // times' rounding (a rate written wrong, or every other row exported): a warning, since the
  // rows are read 1/DataRate apart and the outputs' times follow DataRate.
  void check_rate(MarkerTrial& trial) const {
    if (!first_timed_ || !last_timed_ || last_timed_->row <= first_timed_->row) return;
    const double rows = static_cast<double>(last_timed_->row - first_timed_->row);
    const double span_s = last_timed_->time_s - first_timed_->time_s;
    const double expected_s = rows / trial.rate_hz;
    const double allowed_s =
        0.5 / trial.rate_hz + first_timed_->rounding_s + last_timed_->rounding_s;
    if (!(span_s > 0.0) || std::abs(span_s - expected_s) <= allowed_s) return;
    trial.warnings.push_back("the Time column runs at " + format_number("%.6g", rows / span_s) +
                             " Hz (" + format_number("%.9g", first_timed_->time_s) + " s at line " +
                             std::to_string(first_timed_->line) + " to " +
                             format_number("%.9g", last_timed_->time_s) + " s at line " +
                             std::to_string(last_timed_->line) + "), " + rate_field_ + " says " +
                             format_number("%.6g", trial.rate_hz) + " Hz: rows are read 1/" +
                             rate_field_ + " apart, so the outputs' times follow " + rate_field_ +
                             " (" + format_number("%.6g", expected_s) + " s for those rows, not " +
                             format_number("%.6g", span_s) + "). Fix: correct " + rate_field_ +
                             " (line 3), or the Time column");
  }

  // Time going back is refused (or a warning, see ReadOptions::refuse_ambiguous); standing still
  // is a warning: rows are read 1/rate apart whatever their Time says.
  void report_time(MarkerTrial& trial) const {
    const auto rows = [](const TimeSteps& s) {
      return std::to_string(s.rows) + (s.rows == 1 ? " row" : " rows") + " (the first at line " +
             std::to_string(s.first_line) + ", frame " + std::to_string(s.first_frame) + ": " +
             format_number("%.9g", s.time_s) + " s " +
             (s.time_s == s.previous_s ? std::string("as in the row before")
                                       : "after " + format_number("%.9g", s.previous_s) + " s") +
             ")";
    };
    const TimeSteps& back = trial.source.time_backwards;
    if (back.rows > 0) {
      const std::string what = "the Time column goes back in time at " + rows(back);
      const std::string fix =
          "Fix: put the rows in time order, or export the trial again: OpenSim refuses a Time "
          "column that does not increase";
      if (options_.refuse_ambiguous) fail(what + ". " + fix);
      trial.warnings.push_back(what + ": `fabrik solve` refuses the file. " + fix);
    }
    const TimeSteps& still = trial.source.time_standing;
    if (still.rows > 0) {
      trial.warnings.push_back(
          "the Time column stands still at " + rows(still) +
          ": read as every row is, 1/DataRate after the previous one (OpenSim refuses a Time "
          "column that repeats a value). Fix: if the times are rounded, write them with more "
          "digits; otherwise check DataRate and the rows");
    }
  }

  // Rejects binary or other files before reading a possibly huge "line" from them.
  void check_magic() {
    constexpr std::string_view kBom = "\xEF\xBB\xBF", kMagic = "PathFileType";
    char head[15] = {};
    in_.read(head, sizeof head);
    std::string_view got(head, static_cast<std::size_t>(in_.gcount()));
    in_.clear();
    std::streamoff skip = 0;
    if (got.substr(0, kBom.size()) == kBom) {
      got.remove_prefix(kBom.size());
      skip = static_cast<std::streamoff>(kBom.size());
    }
    if (got.substr(0, kMagic.size()) != kMagic) {
      fail("not a TRC file (it does not start with PathFileType)");
    }
    in_.seekg(skip);
  }

  // The next line without its line ending; FormatError if it is longer than `max_bytes`, before
  // it is stored whole.
  bool next_line(std::string& line, std::size_t max_bytes) {
    const detail::LineRead got = detail::read_line(in_, line, max_bytes);
    if (got == detail::LineRead::end) return false;
    ++line_number_;
    unterminated_ = got == detail::LineRead::unterminated;
    if (got == detail::LineRead::too_long) {
      fail("line " + std::to_string(line_number_) + " is longer than " +
           std::to_string(max_bytes) + " bytes, more than its columns can need: not a TRC row");
    }
    return true;
  }

  void header_line(std::string& line, std::size_t max_bytes = kMaxTrcHeaderLineBytes) {
    if (!next_line(line, max_bytes)) {
      fail("file ends inside the header, at line " + std::to_string(line_number_ + 1) + " of 5");
    }
  }

  int frame_number(std::string_view field) const {
    const std::optional<double> v = parse_number(field);
    if (!v || *v != std::floor(*v) || std::abs(*v) > std::numeric_limits<int>::max()) {
      fail("line " + std::to_string(line_number_) + ": frame number " + quoted(trim(field)) +
           " is not a whole number");
    }
    return static_cast<int>(*v);
  }

  const std::string& path_;
  std::istream& in_;
  std::uint64_t file_bytes_;
  ReadOptions options_;
  std::size_t line_number_ = 0;
  bool unterminated_ = false;  // the line read last ends the file without a line ending
  std::optional<double> previous_time_;
  std::string rate_field_ = "DataRate";  // the header field the rows' rate was read from
  // The first and last rows with a Time that is a number: the Time column's own rate.
  struct TimedRow {
    double time_s;
    std::size_t row, line;
    double rounding_s;  // half its last written decimal
  };
  std::optional<TimedRow> first_timed_, last_timed_;
};

void append_number(std::string& out, double v, int decimals) {
  char buf[400];  // fixed notation of the largest double with 9 decimals fits
  const auto r = decimals < 0
                     ? std::to_chars(buf, buf + sizeof buf, v)
                     : std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  out.append(buf, r.ptr);
}
}  // namespace

MarkerTrial read_trc(const std::string& path, const ReadOptions& options) {
  std::ifstream in = detail::open_input(path);
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  return TrcParser(path, in, ec ? 0 : bytes, options).parse();
}

void write_trc(const std::string& path, const MarkerTrial& trial, const std::string& units) {
  const double from_m = detail::check_trial_for_writing(trial, units, "write_trc");
  for (const std::string& label : trial.labels) {
    if (trim(label).empty() || label.find_first_of("\t\r\n") != std::string::npos) {
      throw std::invalid_argument("write_trc: marker label '" + label +
                                  "' is empty or holds a tab or line break");
    }
  }
  // 1 nm resolution either way: a read-back is well within 1e-6 m.
  const int decimals = units == "mm" ? 6 : 9;
  const std::size_t n = trial.markers(), frames = trial.frames();

  std::string text = "PathFileType\t4\t(X/Y/Z)\t" +
                     std::filesystem::path(path).filename().string() +
                     "\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
                     "OrigDataStartFrame\tOrigNumFrames\n";
  std::string rate;
  append_number(rate, trial.rate_hz, -1);
  text += rate + "\t" + rate + "\t" + std::to_string(frames) + "\t" + std::to_string(n) + "\t" +
          units + "\t" + rate + "\t" + std::to_string(trial.first_frame) + "\t" +
          std::to_string(frames) + "\nFrame#\tTime";
  for (const std::string& label : trial.labels) text += "\t" + label + "\t\t";
  text += "\n\t";
  for (std::size_t m = 1; m <= n; ++m) {
    const std::string k = std::to_string(m);
    text += "\tX" + k + "\tY" + k + "\tZ" + k;
  }
  text += "\n\n";  // OpenSim's files leave line 6 blank

  std::ofstream out = open_output_file(path);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  for (std::size_t f = 0; f < frames; ++f) {
    text = std::to_string(static_cast<long long>(trial.first_frame) + static_cast<long long>(f));
    text += '\t';
    append_number(text, trial.file_time_s(f), -1);  // shortest exact form, not rounded like OpenSim's
    for (std::size_t m = 0; m < n; ++m) {
      const Eigen::Vector3d& p = trial.at(f, m);
      if (!p.allFinite()) {
        text += "\t\t\t";
        continue;
      }
      for (int axis = 0; axis < 3; ++axis) {
        text += '\t';
        append_number(text, p[axis] * from_m, decimals);
      }
    }
    text += '\n';
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  }
  finish_output_file(out, path);
}

}  // namespace fabrik::io
