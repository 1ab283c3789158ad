// Marker files: TRC and C3D round trips in every number format, the real recordings in the
// shared data folder (facts from its SOURCES.md and read off the files by eye), and broken files
// (missing, truncated, garbage, absurd counts) failing with a FormatError that names the file.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "common/format_number.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"
#include "io/recording_info.hpp"
#include "temp_file.hpp"
#include "trc_text.hpp"

using namespace fabrik::io;
namespace fs = std::filesystem;

namespace {
const std::string kDataDir = FABRIK_SHARED_DATA_DIR;

using fabrik::test::TempFile;

// The path of a shared data file, or "" (with a warning) when it is not there.
std::string data_file(const std::string& name) {
  const std::string path = kDataDir + "/" + name;
  if (!fs::exists(path)) {
    WARN("skipped: " << path << " not found");
    return "";
  }
  return path;
}

std::vector<char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

void write_text(const std::string& path, const std::string& text) {
  write_bytes(path, std::vector<char>(text.begin(), text.end()));
}

// Offset of the first occurrence of `what` in `bytes` (fails the test if absent).
std::size_t find_bytes(const std::vector<char>& bytes, const std::string& what) {
  const auto it = std::search(bytes.begin(), bytes.end(), what.begin(), what.end());
  REQUIRE(it != bytes.end());
  return static_cast<std::size_t>(it - bytes.begin());
}

// The FormatError message of `read` (fails the test if it succeeds or throws anything else).
std::string error_of(const std::function<void()>& read) {
  try {
    read();
  } catch (const FormatError& e) {
    return e.what();
  }
  FAIL("the file was read but should have been rejected");
  return "";
}

// Smooth motion of `markers` markers within 2 m of the origin; every 7th sample missing.
MarkerTrial make_trial(std::size_t markers, std::size_t frames, bool gaps) {
  MarkerTrial t;
  for (std::size_t m = 0; m < markers; ++m) t.labels.push_back("M" + std::to_string(m + 1));
  t.rate_hz = 120.0;
  t.first_frame = 7;
  for (std::size_t f = 0; f < frames; ++f) {
    for (std::size_t m = 0; m < markers; ++m) {
      const double a = 0.05 * static_cast<double>(f) + 0.7 * static_cast<double>(m);
      Eigen::Vector3d p(1.9 * std::sin(a), 1.2 + 0.5 * std::cos(1.3 * a), -0.8 * std::sin(0.4 * a));
      if (gaps && (f * markers + m) % 7 == 3) p.setConstant(std::nan(""));
      t.positions_m.push_back(p);
    }
  }
  return t;
}

// Same labels, rate, first frame and NaN pattern; positions within `tol_m`.
void check_same(const MarkerTrial& a, const MarkerTrial& b, double tol_m) {
  REQUIRE(a.labels == b.labels);
  REQUIRE(a.frames() == b.frames());
  CHECK(a.rate_hz == Approx(b.rate_hz).epsilon(1e-7));
  CHECK(a.first_frame == b.first_frame);
  double worst_m = 0.0;
  std::size_t nan_mismatches = 0;
  for (std::size_t i = 0; i < a.positions_m.size(); ++i) {
    const bool a_nan = a.positions_m[i].hasNaN(), b_nan = b.positions_m[i].hasNaN();
    if (a_nan != b_nan) ++nan_mismatches;
    if (!a_nan && !b_nan) {
      worst_m = std::max(worst_m, (a.positions_m[i] - b.positions_m[i]).cwiseAbs().maxCoeff());
    }
  }
  CHECK(nan_mismatches == 0);
  CHECK(worst_m <= tol_m);
}

std::size_t count_missing(const MarkerTrial& t) {
  return static_cast<std::size_t>(
      std::count_if(t.positions_m.begin(), t.positions_m.end(),
                    [](const Eigen::Vector3d& p) { return p.hasNaN(); }));
}

void check_position(const MarkerTrial& t, std::size_t frame, const std::string& label,
                    const Eigen::Vector3d& expected_m, double tol_m) {
  const int m = t.find(label);
  REQUIRE(m >= 0);
  INFO(label << " at frame index " << frame << ": " << t.at(frame, std::size_t(m)).transpose());
  CHECK((t.at(frame, std::size_t(m)) - expected_m).cwiseAbs().maxCoeff() <= tol_m);
}
}  // namespace

TEST_CASE("MarkerTrial indexes frame-major and derives time from frame and rate", "[io]") {
  MarkerTrial t;
  t.labels = {"A", "B"};
  t.rate_hz = 60.0;
  for (int i = 0; i < 6; ++i) t.positions_m.emplace_back(i, 0, 0);
  CHECK(t.frames() == 3);
  CHECK(t.markers() == 2);
  CHECK(t.at(1, 0).x() == 2.0);
  CHECK(t.at(2, 1).x() == 5.0);
  t.at(2, 1).y() = 9.0;
  CHECK(t.positions_m[5].y() == 9.0);
  CHECK(t.time_s(30) == 0.5);
  CHECK(t.find("B") == 1);
  CHECK(t.find("C") == -1);
}

TEST_CASE("TRC round trip keeps labels, rate, first frame, gaps and positions", "[io][trc]") {
  const MarkerTrial original = make_trial(5, 40, true);
  for (const std::string units : {"mm", "m"}) {
    INFO("units " << units);
    TempFile file(".trc");
    write_trc(file.path(), original, units);
    check_same(read_trc(file.path()), original, 1e-6);

    // The header OpenSim and Mokka expect, and empty fields for a missing marker.
    std::ifstream in(file.path());
    std::string line1, line2, line3, line4, line5, line6, row1;
    std::getline(in, line1);
    std::getline(in, line2);
    std::getline(in, line3);
    std::getline(in, line4);
    std::getline(in, line5);
    std::getline(in, line6);
    std::getline(in, row1);
    CHECK(line1.rfind("PathFileType\t4\t(X/Y/Z)\t", 0) == 0);
    CHECK(line2 ==
          "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
          "OrigDataStartFrame\tOrigNumFrames");
    CHECK(line3 == "120\t120\t40\t5\t" + units + "\t120\t7\t40");
    CHECK(line4 == "Frame#\tTime\tM1\t\t\tM2\t\t\tM3\t\t\tM4\t\t\tM5\t\t");
    CHECK(line5.rfind("\t\tX1\tY1\tZ1\tX2", 0) == 0);
    CHECK(line6.empty());
    // Sample 3 (frame 0, marker M4) is missing: columns 12-14 empty. Frame 7's Time is
    // the source's: (7 - 1) / 120 s when the trial knows no other (frame 1 at 0 s).
    CHECK(row1.rfind("7\t0.05\t", 0) == 0);
    CHECK(read_trc(file.path()).file_time_s(0) == 0.05);
    CHECK(row1.find("\t\t\t\t") != std::string::npos);
  }
}

TEST_CASE("TRC reader tolerates CRLF, trailing tabs, blank lines and short rows", "[io][trc]") {
  TempFile file(".trc");
  write_text(file.path(),
             "PathFileType\t4\t(X/Y/Z)\tx.trc\r\n"
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\r\n"
             "100.00\t100.00\t   3\t2\tmm\r\n"
             "Frame#\tTime\tA\t\t\tB\t\t\t\r\n"
             "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\t\r\n"
             "\r\n"
             "10\t0.000\t1000\t2000\t-3000\t4\t5\t6\t\t\r\n"
             "11\t0.010\t\t\t\t4.5\t5\t+6e0\r\n"
             "12\t0.020\t1\t2\r\n"
             "\r\n"
             "\t\r\n");
  const MarkerTrial t = read_trc(file.path());
  REQUIRE(t.labels == std::vector<std::string>{"A", "B"});
  REQUIRE(t.frames() == 3);
  CHECK(t.rate_hz == 100.0);
  CHECK(t.first_frame == 10);
  CHECK(t.at(0, 0).isApprox(Eigen::Vector3d(1.0, 2.0, -3.0)));
  CHECK(t.at(0, 1).isApprox(Eigen::Vector3d(0.004, 0.005, 0.006)));
  CHECK(t.at(1, 0).hasNaN());  // empty fields
  CHECK(t.at(1, 1).isApprox(Eigen::Vector3d(0.0045, 0.005, 0.006)));
  CHECK(t.at(2, 0).hasNaN());  // a row cut short: Z missing
  CHECK(t.at(2, 1).hasNaN());  // and B absent
  CHECK(t.time_s(2) == Approx(0.02));
}

