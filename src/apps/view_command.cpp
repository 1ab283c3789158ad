#include "view_command.hpp"

#include <unistd.h>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <thread>
#include <zmq.hpp>

#include "common/safe_text.hpp"
#include "config/endpoint_check.hpp"
#include "offline/marker_match.hpp"
#include "read_recording.hpp"
#include "tools/cli_checks.hpp"
#include "tools/run_command.hpp"
#include "tools/tools.hpp"
#include "view/view_server.hpp"
#include "view/view_trial.hpp"

namespace fabrik::apps {

namespace {

struct ViewArgs {
  std::string pose = "tcp://127.0.0.1:5556", listen = "127.0.0.1:8080", web_root, trial, config,
              subject;
  double rate_hz = 60.0;
  int max_clients = 16;
};

// An installed fabrik's page (DATADIR/fabrik/view, found from its own folder:
// cmake/view_page_path.cmake), else the source tree's.
std::string default_web_root() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed = exe.parent_path() / FABRIK_VIEW_WEB_ROOT_FROM_BIN;
    if (std::filesystem::is_regular_file(installed / "index.html", ec))
      return installed.lexically_normal().string();
  }
  return FABRIK_VIEW_WEB_ROOT;
}

void run(const ViewArgs& a) {
  view::ViewOptions o;
  // bind: and connect: as every endpoint option takes them (a bare one connects).
  const Endpoint pose = endpoint_option(a.pose, SocketMode::connect, "--pose");
  o.pose_endpoint = pose.address;
  o.pose_bind = pose.mode == SocketMode::bind;
  std::tie(o.listen_host, o.listen_port) = view::parse_listen(a.listen);
  // A ZeroMQ subscriber connected to the view's own web server handshakes with HTTP and never
  // gets a pose: the page would stay empty without a word.
  const bool ipv6_host = o.listen_host.find(':') != std::string::npos;
  const Endpoint web{"tcp://" + (ipv6_host ? "[" + o.listen_host + "]" : o.listen_host) + ":" +
                         std::to_string(o.listen_port),
                     SocketMode::bind};
  if (o.listen_port != 0 && endpoints_clash(pose, web))
    throw std::invalid_argument("--pose '" + a.pose + "' is the view's own --listen address '" +
                                a.listen +
                                "'. Fix: give fabrikd's pose output (its "
                                "output.endpoint, e.g. tcp://127.0.0.1:5556), or another --listen");
  o.subject = a.subject;
  o.on_notice = [](const std::string& text) {
    std::fprintf(stderr, "fabrik view: %s\n", safe_lines(text).c_str());
  };
  o.rate_hz = a.rate_hz;
  o.max_clients = a.max_clients;
  o.max_connections = a.max_clients + 48;  // room for page loads beside the WebSockets
  o.web_root = a.web_root.empty() ? default_web_root() : a.web_root;
  if (!std::filesystem::is_regular_file(std::filesystem::path(o.web_root) / "index.html"))
    std::fprintf(stderr, "fabrik view: warning: %s has no index.html: / answers 404\n",
                 safe_lines(o.web_root).c_str());
  if (!a.trial.empty() && !a.subject.empty())
    throw std::invalid_argument("--subject goes with a live view, not --trial");
  if (a.trial.empty() && !a.config.empty())
    throw std::invalid_argument("--config goes with --trial (a live view takes fabrikd's model)");
  if (!a.trial.empty()) {
    const DaemonConfig config =
        a.config.empty() ? default_daemon_config() : load_daemon_config_file(a.config);
    const io::MarkerTrial trial = read_trial_or_explain("view", a.trial, false);
    require_shared_markers(config, trial, a.trial);
    std::fprintf(stderr, "fabrik view: tracking %s (%zu frames) with %s\n",
                 safe_lines(a.trial).c_str(), trial.frames(), safe_lines(config.file).c_str());
    const std::string file_name = std::filesystem::path(a.trial).filename().string();
    view::TrialView t = view::trial_view(config, trial, safe_lines(file_name));
    o.trial_message = std::make_shared<const std::string>(std::move(t.message));
    o.trial_note = "trial " + safe_lines(file_name) + ": " + std::to_string(t.poses) + " poses";
  }
  zmq::context_t context(1);
  view::ViewServer server(context, o);
  tools::catch_stop_signals();
  server.start();
  // ZeroMQ names a wildcard bind 0.0.0.0, an address no sender can connect to.
  const std::string bound = !o.pose_bind ? ""
                            : binds_any_address(server.pose_endpoint())
                                ? ", bound on every address of this host: "
                                  "a sender connects to one of them"
                                : ", bound";
  // 0.0.0.0 cannot be opened: the machine's name (a browser elsewhere uses it; here too).
  char name[256] = {};
  const std::string this_host = gethostname(name, sizeof name - 1) == 0 ? safe_text(name) : "";
  const bool every_address = view::is_wildcard_host(o.listen_host);
  std::printf("fabrik view: %s (%s; page from %s%s)\n",
              view::url_to_open(o.listen_host, server.port(), this_host).c_str(),
              o.trial_message ? o.trial_note.c_str()
                              : ("poses from " + server.pose_endpoint() + bound).c_str(),
              safe_lines(o.web_root).c_str(),
              every_address ? ("; listening on every address of this host, on this machine also "
                               "http://127.0.0.1:" +
                               std::to_string(server.port()) + "/")
                                  .c_str()
                            : "");
  std::fflush(stdout);
  if (!server.loopback_only())
    std::fprintf(stderr, "fabrik view: warning: listening on %s: other machines can connect\n",
                 safe_lines(o.listen_host).c_str());
  std::fflush(stdout);
  while (!tools::stop_signalled()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  server.stop();
  std::fprintf(stderr, "fabrik view: stopped by signal\n");
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto a = std::make_shared<ViewArgs>();
  CLI::App* c = app.add_subcommand(
      "view", "A live 3D view of fabrikd's poses in the browser (or of a trial, --trial)");
  c->add_option("--pose", a->pose,
                "fabrikd's pose/stats/model output, connected (bind:EP binds it instead)")
      ->capture_default_str();
  c->add_option("--subject", a->subject,
                "A multi-subject fabrikd's subject: its poses on topic pose/NAME, its model on "
                "model/NAME (default: plain pose and model)");
  c->add_option("--listen", a->listen, "HTTP and WebSocket address, HOST:PORT (port 0: any)")
      ->capture_default_str();
  c->add_option("--rate-hz", a->rate_hz, "Poses per second per browser, at most (newest wins)")
      ->capture_default_str()
      ->check(cli::range(0.1, 1000.0));
  c->add_option("--max-clients", a->max_clients,
                "WebSocket clients at once; more are told so and closed")
      ->capture_default_str()
      ->check(cli::range(1, 1024));
  c->add_option(
       "--web-root", a->web_root,
       "The page's files (default: an install's share/fabrik/view, else the source tree's)")
      ->check(CLI::ExistingDirectory);
  c->add_option("--trial", a->trial,
                "Serve a recording (.trc, .c3d) tracked offline instead of a live stream")
      ->check(CLI::ExistingFile);
  c->add_option("--config", a->config, "Daemon config for --trial (default: the embedded one)");
  c->callback([a] { tools::run_command("view", [&] { run(*a); }); });
}

}  // namespace fabrik::apps
