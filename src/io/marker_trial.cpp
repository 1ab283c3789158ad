#include "io/marker_trial.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "io/io_detail.hpp"

namespace fabrik::io {

int MarkerTrial::find(const std::string& label) const {
  const auto it = std::find(labels.begin(), labels.end(), label);
  return it == labels.end() ? -1 : static_cast<int>(it - labels.begin());
}

MarkerTrial read_trial(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".trc") return read_trc(path);
  if (ext == ".c3d") return read_c3d(path);
  throw FormatError(path, "unknown file type '" + ext + "' (expected .trc or .c3d)");
}

namespace detail {

std::ifstream open_input(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw FormatError(path, "file not found");
  if (!std::filesystem::is_regular_file(status)) throw FormatError(path, "not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path, "cannot open the file for reading");
  return in;
}

std::ofstream open_output(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw FormatError(path, "cannot open the file for writing");
  return out;
}

void check_written(std::ofstream& out, const std::string& path) {
  if (!out) throw FormatError(path, "writing failed (disk full or file removed?)");
}

double check_trial_for_writing(const MarkerTrial& trial, const std::string& units,
                               const char* writer) {
  const std::string what = std::string(writer) + ": ";
  if (!(trial.rate_hz > 0.0) || !std::isfinite(trial.rate_hz)) {
    throw std::invalid_argument(what + "rate_hz must be positive and finite");
  }
  if (trial.labels.empty() ? !trial.positions_m.empty()
                           : trial.positions_m.size() % trial.labels.size() != 0) {
    throw std::invalid_argument(what + "positions_m.size() (" +
                                std::to_string(trial.positions_m.size()) +
                                ") is not a multiple of the number of labels (" +
                                std::to_string(trial.labels.size()) + ")");
  }
  if (units == "mm") return 1000.0;
  if (units == "m") return 1.0;
  throw std::invalid_argument(what + "units must be \"mm\" or \"m\", not \"" + units + "\"");
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\0'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

}  // namespace detail
}  // namespace fabrik::io