TEST_CASE("TRC reader rejects broken files with the path and the problem", "[io][trc]") {
  const std::string header =
      "PathFileType\t4\t(X/Y/Z)\tx.trc\n"
      "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n";
  const std::string names = "Frame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n\n";
  struct Case {
    const char* what;
    std::string text;
    const char* expected;
  };
  const std::vector<Case> cases = {
      {"unsupported units", header + "60\t60\t1\t1\tin\n" + names + "1\t0\t1\t2\t3\n",
       "Units 'in' is not supported (expected mm, cm or m)"},
      {"a word for a number", header + "60\t60\t1\t1\tmm\n" + names + "1\t0\t1\tabc\t3\n",
       "line 7, column 4: 'abc' is not a number"},
      {"zero rate", header + "0\t0\t1\t1\tmm\n" + names + "1\t0\t1\t2\t3\n",
       "DataRate '0' and CameraRate '0' are not frame rates (0.001 Hz to 1 MHz). Fix: write "
       "the capture's rate in Hz as DataRate (line 3)"},
      {"a rate no capture has", header + "1e-308\t1e308\t1\t1\tmm\n" + names + "1\t0\t1\t2\t3\n",
       "DataRate '1e-308' and CameraRate '1e308' are not frame rates (0.001 Hz to 1 MHz)"},
      {"no rate",
       "PathFileType\t4\t(X/Y/Z)\tx.trc\nNumFrames\tNumMarkers\tUnits\n1\t1\tmm\n" + names +
           "1\t0\t1\t2\t3\n",
       "DataRate missing"},
      {"no frame column", header + "60\t60\t1\t1\tmm\nTime\tA\t\t\n\tX1\tY1\tZ1\n\n",
       "line 4: expected 'Frame#'"},
      {"values past the last marker", header + "60\t60\t1\t1\tmm\n" + names + "1\t0\t1\t2\t3\t4\n",
       "values beyond"},
      {"header cut short", header, "file ends inside the header"},
      {"not a TRC file", "hello\n", "not a TRC file"},
      {"binary garbage", std::string("\x00\x50\xff\x10", 4), "not a TRC file"},
  };
  for (const Case& c : cases) {
    INFO(c.what);
    TempFile file(".trc");
    write_text(file.path(), c.text);
    const std::string message = error_of([&] { read_trc(file.path()); });
    CHECK(message.rfind(file.path() + ": ", 0) == 0);
    CHECK_THAT(message, Catch::Contains(c.expected));
  }
  const std::string missing = (fs::temp_directory_path() / "fabrik_no_such_file.trc").string();
  CHECK_THAT(error_of([&] { read_trc(missing); }), Catch::StartsWith(missing + ": file not found"));
}

TEST_CASE("subject01_walk1.trc: 41 markers, 151 frames at 60 Hz, mm read as metres",
          "[io][trc][data]") {
  const std::string path = data_file("subject01_walk1.trc");
  if (path.empty()) return;
  const MarkerTrial t = read_trc(path);
  CHECK(t.markers() == 41);
  CHECK(t.frames() == 151);
  CHECK(t.rate_hz == 60.0);
  CHECK(t.first_frame == 1);
  CHECK(t.labels.front() == "R.ASIS");
  CHECK(t.labels.back() == "Top.Head");
  CHECK(t.find("R.Knee.Med") == -1);  // medial markers are in the static trial only
  CHECK(count_missing(t) == 0);       // "no gaps"
  CHECK(t.time_s(150) == Approx(2.5));
  // Values read off the file: row 1 and row 151.
  check_position(t, 0, "R.ASIS", {0.61724762, 1.05527502, 0.17078198}, 1e-12);
  check_position(t, 0, "Top.Head", {0.74933246, 1.74760767, 0.04674146}, 1e-12);
  check_position(t, 150, "Top.Head", {0.61413971, 1.77627051, 0.02329867}, 1e-12);
}

TEST_CASE("subject01_static.trc: 49 markers, 300 frames, with the medial markers",
          "[io][trc][data]") {
  const std::string path = data_file("subject01_static.trc");
  if (path.empty()) return;
  const MarkerTrial t = read_trc(path);
  CHECK(t.markers() == 49);
  CHECK(t.frames() == 300);
  CHECK(t.rate_hz == 60.0);
  CHECK(t.find("R.Knee.Med") >= 0);
  CHECK(t.find("L.Ankle.Med") >= 0);
  CHECK(count_missing(t) == 0);
  check_position(t, 0, "R.ASIS", {0.60866431, 1.07271313, 0.15744215}, 1e-12);
  check_position(t, 299, "Top.Head", {0.57306628, 1.81821582, 0.03806445}, 1e-12);
}

TEST_CASE("arm26_elbow_flex.trc: 3 markers, 121 frames at 120 Hz", "[io][trc][data]") {
  const std::string path = data_file("arm26_elbow_flex.trc");
  if (path.empty()) return;
  const MarkerTrial t = read_trc(path);
  CHECK(t.labels ==
        std::vector<std::string>{"r_acromion", "r_humerus_epicondyle", "r_radius_styloid"});
  CHECK(t.frames() == 121);
  CHECK(t.rate_hz == 120.0);
  check_position(t, 0, "r_acromion", {-0.01305452443, 0.83950547557, 0.1695054756}, 1e-12);
  check_position(t, 120, "r_radius_styloid", {0.2310167559, 0.5005158582, 0.2309769121}, 1e-12);
}

TEST_CASE("Vicon.c3d: 51 points, 100 Hz, 580 frames, 305 missing samples, SCAP_CP gap of 71",
          "[io][c3d][data]") {
  const std::string path = data_file("Vicon.c3d");
  if (path.empty()) return;
  const MarkerTrial t = read_c3d(path);
  REQUIRE(t.markers() == 51);
  REQUIRE(t.frames() == 580);
  CHECK(t.rate_hz == 100.0);
  CHECK(t.first_frame == 1);
  CHECK(t.labels.front() == "boite:gauche_ext");
  CHECK(t.labels.back() == "Daphnee:LATH");

  std::size_t missing = 0, markers_with_gaps = 0, longest = 0;
  std::string longest_label;
  for (std::size_t m = 0; m < t.markers(); ++m) {
    std::size_t run = 0, count = 0;
    for (std::size_t f = 0; f < t.frames(); ++f) {
      run = t.at(f, m).hasNaN() ? run + 1 : 0;
      if (run > 0) ++count;
      if (run > longest) {
        longest = run;
        longest_label = t.labels[m];
      }
    }
    missing += count;
    if (count > 0) ++markers_with_gaps;
  }
  CHECK(missing == 305);
  CHECK(markers_with_gaps == 13);
  CHECK(longest == 71);
  CHECK(longest_label == "Daphnee:SCAP_CP");
  // First sample of the file (float data in mm).
  check_position(t, 0, "boite:gauche_ext", {0.0441627884, -0.2768619385, 0.6756968384}, 1e-9);
}

TEST_CASE("Optotrak.c3d declares 1149 frames but holds 29: rejected, or read on request",
          "[io][c3d][data]") {
  const std::string path = data_file("Optotrak.c3d");
  if (path.empty()) return;
  const std::string message = error_of([&] { read_c3d(path); });
  CHECK_THAT(message, Catch::StartsWith(path + ": 3D data: truncated"));
  CHECK_THAT(message, Catch::Contains("holds 29 complete of the 1149 frames"));

  const MarkerTrial t = read_c3d(path, C3dReadOptions{.allow_truncated_data = true});
  REQUIRE(t.markers() == 54);
  REQUIRE(t.frames() == 29);
  CHECK(t.rate_hz == 30.0);
  CHECK(t.first_frame == 1);
  CHECK(t.labels.front() == "Marker_1");
  CHECK(t.labels.back() == "Marker_54");
  // Float data with residual -1 for the missing: Marker_52 and _53 throughout, _54 once.
  CHECK(count_missing(t) == 59);
  for (std::size_t f = 0; f < t.frames(); ++f) {
    CHECK(t.at(f, 51).hasNaN());
    CHECK(t.at(f, 52).hasNaN());
    CHECK(t.at(f, 53).hasNaN() == (f == 0));
  }
  check_position(t, 0, "Marker_1", {0.3263137512, 0.3286311340, -0.3661706238}, 1e-9);
}

TEST_CASE("C3D round trip in every processor, number type and unit", "[io][c3d]") {
  const MarkerTrial original = make_trial(6, 50, true);
  double max_abs_m = 0.0;
  for (const Eigen::Vector3d& p : original.positions_m) {
    if (p.allFinite()) max_abs_m = std::max(max_abs_m, p.cwiseAbs().maxCoeff());
  }
  for (const C3dProcessor processor :
       {C3dProcessor::intel, C3dProcessor::dec, C3dProcessor::mips}) {
    for (const bool float_data : {false, true}) {
      for (const std::string units : {"mm", "m"}) {
        INFO("processor " << static_cast<int>(processor) << ", float " << float_data << ", "
                          << units);
        TempFile file(".c3d");
        write_c3d(file.path(), original, processor, float_data, units);
        const MarkerTrial back = read_c3d(file.path());
        // int16 data: half the scale (largest coordinate / 32000); float: float precision.
        const double tol_m = float_data ? 1e-6 : 0.5 * max_abs_m / 32000.0 * 1.0001;
        check_same(back, original, tol_m);
      }
    }
  }
}

TEST_CASE("C3D writer stores numbers in each processor's byte order", "[io][c3d]") {
  // Known answers worked out from the spec, independent of the reader: 100.0 and 1.0 and -0.5
  // as Intel (little-endian IEEE), MIPS (big-endian IEEE), DEC (VAX F: word-swapped, x4).
  MarkerTrial t;
  t.labels = {"A", "B", "C"};
  t.rate_hz = 100.0;
  t.positions_m = {{1.0, -0.5, 0.0}, {0.1, 0.2, 0.3}, {0.0, 0.0, 0.0}};
  struct Expected {
    C3dProcessor processor;
    int byte;
    std::vector<unsigned char> points, rate, one, minus_half;
  };
  const std::vector<Expected> cases = {
      {C3dProcessor::intel, 84, {3, 0}, {0, 0, 0xC8, 0x42}, {0, 0, 0x80, 0x3F}, {0, 0, 0, 0xBF}},
      {C3dProcessor::dec, 85, {3, 0}, {0xC8, 0x43, 0, 0}, {0x80, 0x40, 0, 0}, {0x00, 0xC0, 0, 0}},
      {C3dProcessor::mips, 86, {0, 3}, {0x42, 0xC8, 0, 0}, {0x3F, 0x80, 0, 0}, {0xBF, 0, 0, 0}},
  };
  for (const Expected& e : cases) {
    INFO("processor byte " << e.byte);
    TempFile file(".c3d");
    write_c3d(file.path(), t, e.processor, true, "m");
    const std::vector<char> b = read_bytes(file.path());
    REQUIRE(b.size() >= 1024);
    const auto bytes = [&](std::size_t at, std::size_t n) {
      return std::vector<unsigned char>(b.begin() + static_cast<std::ptrdiff_t>(at),
                                        b.begin() + static_cast<std::ptrdiff_t>(at + n));
    };
    CHECK(b[1] == 0x50);
    CHECK(static_cast<unsigned char>(b[512 + 3]) == e.byte);
    CHECK(bytes(2, 2) == e.points);
    CHECK(bytes(20, 4) == e.rate);
    const std::vector<unsigned char> start = bytes(16, 2);
    const std::size_t data_block = e.processor == C3dProcessor::mips
                                       ? std::size_t(start[0]) << 8 | start[1]
                                       : std::size_t(start[1]) << 8 | start[0];
    const std::size_t data = (data_block - 1) * 512;
    REQUIRE(b.size() >= data + 16);
    CHECK(bytes(data, 4) == e.one);
    CHECK(bytes(data + 4, 4) == e.minus_half);
    CHECK(read_c3d(file.path()).at(0, 0).isApprox(Eigen::Vector3d(1.0, -0.5, 0.0)));
  }
}

