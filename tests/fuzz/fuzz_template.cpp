// The calibration template loader on any file content (load_template_file,
// as fabrik calibrate reads it): a template or a ConfigError naming the
// file; any other exception escapes and aborts.
#include <cstdint>

#include "calib/calib_template.hpp"
#include "config/config_error.hpp"
#include "fuzz_check.hpp"
#include "fuzz_input_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fabrik::fuzz::InputFile file;
  const std::string& path = file.write(data, size);
  try {
    const fabrik::calib::CalibTemplate t = fabrik::calib::load_template_file(path);
    fabrik::fuzz::require(!t.segments.empty(), "a template without segments");
  } catch (const fabrik::ConfigError& e) {
    fabrik::fuzz::require_names_file(e.what(), path);
  }
  return 0;
}
