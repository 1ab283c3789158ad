#include "io/output_file.hpp"

#include "io/marker_trial.hpp"

namespace fabrik::io {

std::ofstream open_output_file(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw FormatError(path, "cannot open the file for writing");
  return out;
}

void finish_output_file(std::ofstream& out, const std::string& path) {
  out.close();
  if (!out) throw FormatError(path, "writing failed (disk full or file removed?)");
}

}  // namespace fabrik::io