TEST_CASE("More than 255 markers go through POINT:LABELS2", "[io][c3d]") {
  const MarkerTrial original = make_trial(300, 3, true);
  TempFile file(".c3d");
  write_c3d(file.path(), original, C3dProcessor::intel, true);
  const std::vector<char> b = read_bytes(file.path());
  CHECK(std::search(b.begin(), b.end(), std::begin("LABELS2"), std::end("LABELS2") - 1) != b.end());
  check_same(read_c3d(file.path()), original, 1e-6);
}

TEST_CASE("Vicon.c3d written as TRC reads back the same", "[io][c3d][trc][data]") {
  const std::string path = data_file("Vicon.c3d");
  if (path.empty()) return;
  const MarkerTrial c3d = read_c3d(path);
  TempFile file(".trc");
  write_trc(file.path(), c3d);
  check_same(read_trc(file.path()), c3d, 1e-6);
}

TEST_CASE("read_trial picks the reader by extension, in any case", "[io]") {
  const MarkerTrial original = make_trial(2, 4, false);
  TempFile trc(".TRC"), c3d(".C3d"), other(".txt");
  write_trc(trc.path(), original);
  write_c3d(c3d.path(), original, C3dProcessor::intel, true);
  write_trc(other.path(), original);
  check_same(read_trial(trc.path()), original, 1e-6);
  check_same(read_trial(c3d.path()), original, 1e-6);
  CHECK_THAT(error_of([&] { read_trial(other.path()); }),
             Catch::StartsWith(other.path() + ": unknown file type '.txt'"));
}

TEST_CASE("Broken C3D files throw FormatError naming the file and the problem", "[io][c3d]") {
  TempFile good(".c3d");
  write_c3d(good.path(), make_trial(3, 20, true), C3dProcessor::intel, false);
  const std::vector<char> valid = read_bytes(good.path());
  REQUIRE(read_c3d(good.path()).frames() == 20);

  TempFile bad(".c3d");
  const auto message_for = [&](const std::vector<char>& bytes) {
    write_bytes(bad.path(), bytes);
    const std::string m = error_of([&] { read_c3d(bad.path()); });
    CHECK_THAT(m, Catch::StartsWith(bad.path() + ": "));
    return m;
  };
  const auto patched = [&](const std::string& after, std::size_t skip,
                           const std::vector<char>& with) {
    std::vector<char> b = valid;
    const std::size_t at = find_bytes(b, after) + after.size() + skip;
    std::copy(with.begin(), with.end(), b.begin() + static_cast<std::ptrdiff_t>(at));
    return b;
  };

  SECTION("missing file") {
    const std::string missing = (fs::temp_directory_path() / "fabrik_no_such_file.c3d").string();
    CHECK_THAT(error_of([&] { read_c3d(missing); }),
               Catch::StartsWith(missing + ": file not found"));
  }
  SECTION("empty and short files") {
    CHECK_THAT(message_for({}), Catch::Contains("fewer than the 512"));
    CHECK_THAT(message_for(std::vector<char>(valid.begin(), valid.begin() + 600)),
               Catch::Contains("parameter section: truncated"));
  }
  SECTION("garbage") {
    std::mt19937 rng(7);
    std::vector<char> noise(4096);
    for (char& c : noise) c = static_cast<char>(rng() & 0xFF);
    noise[1] = 0x51;
    CHECK_THAT(message_for(noise), Catch::Contains("header: not a C3D file"));
    noise[1] = 0x50;
    noise[0] = 2;
    noise[512 + 3] = 0;
    CHECK_THAT(message_for(noise), Catch::Contains("unknown processor type 0"));
  }
  SECTION("data cut short") {
    // 15 frames of 3 points x 4 int16 words, and part of the 16th.
    const std::size_t data_block = std::size_t(static_cast<unsigned char>(valid[17])) << 8 |
                                   static_cast<unsigned char>(valid[16]);
    const std::size_t keep = (data_block - 1) * 512 + 15 * 3 * 8 + 10;
    REQUIRE(keep < valid.size());
    std::vector<char> cut(valid.begin(), valid.begin() + static_cast<std::ptrdiff_t>(keep));
    CHECK_THAT(message_for(cut),
               Catch::Contains("3D data: truncated: the file holds 15 complete of the 20 frames") &&
                   Catch::Contains(". Fix: export or copy the file again (it was cut short)"));
    write_bytes(bad.path(), cut);
    CHECK(read_c3d(bad.path(), {.allow_truncated_data = true}).frames() == 15);
  }
  SECTION("absurd counts are caught before allocating") {
    // POINT:USED (the first USED: POINT is the first group) = 32767 points.
    CHECK_THAT(message_for(patched("USED", 4, {'\xff', '\x7f'})),
               Catch::Contains("holds 0 complete of the 20 frames"));
    // TRIAL:ACTUAL_END_FIELD's high word: about 4 billion frames, where POINT:FRAMES and the
    // header say 20 and the data hold them: read 20, saying so.
    write_bytes(bad.path(), patched("ACTUAL_END_FIELD", 7, {'\xff', '\xff'}));
    const MarkerTrial t = read_c3d(bad.path());
    CHECK(t.frames() == 20);
    REQUIRE(t.warnings.size() == 1);
    CHECK_THAT(t.warnings[0], Catch::Contains("frame counts disagree") &&
                                  Catch::Contains("POINT:FRAMES (20): 20 frames") &&
                                  Catch::Contains("read 20 as POINT:FRAMES (20) says"));
  }
  SECTION("frame rates outside 0.001 Hz to 1 MHz") {
    // An Intel float, as the file's own numbers: POINT:RATE's value follows its name, its
    // offset, type and dimension count; the header's rate is bytes 20-23.
    const auto f32 = [](float v) {
      std::vector<char> b(4);
      std::memcpy(b.data(), &v, 4);
      return b;
    };
    std::vector<char> b = patched("RATE", 4, f32(2e6F));
    write_bytes(bad.path(), b);
    CHECK(read_c3d(bad.path()).rate_hz == 120.0);  // the header's rate stands in
    const std::vector<char> header_rate = f32(0.0F);
    std::copy(header_rate.begin(), header_rate.end(), b.begin() + 20);
    CHECK_THAT(message_for(b), Catch::Contains("POINT:RATE and the header's frame rate are not "
                                               "frame rates (0.001 Hz to 1 MHz)"));
    const std::vector<char> slow = patched("RATE", 4, f32(0.0005F));
    std::vector<char> both_slow = slow;
    std::copy(header_rate.begin(), header_rate.end(), both_slow.begin() + 20);
    CHECK_THAT(message_for(both_slow), Catch::Contains("are not frame rates"));
    CHECK(read_c3d(good.path()).rate_hz == 120.0);
  }
  SECTION("parameters missing or wrong") {
    CHECK_THAT(message_for(patched("LABEL", 0, {'X'})),
               Catch::Contains("parameter section: POINT:LABELS missing"));
    CHECK_THAT(message_for(patched("UNITS", 5, {'i', 'n'})),
               Catch::Contains("POINT:UNITS 'in' is not supported"));
    CHECK_THAT(message_for(patched("SCALE", 4, {0, 0, 0, 0})), Catch::Contains("POINT:SCALE"));
    CHECK_THAT(message_for(patched("POINT", 0, {'\x00', '\x80'})),
               Catch::Contains("points backwards"));
  }
}

TEST_CASE("Any truncation or corruption of a C3D gives a trial or a FormatError", "[io][c3d]") {
  TempFile good(".c3d"), bad(".c3d");
  write_c3d(good.path(), make_trial(4, 30, true), C3dProcessor::mips, false);
  const std::vector<char> valid = read_bytes(good.path());
  std::size_t rejected = 0, read = 0, other = 0;
  const auto attempt = [&](const std::vector<char>& bytes) {
    write_bytes(bad.path(), bytes);
    try {
      const MarkerTrial t = read_c3d(bad.path());
      CHECK(t.positions_m.size() == t.frames() * t.markers());
      ++read;
    } catch (const FormatError&) {
      ++rejected;
    } catch (...) {
      ++other;
    }
  };
  for (std::size_t size = 0; size < valid.size(); size += 7) {
    attempt(std::vector<char>(valid.begin(), valid.begin() + static_cast<std::ptrdiff_t>(size)));
  }
  std::mt19937 rng(42);
  for (int i = 0; i < 3000; ++i) {
    std::vector<char> b = valid;
    const int changes = 1 + static_cast<int>(rng() % 4);
    for (int c = 0; c < changes; ++c) b[rng() % 1024] = static_cast<char>(rng() & 0xFF);
    attempt(b);
  }
  CHECK(other == 0);
  CHECK(rejected > 0);
  CHECK(read > 0);
}

