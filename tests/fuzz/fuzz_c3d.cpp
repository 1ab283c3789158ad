// The C3D reader on any file content, strict and with truncated data allowed:
// a trial that keeps its promises, or a FormatError naming the file; any
// other exception escapes and aborts.
#include <cstdint>

#include "fuzz_check.hpp"
#include "fuzz_input_file.hpp"
#include "io/marker_trial.hpp"
#include "trial_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fabrik::fuzz::InputFile file;
  const std::string& path = file.write(data, size);
  for (const bool allow_truncated : {false, true}) {
    try {
      fabrik::fuzz::require_valid_trial(fabrik::io::read_c3d(path, {allow_truncated}));
    } catch (const fabrik::io::FormatError& e) {
      fabrik::fuzz::require_names_file(e.what(), path);
    }
  }
  return 0;
}
