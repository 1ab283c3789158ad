#include "load.hpp"

#include "daemon_config.hpp"

namespace fabrik {

TrackerSetup load_tracker_setup_file(const std::string& path) {
  return load_daemon_config_file(path).tracker;
}

TrackerSetup load_tracker_setup(const std::string& json_text, const std::string& file) {
  return load_daemon_config(json_text, file).tracker;
}

TrackerSetup default_tracker_setup() { return default_daemon_config().tracker; }

}  // namespace fabrik