// ---- Files as other tools write them (issue: recordings from any lab) ----

namespace {
// A TRC file with `rate_line`'s header values, two markers A and B and three rows.
std::string small_trc(const std::string& keys_line, const std::string& values_line,
                      const std::string& names_line = "Frame#\tTime\tA\t\t\tB\t\t\t") {
  return "PathFileType\t4\t(X/Y/Z)\tx.trc\n" + keys_line + "\n" + values_line + "\n" + names_line +
         "\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\n"
         "1\t0.000\t1\t2\t3\t4\t5\t6\n"
         "2\t0.010\t1.5\t2\t3\t4\t5\t6\n"
         "3\t0.020\t2\t2\t3\t4\t5\t6\n";
}
const std::string kKeys =
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\t"
    "OrigNumFrames";

MarkerTrial read_text_trc(const std::string& text, const ReadOptions& options = {}) {
  TempFile file(".trc");
  write_text(file.path(), text);
  return read_trc(file.path(), options);
}
}  // namespace

TEST_CASE("TRC header values separated by runs of whitespace, as OpenSim writes them",
          "[io][trc]") {
  // OpenSim's own motion_capture_walk.trc: double tabs, and spaces before some values.
  const MarkerTrial t = read_text_trc(
      small_trc("DataRate\t\tCameraRate\t\tNumFrames\t\tNumMarkers\t\tUnits\t\tOrigDataRate\t\t"
                "OrigDataStartFrame\t\tOrigNumFrames",
                "100.0\t\t100.0\t\t3\t\t2\t\t mm\t 100.0\t 1\t 3"));
  CHECK(t.rate_hz == 100.0);
  CHECK(t.labels == std::vector<std::string>{"A", "B"});
  REQUIRE(t.frames() == 3);
  CHECK(t.at(1, 0).isApprox(Eigen::Vector3d(0.0015, 0.002, 0.003)));
  CHECK(t.source.units == "mm");
  CHECK(t.warnings.empty());

  // An empty value between two tabs keeps the others in their columns.
  const MarkerTrial e = read_text_trc(small_trc(kKeys, "100\t100\t3\t2\tmm\t\t1\t3"));
  CHECK(e.rate_hz == 100.0);
  CHECK(e.source.units == "mm");
  CHECK(e.warnings.empty());
}

TEST_CASE("TRC units in any case, mm, cm or m, converted to metres", "[io][trc]") {
  for (const auto& [units, to_m] : std::vector<std::pair<std::string, double>>{
           {"mm", 0.001}, {"MM", 0.001}, {"Mm", 0.001}, {"cm", 0.01}, {"CM", 0.01},
           {"m", 1.0}, {"M", 1.0}, {"meters", 1.0}}) {
    INFO("units " << units);
    const MarkerTrial t = read_text_trc(small_trc(kKeys, "100\t100\t3\t2\t" + units + "\t100\t1\t3"));
    REQUIRE(t.frames() == 3);
    CHECK(t.at(2, 1).isApprox(Eigen::Vector3d(4, 5, 6) * to_m));
    CHECK(t.source.units == units);
  }
}

TEST_CASE("TRC Frame# in any case", "[io][trc]") {
  for (const std::string frame : {"Frame#", "frame#", "FRAME#"}) {
    const MarkerTrial t = read_text_trc(
        small_trc(kKeys, "100\t100\t3\t2\tmm\t100\t1\t3", frame + "\tTime\tA\t\t\tB\t\t\t"));
    CHECK(t.frames() == 3);
  }
}

TEST_CASE("TRC DataRate 0 or absent with CameraRate set reads at the CameraRate, with a warning",
          "[io][trc]") {
  const MarkerTrial t = read_text_trc(small_trc(kKeys, "0\t120\t3\t2\tmm\t0\t1\t3"));
  CHECK(t.rate_hz == 120.0);
  REQUIRE(t.warnings.size() == 1);
  CHECK_THAT(t.warnings[0], Catch::Contains("DataRate '0' is not a frame rate (0.001 Hz to 1 MHz): "
                                            "read the CameraRate, 120 Hz"));
  // No DataRate at all: the CameraRate, said (it was read silently).
  const MarkerTrial c = read_text_trc(small_trc("CameraRate\tNumFrames\tNumMarkers\tUnits",
                                                "100\t3\t2\tmm"));  // the rows' rate
  CHECK(c.rate_hz == 100.0);
  REQUIRE(c.warnings.size() == 1);
  CHECK(c.warnings[0] == "header: no DataRate: read the CameraRate, 100 Hz");
}

TEST_CASE("TRC NumFrames and NumMarkers that disagree with the data: the data win, with warnings",
          "[io][trc]") {
  struct Case {
    const char* values;  // line 3
    std::size_t markers;
    const char* warning;
  };
  const std::vector<Case> cases = {
      {"100\t100\t200\t2\tmm\t100\t1\t200", 2,
       "header: NumFrames is 200 but the file has 3 data rows: read 3"},
      {"100\t100\t1\t2\tmm\t100\t1\t1", 2,
       "header: NumFrames is 1 but the file has 3 data rows: read 3"},
      {"100\t100\t3\t41\tmm\t100\t1\t3", 2,
       "header: NumMarkers is 41 but line 4 names 2 markers: read 2"},
      {"100\t100\t3\tmany\tmm\t100\t1\t3", 2,
       "header: NumMarkers 'many' is not a whole number: ignored"},
  };
  for (const Case& c : cases) {
    INFO(c.values);
    const MarkerTrial t = read_text_trc(small_trc(kKeys, c.values));
    CHECK(t.markers() == c.markers);
    CHECK(t.frames() == 3);
    CHECK(t.source.frames == 3);
    CHECK(t.warnings == std::vector<std::string>{c.warning});
  }
}

TEST_CASE("subject01_walk1 with OpenSim's double-tab header reads identically to the original",
          "[io][trc][data]") {
  const std::string path = data_file("subject01_walk1.trc");
  if (path.empty()) return;
  const std::vector<char> bytes = read_bytes(path);
  std::string text(bytes.begin(), bytes.end());
  // Lines 2 and 3 rewritten the way OpenSim's motion_capture_walk.trc has them.
  const std::size_t l2 = text.find('\n') + 1, l3 = text.find('\n', l2) + 1,
                    l4 = text.find('\n', l3) + 1;
  std::string keys = text.substr(l2, l3 - l2), values = text.substr(l3, l4 - l3);
  for (std::string* line : {&keys, &values}) {
    std::string doubled;
    for (char c : *line) doubled += c == '\t' ? std::string("\t\t ") : std::string(1, c);
    *line = doubled;
  }
  REQUIRE(values.find("\t\t mm") != std::string::npos);
  TempFile copy(".trc");
  write_text(copy.path(), text.substr(0, l2) + keys + values + text.substr(l4));
  const MarkerTrial original = read_trc(path), opensim = read_trc(copy.path());
  check_same(opensim, original, 0.0);
  CHECK(opensim.warnings.empty());
}

TEST_CASE("An exact (0, 0, 0) is a missing marker by default, in TRC and C3D", "[io][trc][c3d]") {
  MarkerTrial trial = make_trial(3, 10, false);
  for (std::size_t f = 0; f < 10; ++f) trial.at(f, 1).setZero();  // M2 "not seen" throughout
  trial.at(4, 2) = Eigen::Vector3d(0.0, 0.0, 0.001);                // near the origin: a position
  trial.at(6, 0) = Eigen::Vector3d(-0.0, 0.0, 0.0);                 // -0 is zero too
  TempFile trc(".trc"), c3d(".c3d");
  write_trc(trc.path(), trial);
  write_c3d(c3d.path(), trial, C3dProcessor::intel, true);
  for (const std::string& path : {trc.path(), c3d.path()}) {
    INFO(path);
    const MarkerTrial t = read_trial(path);
    CHECK(t.source.zero_samples == std::vector<std::size_t>{1, 10, 0});
    CHECK(count_missing(t) == 11);
    CHECK(t.at(3, 1).hasNaN());
    CHECK(t.at(6, 0).hasNaN());
    CHECK(t.at(4, 2).isApprox(Eigen::Vector3d(0.0, 0.0, 0.001)));
    REQUIRE(t.warnings.size() == 1);
    CHECK_THAT(t.warnings[0], Catch::StartsWith("11 samples of 2 markers are exactly (0, 0, 0) "
                                                "(most: M2, 10 of 10 frames): read as missing"));

    const MarkerTrial kept = read_trial(path, {.zeros_are_missing = false});
    CHECK(kept.source.zero_samples == std::vector<std::size_t>{1, 10, 0});
    CHECK(count_missing(kept) == 0);
    CHECK(kept.at(3, 1) == Eigen::Vector3d::Zero());
    REQUIRE(kept.warnings.size() == 1);
    CHECK_THAT(kept.warnings[0], Catch::Contains("kept as positions at the origin"));
  }
  // A missing sample written as zeros with a negative residual is missing, not a zero.
  MarkerTrial gaps = make_trial(2, 5, false);
  gaps.at(2, 0).setConstant(std::nan(""));
  write_c3d(c3d.path(), gaps, C3dProcessor::dec, false);
  const MarkerTrial g = read_c3d(c3d.path());
  CHECK(g.source.zero_samples == std::vector<std::size_t>{0, 0});
  CHECK(count_missing(g) == 1);
  CHECK(g.warnings.empty());
}

