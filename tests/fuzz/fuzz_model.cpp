// The model loader on any file content (through load_model_file, as fabrikd
// and fabrik read models): a model or a ConfigError naming the file; any
// other exception escapes and aborts.
#include <cstdint>

#include "config/config_error.hpp"
#include "config/model_loader.hpp"
#include "fuzz_check.hpp"
#include "fuzz_input_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fabrik::fuzz::InputFile file;
  const std::string& path = file.write(data, size);
  try {
    const fabrik::Model model = fabrik::load_model_file(path);
    fabrik::fuzz::require(!model.segments.empty(), "a model without segments");
  } catch (const fabrik::ConfigError& e) {
    fabrik::fuzz::require_names_file(e.what(), path);
  }
  return 0;
}
