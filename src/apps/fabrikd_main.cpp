// fabrikd: the real-time marker-tracking daemon. Setup errors (bad config,
// busy port) exit with code 2 and a message that names the fix; once running,
// no message can stop it: only SIGINT/SIGTERM (a stop within 100 ms at any
// moment: during startup, while running and during a reload) and SIGHUP (reload the config off the frame loop,
// keeping the old one if the new one is invalid).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <sys/eventfd.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <tuple>

#include "cli_exit.hpp"
#include "common/safe_text.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/endpoint_check.hpp"
#include "transport/daemon.hpp"
#include "version.hpp"

namespace {

// Static storage, not a pointer to a stack object: the handler may run at
// any time (before the daemon exists, after run() has thrown), and storing
// to a lock-free atomic is async-signal-safe.
fabrik::wire::DaemonControl g_control;
// Until the loop runs there is nothing to stop cleanly (reading a large
// config or setting up a model may take a while): a stop ends the process
// at once, from the handler.
std::atomic<bool> g_running{false};

extern "C" void on_signal(int sig) {
  const int saved_errno = errno;  // the interrupted code may be about to read it
  if (sig == SIGHUP) {
    g_control.reload.store(true);
  } else {
    g_control.stop.store(true);
    if (!g_running.load()) {
      constexpr char kText[] = "fabrikd: stopped during startup\n";
      (void)!write(STDERR_FILENO, kText, sizeof kText - 1);
      _exit(0);
    }
  }
  if (g_control.wake_fd >= 0) {
    const std::uint64_t one = 1;
    (void)!write(g_control.wake_fd, &one, sizeof one);
  }
  errno = saved_errno;
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &sa, nullptr);
}

// Every client connection costs a file descriptor, and when none is left
// ZeroMQ's listener retries accept() in a busy loop. A soft limit of 1024 (a
// common default) is raised to the hard limit, so thousands of connections
// are only memory; connections that never complete ZeroMQ's handshake are
// closed after kHandshakeTimeoutMs.
void raise_open_file_limit() {
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur == limit.rlim_max) return;
  const rlim_t before = limit.rlim_cur;
  limit.rlim_cur = limit.rlim_max == RLIM_INFINITY ? rlim_t{1} << 20 : limit.rlim_max;
  if (setrlimit(RLIMIT_NOFILE, &limit) != 0) {
    spdlog::warn("open files limit stays at {} (cannot raise it to {})", before, limit.rlim_cur);
    return;
  }
  spdlog::debug("open files limit raised from {} to {}", before, limit.rlim_cur);
}

struct Overrides {
  std::string config_path, input, output, log_level;
};

fabrik::DaemonConfig load(const Overrides& o) {
  fabrik::DaemonConfig c = o.config_path.empty() ? fabrik::default_daemon_config()
                                                 : fabrik::load_daemon_config_file(o.config_path);
  if (!o.input.empty()) {
    c.input = fabrik::endpoint_option(o.input, c.input.mode, "--input");
    c.input.option = "--input";
  }
  if (!o.output.empty()) {
    c.output = fabrik::endpoint_option(o.output, c.output.mode, "--output");
    c.output.option = "--output";
  }
  // As the config's own check (daemon_config.cpp), after the options: bound twice, the
  // output's bind failed with "Address already in use"; bound and connected, it was taken.
  if ((!o.input.empty() || !o.output.empty()) && fabrik::endpoints_clash(c.input, c.output)) {
    const fabrik::Endpoint& named = o.output.empty() ? c.input : c.output;
    const fabrik::Endpoint& other = o.output.empty() ? c.output : c.input;
    throw std::invalid_argument(std::string(o.output.empty() ? "--input" : "--output") + ": '" +
                                named.address + "' is also the " +
                                (o.output.empty() ? "output's" : "input's") + " endpoint" +
                                fabrik::clash_spelling(named, other) +
                                ". Fix: give the input and the pose output an endpoint each");
  }
  if (!o.log_level.empty()) c.log_level = o.log_level;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fabrikd: real-time marker tracking with prioritized FABRIK, over ZeroMQ"};
  app.set_version_flag("--version", std::string(fabrik::kVersion));
  Overrides o;
  // An empty value (--config "", an unset shell variable) is refused below:
  // it must not quietly mean "the default".
  const CLI::Option* config_opt = app.add_option(
      "--config", o.config_path, "Daemon config JSON (default: the embedded config/default.json)");
  const CLI::Option* input_opt =
      app.add_option("--input", o.input,
                     "Marker input endpoint, e.g. tcp://127.0.0.1:5555; prefix bind: or connect: "
                     "to set the mode");
  const CLI::Option* output_opt = app.add_option(
      "--output", o.output, "Pose output endpoint, e.g. tcp://127.0.0.1:5556 (same prefixes)");
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return fabrik::apps::exit_safely(app, e, "fabrikd");
  }
  const std::tuple<const CLI::Option*, const std::string*, const char*> empty_checks[] = {
      {config_opt, &o.config_path,
       "give the path of a daemon config file, or leave out --config for the embedded default"},
      {input_opt, &o.input,
       "give an endpoint, e.g. tcp://127.0.0.1:5555, or leave out --input for the config's"},
      {output_opt, &o.output,
       "give an endpoint, e.g. tcp://127.0.0.1:5556, or leave out --output for the config's"}};
  for (const auto& [opt, value, fix] : empty_checks) {
    if (opt->count() > 0 && value->empty()) {
      std::fprintf(stderr, "fabrikd: %s is empty. Fix: %s\n", opt->get_name().c_str(), fix);
      return 2;
    }
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("fabrikd"));  // stdout stays clean
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  g_control.wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  const int eventfd_errno = errno;
  install_signal_handlers();
  bool abandoned = false;
  try {
    fabrik::DaemonConfig config = load(o);
    spdlog::set_level(spdlog::level::from_str(config.log_level));
    if (g_control.wake_fd < 0)
      spdlog::warn("no eventfd ({}): a stop is seen within the loop's 100 ms poll instead of at once",
                   std::strerror(eventfd_errno));
    spdlog::info("fabrikd {}: config {}", fabrik::kVersion, fabrik::wire::safe_text(config.file));
    raise_open_file_limit();
    zmq::context_t context(1);
    fabrik::wire::Daemon daemon(context, std::move(config));
    g_running.store(true);
    if (g_control.stop.load()) return 0;  // stopped just before the line above
    daemon.run(g_control, [o] { return load(o); });
    abandoned = daemon.reload_abandoned();
  } catch (const fabrik::ConfigError& e) {
    std::fprintf(stderr, "fabrikd: config error: %s\n", e.what());  // already safe text
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fabrikd: %s\n", fabrik::safe_lines(e.what()).c_str());
    return 2;
  }
  if (abandoned) {
    // A reload thread is still reading: do not unwind under it.
    spdlog::default_logger()->flush();
    std::_Exit(0);
  }
  return 0;
}