TEST_CASE("A TRC row may cost no more than its columns need", "[io][trc]") {
  // A data row that is one run of tabs (a 20 MB one peaked at 564 MB when every empty field
  // was materialised): refused as soon as it is longer than two markers' columns can need.
  const std::string head = small_trc(kKeys, "100\t100\t3\t2\tmm\t100\t1\t3");
  const std::size_t limit = (2 + 3 * 2) * kTrcBytesPerField + 4096;
  const std::string message = error_of(
      [&] { read_text_trc(head + "4\t0.03" + std::string(std::size_t{1} << 20, '\t') + "\n"); });
  CHECK_THAT(message, Catch::Contains("line 10 is longer than " + std::to_string(limit) +
                                      " bytes, more than its columns can need"));
  // Short rows are missing markers, but a file of 20000 names and rows holding only a frame
  // number would cost 24 bytes a marker a row: refused once that passes 64 times its size.
  std::string names = "Frame#\tTime";
  for (int m = 0; m < 20000; ++m) names += "\tM" + std::to_string(m) + "\t\t";
  std::string sparse = "PathFileType\t4\t(X/Y/Z)\tx.trc\n" + kKeys +
                       "\n100\t100\t60\t20000\tmm\t100\t1\t60\n" + names + "\n\n\n";
  for (int f = 1; f <= 60; ++f) sparse += std::to_string(f) + "\n";
  CHECK_THAT(error_of([&] { read_text_trc(sparse); }),
             Catch::Contains("rows of 20000 markers would take more than 16 MiB") &&
                 Catch::Contains("rows this short are not a recording"));
  // Trailing tabs and spaces within the bound are still fine.
  const MarkerTrial t = read_text_trc(head + "4\t0.03\t1\t2\t3" + std::string(2000, '\t') + "\n");
  CHECK(t.frames() == 4);
  CHECK(t.at(3, 1).hasNaN());
}

TEST_CASE("A DEC C3D whose POINT:DATA_START is 0 reads like the correct one, with a warning",
          "[io][c3d]") {
  const MarkerTrial original = make_trial(23, 67, true);  // the DEC file: 23 points, 25 Hz
  for (const bool float_data : {false, true}) {
    INFO((float_data ? "float" : "int16"));
    TempFile good(".c3d"), zero(".c3d");
    C3dWriteOptions o{.processor = C3dProcessor::dec, .float_data = float_data};
    write_c3d(good.path(), original, o);
    o.point_data_start_zero = true;
    write_c3d(zero.path(), original, o);
    const MarkerTrial expected = read_c3d(good.path()), t = read_c3d(zero.path());
    CHECK(expected.warnings.empty());
    check_same(t, expected, 0.0);
    CHECK(t.source.number_format == (float_data ? "DEC float" : "DEC int16"));
    REQUIRE(t.warnings.size() == 1);
    CHECK_THAT(t.warnings[0],
               Catch::StartsWith("POINT:DATA_START is block 0, not after the parameter section: "
                                 "read the 3D data from the header's data start, block"));
  }
}

TEST_CASE("C3D frame counts: the header's wrapped 16-bit numbers, POINT:FRAMES, and which is used",
          "[io][c3d]") {
  SECTION("header first 32769, last 32768: 65536 frames") {
    const MarkerTrial original = make_trial(1, 65536, false);
    for (const long point_frames : {0L, 65535L}) {  // 65536 in 16 bits, and ezc3d's -1
      INFO("POINT:FRAMES " << point_frames);
      TempFile file(".c3d");
      write_c3d(file.path(), original,
                C3dWriteOptions{.trial_group = false, .header_first_frame = 32769,
                                .point_frames = point_frames});
      const std::vector<char> bytes = read_bytes(file.path());
      REQUIRE(static_cast<unsigned char>(bytes[6]) + 256 * static_cast<unsigned char>(bytes[7]) ==
              32769);
      REQUIRE(static_cast<unsigned char>(bytes[8]) + 256 * static_cast<unsigned char>(bytes[9]) ==
              32768);
      const MarkerTrial t = read_c3d(file.path());
      REQUIRE(t.frames() == 65536);
      CHECK(t.first_frame == 32769);
      CHECK(t.at(65535, 0).isApprox(original.at(65535, 0), 1e-6));
      REQUIRE(t.warnings.size() == 1);
      CHECK_THAT(t.warnings[0], Catch::Contains("the header's 16-bit frame numbers wrap past "
                                                "65535 (first 32769, last 32768): read 65536"));
    }
  }
  SECTION("POINT:FRAMES smaller than the header's range: POINT:FRAMES, as ezc3d") {
    TempFile file(".c3d");
    write_c3d(file.path(), make_trial(2, 20, false),
              C3dWriteOptions{.trial_group = false, .point_frames = 15});
    const MarkerTrial t = read_c3d(file.path());
    CHECK(t.frames() == 15);
    REQUIRE(t.warnings.size() == 1);
    CHECK(t.warnings[0] ==
          "frame counts disagree (POINT:FRAMES (15): 15 frames, the header's frame range (7 to "
          "26): 20 frames): read 15 as POINT:FRAMES (15) says");
  }
  SECTION("POINT:FRAMES larger than the data: the header's range, which the data hold") {
    TempFile file(".c3d");  // 20 markers: the padding to the next block holds no whole frame
    write_c3d(file.path(), make_trial(20, 20, false),
              C3dWriteOptions{.trial_group = false, .point_frames = 30});
    const MarkerTrial t = read_c3d(file.path());
    CHECK(t.frames() == 20);
    REQUIRE(t.warnings.size() == 1);
    CHECK_THAT(t.warnings[0], Catch::EndsWith("read 20 as the header's frame range (7 to 26) says"));
  }
}

TEST_CASE("C3D analog channels and rotations are counted and skipped, the points read right",
          "[io][c3d]") {
  const MarkerTrial original = make_trial(4, 30, true);
  for (const bool float_data : {false, true}) {
    INFO((float_data ? "float" : "int16"));
    TempFile file(".c3d");
    write_c3d(file.path(), original,
              C3dWriteOptions{.processor = C3dProcessor::mips, .float_data = float_data,
                              .analog_channels = 6, .analog_samples_per_frame = 10,
                              .rotations = 2});
    const MarkerTrial t = read_c3d(file.path());
    check_same(t, original, float_data ? 1e-6 : 1e-4);
    CHECK(t.warnings.empty());
    CHECK(t.source.analog_channels == 6);
    CHECK(t.source.analog_rate_hz == 1200.0);
    CHECK(t.source.analog_labels.size() == 6);
    CHECK(t.source.analog_labels[5] == "Analog6");
    CHECK(t.source.rotations == 2);
    CHECK(t.source.rotation_labels == std::vector<std::string>{"Segment1", "Segment2"});
  }
}

TEST_CASE("A C3D without 3D points reads as no markers, and says what it holds instead",
          "[io][c3d]") {
  MarkerTrial none;
  none.rate_hz = 100.0;
  SECTION("analog only (a force-plate file)") {
    TempFile file(".c3d");
    write_c3d(file.path(), none,
              C3dWriteOptions{.analog_channels = 8, .analog_samples_per_frame = 10,
                              .frames_without_points = 50});
    const MarkerTrial t = read_c3d(file.path());
    CHECK(t.markers() == 0);
    CHECK(t.source.frames == 50);
    CHECK(t.source.analog_channels == 8);
    CHECK(t.source.analog_rate_hz == 1000.0);
    CHECK_THAT(error_of([&] { require_marker_data(t, file.path()); }),
               Catch::StartsWith(file.path() + ": the file has no 3D marker data; it has 8 analog "
                                               "channels at 1000 Hz over 50 frames. Fix:"));
  }
  SECTION("rotations only") {
    TempFile file(".c3d");
    write_c3d(file.path(), none, C3dWriteOptions{.rotations = 3, .frames_without_points = 40});
    const MarkerTrial t = read_c3d(file.path());
    CHECK(t.markers() == 0);
    CHECK(t.source.rotations == 3);
    CHECK_THAT(error_of([&] { require_marker_data(t, file.path()); }),
               Catch::Contains("the file has no 3D marker data; it has 3 rotations over 40 "
                               "frames"));
  }
  SECTION("nothing at all, and markers without frames") {
    TempFile file(".c3d");
    write_c3d(file.path(), none, C3dWriteOptions{});
    CHECK_THAT(error_of([&] { require_marker_data(read_c3d(file.path()), file.path()); }),
               Catch::Contains("no 3D marker data; it has no other data either"));
    MarkerTrial empty = make_trial(2, 0, false);
    CHECK_THAT(error_of([&] { require_marker_data(empty, "x.trc"); }),
               Catch::StartsWith("x.trc: the file has 2 markers but no frames"));
  }
}

TEST_CASE("An empty string parameter ending exactly at the end of the parameter section",
          "[io][c3d]") {
  // test_io is built with _GLIBCXX_ASSERTIONS: taking &section[size] for the empty value aborts.
  std::vector<char> bytes(1024, 0);
  bytes[0] = 2;       // parameter section at block 2
  bytes[1] = 0x50;
  bytes[16] = 3;      // header word 9: data start block 3 (the end of the file: no frames)
  bytes[6] = 1;       // first frame 1, last 0: no frames
  char* section = &bytes[512];
  section[1] = 0x50;
  section[2] = 1;     // one block
  section[3] = 84;    // Intel
  // Group POINT at byte 4; its "next" offset (at byte 11) jumps to byte 500.
  const std::string group = "\x05\xff" "POINT";
  std::copy(group.begin(), group.end(), section + 4);
  section[11] = static_cast<char>((500 - 11) & 0xFF);
  section[12] = static_cast<char>((500 - 11) >> 8);
  // POINT:UNITS, a character parameter of length 0: 12 bytes ending at byte 512.
  const std::string units("\x05\x01UNITS\x00\x00\xff\x01\x00", 12);
  std::copy(units.begin(), units.end(), section + 500);
  TempFile file(".c3d");
  write_bytes(file.path(), bytes);
  const MarkerTrial t = read_c3d(file.path());
  CHECK(t.markers() == 0);
  CHECK(t.source.units == "mm");  // blank: the format's default
}

