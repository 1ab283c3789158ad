// fabrikd: the real-time marker-tracking daemon. Setup errors (bad config,
// busy port) exit with code 2 and a message that names the fix; once running,
// no message can stop it: only SIGINT/SIGTERM (clean stop) and SIGHUP
// (reload the config, keeping the old one if the new one is invalid).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>

#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "transport/daemon.hpp"
#include "version.hpp"

namespace {

fabrik::wire::DaemonControl* g_control = nullptr;

extern "C" void on_signal(int sig) {
  // Only lock-free atomic stores: async-signal-safe.
  if (!g_control) return;
  if (sig == SIGHUP)
    g_control->reload.store(true);
  else
    g_control->stop.store(true);
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &sa, nullptr);
}

struct Overrides {
  std::string config_path, input, output, log_level;
};

fabrik::Endpoint endpoint_override(const std::string& spec, fabrik::Endpoint e) {
  // "bind:tcp://..." or "connect:tcp://..." choose the mode; a bare endpoint keeps it.
  for (auto [prefix, mode] : {std::pair{"bind:", fabrik::SocketMode::bind},
                              std::pair{"connect:", fabrik::SocketMode::connect}}) {
    if (spec.rfind(prefix, 0) == 0) return {spec.substr(std::strlen(prefix)), mode};
  }
  return {spec, e.mode};
}

fabrik::DaemonConfig load(const Overrides& o) {
  fabrik::DaemonConfig c = o.config_path.empty() ? fabrik::default_daemon_config()
                                                 : fabrik::load_daemon_config_file(o.config_path);
  if (!o.input.empty()) c.input = endpoint_override(o.input, c.input);
  if (!o.output.empty()) c.output = endpoint_override(o.output, c.output);
  if (!o.log_level.empty()) c.log_level = o.log_level;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fabrikd: real-time marker tracking with prioritized FABRIK, over ZeroMQ"};
  app.set_version_flag("--version", std::string(fabrik::kVersion));
  Overrides o;
  app.add_option("--config", o.config_path,
                 "Daemon config JSON (default: the embedded config/default.json)");
  app.add_option("--input", o.input,
                 "Marker input endpoint, e.g. tcp://127.0.0.1:5555; prefix bind: or connect: to "
                 "set the mode");
  app.add_option("--output", o.output,
                 "Pose output endpoint, e.g. tcp://127.0.0.1:5556 (same prefixes)");
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("fabrikd"));  // stdout stays clean
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  try {
    fabrik::DaemonConfig config = load(o);
    spdlog::set_level(spdlog::level::from_str(config.log_level));
    spdlog::info("fabrikd {}: config {}", fabrik::kVersion, config.file);
    zmq::context_t context(1);
    fabrik::wire::DaemonControl control;
    fabrik::wire::Daemon daemon(context, std::move(config));
    g_control = &control;
    install_signal_handlers();
    daemon.run(control, [&] {
      fabrik::DaemonConfig c = load(o);
      spdlog::set_level(spdlog::level::from_str(c.log_level));
      return c;
    });
    g_control = nullptr;
  } catch (const fabrik::ConfigError& e) {
    std::fprintf(stderr, "fabrikd: config error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fabrikd: %s\n", e.what());
    return 2;
  }
  return 0;
}
