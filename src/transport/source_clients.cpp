// make_source_client: the config's source as a vendor client (src/bridges).
#include "source_input.hpp"

namespace fabrik::wire {

SourceClient make_source_client(const SourceConfig& source) {
  (void)source;
  return [](bridges::FrameSink&, bridges::SourceStatus& status, std::stop_token) {
    status.error("vendor clients are not built yet");
  };
}

}  // namespace fabrik::wire