// ---- What a recording holds (`fabrik info`) ----

TEST_CASE("inspect_recording: markers with missing samples, exact zeros and longest gaps",
          "[io][info]") {
  MarkerTrial trial = make_trial(3, 20, false);
  for (std::size_t f = 5; f < 12; ++f) trial.at(f, 0).setConstant(std::nan(""));  // a 7-frame gap
  trial.at(15, 0).setConstant(std::nan(""));
  for (std::size_t f = 0; f < 20; f += 2) trial.at(f, 2).setZero();  // every other frame zero
  TempFile trc(".trc");
  write_trc(trc.path(), trial);
  const RecordingInfo info = inspect_recording(trc.path());
  CHECK(info.kind == "markers");
  CHECK(info.trial.source.format == "TRC");
  CHECK(info.trial.source.frames == 20);
  REQUIRE(info.markers.size() == 3);
  CHECK(info.markers[0].missing == 8);
  CHECK(info.markers[0].longest_gap == 7);
  CHECK(info.markers[0].zeros == 0);
  CHECK(info.markers[1].missing == 0);
  CHECK(info.markers[2].missing == 10);
  CHECK(info.markers[2].zeros == 10);
  CHECK(info.markers[2].longest_gap == 1);
  CHECK(info.trial.warnings.size() == 1);  // the zeros
}

TEST_CASE("inspect_recording: a C3D with analog channels only, and a truncated one",
          "[io][info][c3d]") {
  MarkerTrial none;
  none.rate_hz = 50.0;
  TempFile c3d(".c3d");
  write_c3d(c3d.path(), none,
            C3dWriteOptions{.processor = C3dProcessor::dec, .float_data = false,
                            .analog_channels = 4, .analog_samples_per_frame = 20,
                            .frames_without_points = 30});
  const RecordingInfo info = inspect_recording(c3d.path());
  CHECK(info.trial.markers() == 0);
  CHECK(info.trial.source.number_format == "DEC int16");
  CHECK(info.trial.source.frames == 30);
  CHECK(info.trial.source.analog_channels == 4);
  CHECK(info.trial.source.analog_rate_hz == 1000.0);

  // Truncated data are shown as far as they go, with a warning.
  write_c3d(c3d.path(), make_trial(30, 20, false), C3dProcessor::intel, true);
  std::vector<char> bytes = read_bytes(c3d.path());
  bytes.resize(bytes.size() - 512 * 4);
  write_bytes(c3d.path(), bytes);
  const RecordingInfo cut = inspect_recording(c3d.path());
  CHECK(cut.trial.frames() < 20);
  REQUIRE(cut.trial.warnings.size() == 1);
  CHECK_THAT(cut.trial.warnings[0], Catch::StartsWith("3D data: the file holds"));
}

TEST_CASE("OpenSim tables: header, columns, rows, time span and rate", "[io][info]") {
  TempFile sto(".sto"), mot(".mot"), other(".txt");
  write_text(sto.path(),
             "DataRate=50.000000\nDataType=Quaternion\nversion=3\nOpenSimVersion=4.1\nendheader\n"
             "time\tpelvis_imu\ttorso_imu\n"
             "0\t1,0,0,0\t0.7,0.7,0,0\n0.02\t1,0,0,0\t0.7,0.7,0,0\n0.04\t1,0,0,0\t0.7,0.7,0,0\n");
  const RecordingInfo s = inspect_recording(sto.path());
  REQUIRE(s.table);
  CHECK(s.kind == "table");
  CHECK(s.table->columns == std::vector<std::string>{"time", "pelvis_imu", "torso_imu"});
  CHECK(s.table->rows == 3);
  CHECK(s.table->rate_hz == 50.0);
  CHECK(s.table->rate_source == "from DataRate");
  CHECK(s.table->cell_kind == "quaternions (w,x,y,z)");
  CHECK(s.table->last_time_s == 0.04);
  CHECK(s.table->warnings.empty());

  write_text(mot.path(),
             "Coordinates\nversion=1\nnRows=5\nnColumns=3\ninDegrees=yes\n\nUnits are S.I.\n"
             "endheader\ntime\tknee_angle_r\tankle_angle_r\n"
             "      0.50\t  -5.0\t 1.0\n      0.60\t  -6.0\t 2.0\n      0.70\t  -7.0\n"
             "      0.80\t  -8.0\t 3.0\n");
  const RecordingInfo m = inspect_recording(mot.path());
  REQUIRE(m.table);
  CHECK(m.table->name == "Coordinates");
  CHECK(m.table->rows == 3);  // the short row is left out, and said
  // Its time still counts: 4 rows in 0.3 s are 10 Hz (was 3 rows, 6.7 Hz).
  CHECK(m.table->rate_hz == Approx(10.0));
  CHECK(m.table->rate_source == "from the time column");
  CHECK(m.table->cell_kind == "numbers");
  REQUIRE(m.table->warnings.size() == 2);
  CHECK_THAT(m.table->warnings[0], Catch::StartsWith("1 rows left out (the first on line 12)"));
  CHECK(m.table->warnings[1] == "nRows is 5 but the table has 3");

  // A row out of time order is kept and said apart; the rate spans the earliest to the latest.
  write_text(mot.path(),
             "Coordinates\nversion=1\nnRows=4\nnColumns=2\ninDegrees=yes\nendheader\n"
             "time\tknee_angle_r\n0.1\t1\n0.0\t2\n0.2\t3\n0.3\t4\n");
  const RecordingInfo u = inspect_recording(mot.path());
  REQUIRE(u.table);
  CHECK(u.table->rows == 4);
  CHECK(u.table->rate_hz == Approx(10.0));  // was 3 / 0.2 s = 15 Hz
  REQUIRE(u.table->warnings.size() == 1);
  CHECK(u.table->warnings[0] ==
        "the time column goes back in time at 1 row (the first at line 9: 0 s after 0.1 s at "
        "line 8): rows kept in the file's order");
  // Read to be used (not described), the same file is refused, as OpenSim refuses it.
  CHECK_THAT(error_of([&] { read_opensim_table(mot.path()); }),
             Catch::Contains("the time column goes back in time at 1 row") &&
                 Catch::Contains("Fix: put the rows in time order"));
  // A time equal to the previous row's is kept, said apart.
  write_text(mot.path(),
             "Coordinates\nversion=1\nnRows=3\nnColumns=2\ninDegrees=yes\nendheader\n"
             "time\tknee_angle_r\n0.0\t1\n0.0\t2\n0.1\t3\n");
  const OpenSimTable same = read_opensim_table(mot.path());
  REQUIRE(same.warnings.size() == 1);
  CHECK(same.warnings[0] == "1 rows kept (the first on line 9) whose time is the previous row's");

  write_text(mot.path(), "Coordinates\nversion=1\ntime\tx\n0\t1\n");
  CHECK_THAT(error_of([&] { inspect_recording(mot.path()); }),
             Catch::Contains("no 'endheader' line"));
  write_text(other.path(), "hello\n");
  CHECK_THAT(error_of([&] { inspect_recording(other.path()); }),
             Catch::Contains("unknown file type '.txt': fabrik info reads .trc, .c3d (markers), "
                             ".sto, .mot (OpenSim tables)"));
}

TEST_CASE("inspect_recording on every file of the shared data folder", "[io][info][data]") {
  if (!fs::exists(kDataDir)) {
    WARN("skipped: " << kDataDir << " not found");
    return;
  }
  std::size_t seen = 0;
  for (const auto& entry : fs::directory_iterator(kDataDir)) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".md") continue;
    INFO(entry.path().string());
    const RecordingInfo info = inspect_recording(entry.path().string());
    ++seen;
    const std::string name = entry.path().filename().string();
    if (name == "Vicon.c3d") {
      CHECK(info.markers.size() == 51);
      CHECK(info.trial.source.frames == 580);
      CHECK(info.trial.source.analog_channels == 38);
      CHECK(info.trial.source.analog_rate_hz == 2000.0);
      CHECK(info.trial.warnings.empty());
    } else if (name == "Optotrak.c3d") {
      CHECK(info.trial.source.frames == 29);
      CHECK(info.trial.warnings.size() == 1);
    } else if (name == "subject01_walk1_ik.mot") {
      REQUIRE(info.table);
      CHECK(info.table->rows == 73);
      CHECK(info.table->columns.size() == 24);
      CHECK(info.table->rate_hz == Approx(60.0).epsilon(1e-6));
      CHECK(info.table->warnings.empty());
    } else if (name == "opensense_walking_orientations.sto") {
      REQUIRE(info.table);
      CHECK(info.table->rows == 2432);
      CHECK(info.table->columns.size() == 9);
      CHECK(info.table->rate_hz == 100.0);
      CHECK(info.table->cell_kind == "quaternions (w,x,y,z)");
    } else if (ext == ".trc") {
      CHECK(info.trial.warnings.empty());
      CHECK(info.trial.frames() > 0);
      for (const MarkerSamples& m : info.markers) CHECK(m.missing == 0);
    }
  }
  CHECK(seen >= 8);
}

// ---- What OpenSim refuses: a label on two markers, a Time column that goes back ----

using fabrik::format_number;
using fabrik::test::two_marker_trc;

TEST_CASE("A TRC label on two markers is refused, naming both columns, and info reads it",
          "[io][trc][opensim]") {
  TempFile file(".trc");
  write_text(file.path(), two_marker_trc("R.ASIS", "R.ASIS", {"0", "0.01", "0.02"}));
  const std::string message = error_of([&] { read_trc(file.path()); });
  CHECK_THAT(message, Catch::StartsWith(file.path() + ": line 4: marker 'R.ASIS' labels columns "
                                                      "3 and 6: which of them is the marker is "
                                                      "ambiguous") &&
                          Catch::Contains("Fix: rename one of them in line 4"));
  const MarkerTrial t = read_trc(file.path(), {.refuse_ambiguous = false});
  REQUIRE(t.source.repeated_labels.size() == 1);
  CHECK(t.source.repeated_labels[0].label == "R.ASIS");
  CHECK(t.source.repeated_labels[0].first == 3);
  CHECK(t.source.repeated_labels[0].second == 6);
  REQUIRE(t.warnings.size() == 1);
  CHECK_THAT(t.warnings[0], Catch::Contains("`fabrik solve` refuses the file"));
  const RecordingInfo info = inspect_recording(file.path());  // describes it all the same
  CHECK(info.trial.source.repeated_labels.size() == 1);
  CHECK(info.markers.size() == 2);
}

TEST_CASE("A C3D label on two points is refused, naming both POINT:LABELS entries",
          "[io][c3d][opensim]") {
  MarkerTrial trial;
  trial.labels = {"A", "B", "A"};
  trial.rate_hz = 100.0;
  trial.positions_m.assign(3 * 4, Eigen::Vector3d(0.1, 0.2, 0.3));
  TempFile file(".c3d");
  write_c3d(file.path(), trial, C3dProcessor::intel, true);
  CHECK_THAT(error_of([&] { read_c3d(file.path()); }),
             Catch::StartsWith(file.path() + ": parameter section: POINT:LABELS: marker 'A' "
                                             "labels entries 1 and 3") &&
                 Catch::Contains("Fix: rename one of them in POINT:LABELS"));
  const RecordingInfo info = inspect_recording(file.path());
  REQUIRE(info.trial.source.repeated_labels.size() == 1);
  CHECK(info.trial.source.repeated_labels[0].first == 1);
  CHECK(info.trial.source.repeated_labels[0].second == 3);
}

TEST_CASE("A TRC's first time is put on the frame grid within the rounding it is written with",
          "[io][trc][opensim]") {
  TempFile file(".trc");
  auto first_time_s = [&](const std::string& time, const std::string& rate, int frame) {
    write_text(file.path(), two_marker_trc("A", "B", {time}, rate, frame));
    return read_trc(file.path()).file_time_s(0);
  };
  // Frame 26 of a 60 Hz trial written with 3 decimals: 0.417 is 25.02 frames, off the grid by
  // more than a hundredth of a frame; it was kept, so every row was 0.33 ms late.
  CHECK(first_time_s("0.417", "60", 26) == 25.0 / 60.0);
  CHECK(first_time_s("0.433", "60", 27) == 26.0 / 60.0);    // 25.98 frames
  CHECK(first_time_s("0.104", "240", 26) == 25.0 / 240.0);  // 24.96: 0.12 frame at 240 Hz
  // Written more finely, the same offsets are the file's own clock: kept.
  CHECK(first_time_s("0.4172", "60", 26) == Approx(0.4172).epsilon(1e-12));
  CHECK(first_time_s("0.41700000", "60", 26) == Approx(0.417).epsilon(1e-12));
  CHECK(first_time_s("4.17e-1", "60", 26) == Approx(0.417).epsilon(1e-12));
  // On the grid already, or within a hundredth of a frame, as before.
  CHECK(first_time_s("0.23", "100", 24) == 23.0 / 100.0);
  CHECK(first_time_s("0.41666667", "60", 26) == 25.0 / 60.0);
}

TEST_CASE("A TRC Time column that goes back is refused at its first row, one standing still warns",
          "[io][trc][opensim]") {
  TempFile back(".trc"), still(".trc");
  // Rows start at line 6: frame 3 (0.005 after 0.01) is line 8.
  write_text(back.path(), two_marker_trc("A", "B", {"0", "0.01", "0.005", "0.03", "0.02"}));
  CHECK_THAT(error_of([&] { read_trc(back.path()); }),
             Catch::StartsWith(back.path() + ": the Time column goes back in time at 2 rows (the "
                                             "first at line 8, frame 3: 0.005 s after 0.01 s)") &&
                 Catch::Contains("Fix: put the rows in time order"));
  const MarkerTrial b = read_trc(back.path(), {.refuse_ambiguous = false});
  CHECK(b.source.time_backwards.rows == 2);
  CHECK(b.source.time_backwards.first_frame == 3);
  CHECK(b.source.time_backwards.first_line == 8);
  CHECK(b.source.time_standing.rows == 0);
  CHECK(b.frames() == 5);

  // Times rounded to 2 decimals at a high rate (200 Hz) repeat: read (time comes from the
  // rate), warned.
  write_text(still.path(), two_marker_trc("A", "B", {"0", "0.01", "0.01", "0.02", "0.02"}, "200"));
  const MarkerTrial s = read_trc(still.path());
  CHECK(s.frames() == 5);
  CHECK(s.source.time_standing.rows == 2);
  CHECK(s.source.time_standing.first_frame == 3);
  CHECK(s.source.time_backwards.rows == 0);
  REQUIRE(s.warnings.size() == 1);
  CHECK_THAT(s.warnings[0], Catch::StartsWith("the Time column stands still at 2 rows (the first "
                                              "at line 8, frame 3: 0.01 s as in the row before)"));
  // Increasing times (the writer's own) say nothing.
  TempFile good(".trc");
  write_text(good.path(), two_marker_trc("A", "B", {"0", "0.01", "0.02"}));
  CHECK(read_trc(good.path()).warnings.empty());
}

TEST_CASE(
    "A TRC Time column at another rate than DataRate warns, times rounded to the rate's "
    "grid do not",
    "[io][trc]") {
  const auto warnings_of = [](const std::vector<std::string>& times, const std::string& rate) {
    TempFile f(".trc");
    write_text(f.path(), two_marker_trc("A", "B", times, rate));
    return read_trc(f.path()).warnings;
  };
  // Every other row of a 60 Hz export, DataRate left at 60: the Time column runs at 30 Hz.
  std::vector<std::string> halved;
  for (int i = 0; i < 76; ++i) halved.push_back(format_number("%.5f", i / 30.0));
  const std::vector<std::string> w = warnings_of(halved, "60");
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::StartsWith("the Time column runs at 30 Hz (0 s at line 6 to 2.5 s at "
                                     "line 81), DataRate says 60 Hz") &&
                       Catch::Contains("(1.25 s for those rows, not 2.5)") &&
                       Catch::Contains("Fix: correct DataRate"));
  // Less than half a frame off over the file (beyond the times' rounding): nothing.
  std::vector<std::string> rounded, drifting;
  for (int i = 0; i < 1200; ++i) {
    rounded.push_back(format_number("%.3f", i / 120.0));  // 3 decimals at 120 Hz
    drifting.push_back(format_number("%.6f", i / 120.0 * (1.0 + 0.3 / 1199.0)));  // 0.3 frame
  }
  CHECK(warnings_of(rounded, "120").empty());
  CHECK(warnings_of(drifting, "120").empty());
  // 0.6 of a frame over the file is named.
  for (int i = 0; i < 1200; ++i)
    drifting[i] = format_number("%.6f", i / 120.0 * (1.0 + 0.6 / 1199.0));
  CHECK(warnings_of(drifting, "120").size() == 1);
  // Read at the CameraRate (DataRate 0): both warnings, the second naming the CameraRate.
  TempFile f(".trc");
  std::string text = two_marker_trc("A", "B", halved, "60");
  const std::string rates = "\n60\t60\t";
  REQUIRE(text.find(rates) != std::string::npos);
  text.replace(text.find(rates), rates.size(), "\n0\t60\t");
  write_text(f.path(), text);
  const std::vector<std::string> camera = read_trc(f.path()).warnings;
  REQUIRE(camera.size() == 2);
  CHECK_THAT(camera[0], Catch::Contains("read the CameraRate, 60 Hz"));
  CHECK_THAT(camera[1], Catch::StartsWith("the Time column runs at 30 Hz") &&
                            Catch::Contains("CameraRate says 60 Hz") &&
                            Catch::Contains("Fix: correct CameraRate") &&
                            !Catch::Contains("DataRate"));
}

TEST_CASE(
    "A TRC cut short inside its last row is refused as truncated, a short row that ends "
    "its line is missing markers",
    "[io][trc]") {
  const std::string whole = two_marker_trc("A", "B", {"0", "0.01", "0.02"});  // ends "\n"
  TempFile f(".trc");
  // Cut inside the last row's markers (as `head -c` or an interrupted copy leaves it).
  const std::string cut = whole.substr(0, whole.size() - 5);  // "...\t1\t2\t3\t4"
  write_text(f.path(), cut);
  CHECK_THAT(error_of([&] { read_trc(f.path()); }),
             Catch::StartsWith(f.path() + ": line 8, the last: the file ends inside this row, 2 "
                                          "of its 8 columns missing and no line ending: it is "
                                          "truncated") &&
                 Catch::Contains("Fix: copy or export the trial again"));
  // `fabrik info` describes it all the same (the rows it holds), warned.
  const MarkerTrial described = read_trc(f.path(), {.refuse_ambiguous = false});
  CHECK(described.frames() == 3);
  REQUIRE(described.warnings.size() == 1);
  CHECK_THAT(described.warnings[0], Catch::Contains("it is truncated: `fabrik solve` refuses"));
  // The same short row with its line ending: B's last sample is missing, as documented.
  write_text(f.path(), cut + "\n");
  const MarkerTrial t = read_trc(f.path());
  REQUIRE(t.frames() == 3);
  CHECK_FALSE(t.at(2, 1).allFinite());
  // A whole last row without a line ending is whole.
  write_text(f.path(), whole.substr(0, whole.size() - 1));
  CHECK(read_trc(f.path()).at(2, 1).allFinite());
  // A writer that leaves out trailing empty fields: every row as short, the last without a
  // line ending, is not cut short.
  const std::string header = whole.substr(0, whole.find("\n1\t0\t") + 1);
  write_text(f.path(), header + "1\t0\t1\t2\t3\n2\t0.01\t1\t2\t3\n3\t0.02\t1\t2\t3");
  const MarkerTrial terse = read_trc(f.path());
  CHECK(terse.frames() == 3);
  CHECK_FALSE(terse.at(2, 1).allFinite());
}

TEST_CASE("A failed write keeps only an errno a write gives as its reason", "[output_file]") {
  // A stream sets no errno of its own: by the close, errno may have been set by an unrelated
  // call since the write failed. Only a write's own reasons are named; another is left out
  // rather than blame the wrong thing.
  struct Case {
    int error_number;
    bool named;
  };
  for (const Case c :
       {Case{ENOSPC, true}, Case{EDQUOT, true}, Case{EFBIG, true}, Case{EIO, true},
        Case{EPIPE, true}, Case{ESTALE, true}, Case{ENOENT, false}, Case{EACCES, false},
        Case{EBADF, false}, Case{EAGAIN, false}, Case{EINVAL, false}}) {
    CAPTURE(c.error_number, std::strerror(c.error_number));
    fabrik::test::TempFile file(".txt");
    std::ofstream out = fabrik::io::open_output_file(file.path());
    out << "x";
    out.setstate(std::ios::badbit);  // as a failed write leaves it
    errno = c.error_number;
    try {
      fabrik::io::finish_output_file(out, file.path());
      FAIL("a stream that failed was finished without an error");
    } catch (const fabrik::io::OutputFileError& e) {
      const std::string reason = std::string("(") + std::strerror(c.error_number) + ")";
      CHECK(e.error_number() == (c.named ? c.error_number : 0));
      if (c.named) {
        CHECK(e.problem() == "writing failed " + reason);
      } else {
        CHECK(e.problem() == "writing failed (disk full or file removed?)");
      }
    }
  }
}

TEST_CASE("A recording's typical spread: twice the median distance from the per-axis median",
          "[io][trc]") {
  // Known answer: at (0,0,0), (1,0,0), (0,1,0), (0,0,1) m the per-axis median is the origin,
  // the distances 0, 1, 1, 1, their median 1: a spread of 2 m in every frame.
  MarkerTrial t;
  t.labels = {"A", "B", "C", "D", "E"};
  t.rate_hz = 100.0;
  for (int f = 0; f < 20; ++f) {
    for (const Eigen::Vector3d& p_m : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0),
                                       Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1)})
      t.positions_m.push_back(p_m);
    // A fifth marker missing but in 3 frames, where it glitches 5 km away: the median
    // distance (and so the spread) of those frames is still 1 m (the box's would be 5 km).
    t.positions_m.push_back(f % 7 == 0 ? Eigen::Vector3d(5000, 0, 0)
                                       : Eigen::Vector3d::Constant(NAN));
  }
  TempFile trc(".trc");
  write_trc(trc.path(), t, "m");
  CHECK(read_trc(trc.path()).source.typical_span_m == Approx(2.0).margin(1e-9));
  // Four more markers at exact zeros, kept as positions (keep-zeros): not seen, left out of
  // the spread (with them the median distance was 0, the file refused as metres labelled mm).
  MarkerTrial zeros;
  zeros.labels = {"A", "B", "C", "D", "E", "F", "G"};
  zeros.rate_hz = 100.0;
  for (int f = 0; f < 20; ++f)
    for (const Eigen::Vector3d& p_m :
         {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1),
          Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0, 0),
          Eigen::Vector3d(0, 0, 0)})
      zeros.positions_m.push_back(p_m);
  write_trc(trc.path(), zeros, "m");
  const MarkerTrial kept = read_trc(trc.path(), {.zeros_are_missing = false});
  CHECK(kept.source.typical_span_m == Approx(2.0).margin(1e-9));
  CHECK(kept.source.unit_problem.empty());
}

TEST_CASE(
    "A recording whose markers span less than 20 mm or more than 100 m is told its unit may be "
    "wrong, TRC and C3D, a body in its right unit is not",
    "[io][trc][c3d]") {
  // Three markers of a standing body (pelvis and head), walking 2 m over 10 frames.
  MarkerTrial body;
  body.labels = {"LASI", "RASI", "HEAD"};
  body.rate_hz = 100.0;
  for (int f = 0; f < 10; ++f)
    for (const Eigen::Vector3d& p_mm :
         {Eigen::Vector3d(100, 900, 50), Eigen::Vector3d(-100, 900, 50),
          Eigen::Vector3d(0, 1700, 0)})
      body.positions_m.push_back((p_mm + Eigen::Vector3d(0, 0, 200.0 * f)) / 1000.0);
  const auto scaled = [&](double factor) {
    MarkerTrial t = body;
    for (Eigen::Vector3d& p : t.positions_m) p *= factor;
    return t;
  };
  const auto unit_warnings = [](const MarkerTrial& t) {
    std::vector<std::string> found;
    for (const std::string& w : t.warnings)
      if (w.find("is the unit right?") != std::string::npos) found.push_back(w);
    return found;
  };
  TempFile trc(".trc"), c3d(".c3d");
  // Right: nothing, whatever the unit written.
  for (const std::string units : {"mm", "m"}) {
    write_trc(trc.path(), body, units);
    CHECK(unit_warnings(read_trc(trc.path())).empty());
    write_c3d(trc.path() + ".c3d", body, C3dProcessor::intel, true, units);
    CHECK(unit_warnings(read_c3d(trc.path() + ".c3d")).empty());
    fs::remove(trc.path() + ".c3d");
  }
  // Metres written under "mm": the body reads 1000 times too small.
  write_trc(trc.path(), scaled(1e-3), "mm");
  std::vector<std::string> w = unit_warnings(read_trc(trc.path()));
  REQUIRE(w.size() == 1);
  // Spread: twice the median distance from the per-axis median (0, 0.9, 0.05) mm, of 0.1, 0.1
  // and 0.8016 mm: 0.2 mm, below the 10 mm the commands refuse; the warning is the refusal.
  MarkerTrial got = read_trc(trc.path());
  CHECK_THAT(w[0], Catch::StartsWith("the markers spread over 0.2 mm in a typical frame (less "
                                     "than 10 mm") &&
                       Catch::Contains("Fix: correct Units (line 3) (metres labelled mm"));
  CHECK(got.source.unit_problem == w[0]);
  write_c3d(c3d.path(), scaled(1e-3), C3dProcessor::intel, true, "mm");
  w = unit_warnings(read_c3d(c3d.path()));
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::Contains("Fix: correct POINT:UNITS"));
  // Millimetres written under "m": 1000 times too large.
  write_trc(trc.path(), scaled(1e3), "m");
  got = read_trc(trc.path());
  w = unit_warnings(got);
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::Contains("more than 100 m") && Catch::Contains("mm labelled m"));
  CHECK(got.source.unit_problem == w[0]);
  // A body with one marker glitching 150 km away: its bounding box warns, its spread (a body's)
  // is not refused.
  MarkerTrial glitch = body;
  glitch.labels.push_back("GLITCH");
  glitch.positions_m.clear();
  for (std::size_t f = 0; f < body.frames(); ++f) {
    for (std::size_t m = 0; m < body.markers(); ++m) glitch.positions_m.push_back(body.at(f, m));
    glitch.positions_m.push_back(Eigen::Vector3d(150e3, 0, 0));
  }
  write_trc(trc.path(), glitch, "mm");
  got = read_trc(trc.path());
  w = unit_warnings(got);
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Catch::StartsWith("the markers span "));
  CHECK(got.source.unit_problem.empty());
  // Four markers within a millimetre and a fifth a metre off: the box is a body's, the spread
  // (0.5 mm) is not: refused, though nothing spans under 20 mm.
  MarkerTrial clump;
  clump.labels = {"A", "B", "C", "D", "E"};
  clump.rate_hz = 100.0;
  for (int f = 0; f < 10; ++f)
    for (const Eigen::Vector3d& p_mm :
         {Eigen::Vector3d(0, 1000, 0), Eigen::Vector3d(0.25, 1000, 0),
          Eigen::Vector3d(-0.25, 1000, 0), Eigen::Vector3d(0, 1000.25, 0),
          Eigen::Vector3d(1000, 1000, 0)})
      clump.positions_m.push_back(p_mm / 1000.0);
  write_trc(trc.path(), clump, "mm");
  got = read_trc(trc.path());
  CHECK(got.source.typical_span_m == Approx(0.0005).margin(1e-9));
  CHECK_THAT(got.source.unit_problem, Catch::StartsWith("the markers spread over 0.5 mm"));
}
