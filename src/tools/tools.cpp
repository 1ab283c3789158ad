#include "tools.hpp"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>

#include "bridges/ipv4_multicast.hpp"
#include "bridges/natnet_sim_server.hpp"
#include "bridges/qtm/sim_server.hpp"
#include "cli_checks.hpp"
#include "common/safe_text.hpp"
#include "distinct_files.hpp"
#include "replay.hpp"
#include "run_command.hpp"
#include "sim.hpp"
#include "synth.hpp"
#include "watch.hpp"

namespace fabrik::tools {

namespace {

// A simulator bound to every interface is reached at one of this machine's addresses: the
// hint names HOST there, not 0.0.0.0 (which a client cannot connect to).
bool wildcard(const std::string& bind) {
  return bind == "0.0.0.0" || bind == "*" || bind == "::" || bind == "[::]";
}
std::string url_host(const std::string& bind) {
  if (wildcard(bind)) return "HOST";
  return bind.find(':') != std::string::npos && !bind.starts_with("[")
             ? "[" + safe_lines(bind) + "]"
             : safe_lines(bind);
}

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) {
  g_stop.store(true);
}

}  // namespace

// Ctrl-C (or SIGTERM) ends a replay or a watch cleanly, with its summary.
void catch_stop_signals() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

bool stop_signalled() { return g_stop.load(); }

void add_replay_command(CLI::App& app) {
  struct Args {
    std::string file, to, encoding = "json", orientations;
    bool bind = false, loop = false, keep_zeros = false;
    double speed = 1.0, wait_subscriber_s = -1.0;
    std::vector<std::string> drops;
    std::uint64_t frames = 0;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "replay",
      "Stream a TRC/C3D recording to fabrikd's marker input (topic `markers`, mm, null for "
      "missing markers) at its own rate. PUB/SUB drops frames sent before the subscription "
      "arrives: start fabrikd first, or use --wait-subscriber.");
  cmd->add_option("file", a->file, "Recording (.trc or .c3d); optional with --orientations")
      ->check(CLI::ExistingFile);
  cmd->add_option("--orientations", a->orientations,
                  "OpenSim quaternion table (.sto) sent as the frames' `orientations`, joined "
                  "on time with the recording's frames (without a recording, its rows are the "
                  "frames)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--to", a->to, "ZeroMQ endpoint, e.g. tcp://127.0.0.1:5555")->required();
  cmd->add_flag("--bind", a->bind, "Bind the endpoint instead of connecting to it");
  cmd->add_option("--speed", a->speed, "Playback speed factor (0: as fast as possible)")
      ->check(cli::range(0.0, 1000.0));
  cmd->add_flag("--loop", a->loop, "Start over at the end (frame numbers keep increasing)");
  cmd->add_option("--drop", a->drops,
                  "NAME:T0:T1 sends marker NAME as null from T0 to T1 s (repeatable)");
  cmd->add_option("--encoding", a->encoding, "Payload encoding")
      ->check(CLI::IsMember({"json", "msgpack"}));
  cmd->add_option("--frames", a->frames, "Stop after N frames (0: all)")
      ->check(cli::range(0LL, 1'000'000'000'000LL));  // signed: "-1" must not wrap to 2^64 - 1
  cmd->add_option("--wait-subscriber", a->wait_subscriber_s,
                  "Wait up to S seconds for a `markers` subscriber before sending")
      ->check(cli::range(0.0, 86400.0));
  cmd->add_flag("--keep-zeros", a->keep_zeros,
                "Send exact (0, 0, 0) samples as positions (default: as null, missing)");
  cmd->callback([a] {
    run_command("replay", [&] {
      const Endpoint to = tool_endpoint(a->to, a->bind, "--to");  // before reading the file
      ReplayOptions o;
      for (const std::string& d : a->drops) o.drops.push_back(parse_drop_spec(d));
      if (a->file.empty() && a->orientations.empty())
        throw std::invalid_argument(
            "give a recording (.trc/.c3d), an orientation table (--orientations FILE.sto), or "
            "both");
      io::MarkerTrial trial;
      if (!a->file.empty()) {
        trial = io::read_trial(a->file, {.zeros_are_missing = !a->keep_zeros});
        for (const std::string& w : trial.warnings)
          std::fprintf(stderr, "fabrik replay: warning: %s: %s\n", safe_lines(a->file).c_str(),
                       safe_lines(w).c_str());
        io::require_marker_data(trial, a->file);
      }
      io::OrientationTable table;
      if (!a->orientations.empty()) {
        table = io::read_orientation_table(a->orientations);
        for (const std::string& w : table.warnings)
          std::fprintf(stderr, "fabrik replay: warning: %s: %s\n",
                       safe_lines(a->orientations).c_str(), safe_lines(w).c_str());
        if (!a->file.empty()) {
          std::vector<std::string> overlap;
          io::check_time_overlap(trial, a->file, table, a->orientations, overlap);
          for (const std::string& w : overlap)
            std::fprintf(stderr, "fabrik replay: warning: %s: %s\n",
                         safe_lines(a->orientations).c_str(), safe_lines(w).c_str());
        }
        o.orientations = &table;
        std::fprintf(stderr, "replay: %s: %zu rows x %zu sensors at %g Hz%s\n",
                     safe_lines(a->orientations).c_str(), table.rows(), table.sensors.size(),
                     table.rate_hz, a->file.empty() ? " (the frames)" : ", joined on time");
      }
      o.endpoint = to.address;  // without a bind:/connect: prefix, in messages too
      o.bind = to.mode == SocketMode::bind;
      o.speed = a->speed;
      o.loop = a->loop;
      o.encoding = parse_wire_encoding(a->encoding);
      o.max_frames = a->frames;
      o.wait_subscriber_s = a->wait_subscriber_s;
      catch_stop_signals();
      o.stop_requested = [] { return g_stop.load(); };
      o.progress = [](const ReplayProgress& p) {
        if (p.frames_total)
          std::fprintf(stderr, "\rreplay: %llu/%llu frames, %.1f s, %.1f ms behind   ",
                       static_cast<unsigned long long>(p.frames_sent),
                       static_cast<unsigned long long>(p.frames_total), p.elapsed_s, p.behind_ms);
        else
          std::fprintf(stderr, "\rreplay: %llu frames, %.1f s, %.1f ms behind   ",
                       static_cast<unsigned long long>(p.frames_sent), p.elapsed_s, p.behind_ms);
      };
      // Said once the socket is open: a --bind that fails prints only why.
      o.opened = [&] {
        if (!a->file.empty())
          std::fprintf(stderr, "replay: %s: %zu frames x %zu markers at %g Hz -> %s (%s%s)\n",
                       safe_lines(a->file).c_str(), trial.frames(), trial.markers(), trial.rate_hz,
                       safe_lines(to.address).c_str(), a->encoding.c_str(),
                       to.mode == SocketMode::bind ? ", bound" : "");
      };
      zmq::context_t context;
      const ReplaySummary s = replay_trial(context, trial, o);
      std::size_t zeros = 0;
      for (const std::size_t z : trial.source.zero_samples) zeros += z;
      const std::string zero_note =
          zeros > 0 ? std::string(a->keep_zeros ? "; the recording's " : ", the recording's ") +
                          std::to_string(zeros) + " exact (0, 0, 0) samples " +
                          (a->keep_zeros ? "sent as positions" : "among them")
                    : "";
      std::fprintf(stderr,
                   "\nreplay: sent %llu frames (%llu complete passes) in %.2f s, %llu null "
                   "markers (%llu missing in the recording%s; %llu dropped by --drop), %llu "
                   "frames late by > 1 ms (worst %.2f ms), %llu null orientations%s\n",
                   static_cast<unsigned long long>(s.frames_sent),
                   static_cast<unsigned long long>(s.loops), s.elapsed_s,
                   static_cast<unsigned long long>(s.markers_nulled),
                   static_cast<unsigned long long>(s.markers_missing), zero_note.c_str(),
                   static_cast<unsigned long long>(s.markers_dropped),
                   static_cast<unsigned long long>(s.late_frames), s.max_behind_ms,
                   static_cast<unsigned long long>(s.orientations_nulled), s.stopped ? ", stopped by signal" : "");
    });
  });
}

void add_watch_command(CLI::App& app) {
  struct Args {
    std::string from, topic = "pose";
    bool bind = false, json = false;
    double seconds = 0.0;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "watch",
      "Subscribe to fabrikd's pose and stats, print a live line per stats interval and a summary "
      "(loss from gaps in frame numbers, residuals, solve times)");
  cmd->add_option("--from", a->from, "ZeroMQ endpoint, e.g. tcp://127.0.0.1:5556")->required();
  cmd->add_flag("--bind", a->bind, "Bind the endpoint instead of connecting to it");
  cmd->add_option("--seconds", a->seconds, "Stop after S seconds (0: at Ctrl-C)")
      ->check(cli::range(0.0, 1e9));
  cmd->add_option("--topic", a->topic,
                  "The poses' topic: pose, a subject's pose/NAME or a pose view's (output.views)")
      ->capture_default_str()
      ->check([](const std::string& t) { return t.empty() ? std::string("is empty") : std::string(); });
  cmd->add_flag("--json", a->json,
                "Print the final summary as one JSON object on stdout (live lines go to stderr)");
  cmd->callback([a] {
    run_command("watch", [&] {
      const Endpoint from = tool_endpoint(a->from, a->bind, "--from");  // before any output
      WatchOptions o;
      o.endpoint = from.address;
      o.bind = from.mode == SocketMode::bind;
      o.seconds = a->seconds;
      o.topic = a->topic;
      catch_stop_signals();
      o.stop_requested = [] { return g_stop.load(); };
      FILE* live = a->json ? stderr : stdout;
      o.live = [live](const std::string& line) {
        std::fprintf(live, "%s\n", line.c_str());
        std::fflush(live);
      };
      zmq::context_t context;
      WatchTally tally;
      const nlohmann::json s = watch(context, o, tally);
      if (a->json)
        std::cout << s.dump(2) << "\n";
      else
        std::cout << "summary: " << tally.summary_text();
    });
  });
}

void add_synth_command(CLI::App& app) {
  struct Args {
    std::string config, output, units = "mm";
    SynthOptions o;
    bool keypoints = false;
    KeypointCorruption k;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a synthetic TRC of a daemon config's model: smooth motion, Gaussian marker noise, "
      "occlusion gaps; the true joint centres go to FILE.joints.trc");
  cmd->add_option("--config", a->config, "Daemon config (fabrikd-config/1)")->required();
  cmd->add_option("--output", a->output, "TRC file to write (.trc)")->required();
  cmd->add_option("--seconds", a->o.seconds, "Duration")
      ->capture_default_str()
      ->check(cli::range(0.01, 86400.0));
  cmd->add_option("--rate", a->o.rate_hz, "Frame rate (Hz)")
      ->capture_default_str()
      ->check(cli::range(1.0, 10000.0));
  cmd->add_option("--noise-mm", a->o.noise_mm, "Marker noise, standard deviation per axis")
      ->capture_default_str()
      ->check(cli::range(0.0, 100.0));
  cmd->add_option("--gaps", a->o.gaps, "Occlusion windows of 0.2-1 s on random markers")
      ->capture_default_str()
      ->check(cli::range(0, 1000000));
  cmd->add_option("--seed", a->o.seed, "Motion, noise and gap seed")->capture_default_str();
  CLI::Option* keypoints =
      cmd->add_flag("--keypoints", a->keypoints,
                    "A markerless trial (docs/keypoints.md): the config's markers are keypoints "
                    "(`fabrik calibrate --template config/templates/halpe26.json --nominal`); adds "
                    "the jitter, dropouts and left/right swaps the options below ask for (none by "
                    "default); writes FILE.joints.trc, FILE.truth.mot "
                    "(true coordinates) and FILE.injected.csv (where each swap and dropout is)");
  cmd->add_option("--jitter-mm", a->k.jitter_mm, "--keypoints: jitter, sd per axis (mm)")
      ->capture_default_str()
      ->check(cli::range(0.0, 200.0))
      ->needs(keypoints);
  cmd->add_option("--dropouts-per-s", a->k.dropouts_per_s,
                  "--keypoints: runs of missing samples per second, on random keypoints")
      ->capture_default_str()
      ->check(cli::range(0.0, 1000.0))
      ->needs(keypoints);
  cmd->add_option("--dropout-frames-max", a->k.dropout_frames_max,
                  "--keypoints: each dropout lasts 2 to this many frames")
      ->capture_default_str()
      ->check(cli::range(2, 100000))
      ->needs(keypoints);
  cmd->add_option("--swaps-per-s", a->k.swaps_per_s,
                  "--keypoints: left/right label swaps per second")
      ->capture_default_str()
      ->check(cli::range(0.0, 1000.0))
      ->needs(keypoints);
  cmd->add_option("--swap-frames-max", a->k.swap_frames_max,
                  "--keypoints: each swap lasts 2 to this many frames")
      ->capture_default_str()
      ->check(cli::range(2, 100000))
      ->needs(keypoints);
  cmd->add_option("--limb-swap-share", a->k.limb_swap_share,
                  "--keypoints: share of swaps that swap a whole limb (else one pair)")
      ->capture_default_str()
      ->check(cli::range(0.0, 1.0))
      ->needs(keypoints);
  cmd->add_option("--units", a->units, "Units of the written TRC files")
      ->capture_default_str()
      ->check(CLI::IsMember({"mm", "m"}));
  cmd->callback([a] {
    run_command("synth", [&] {
      const std::string joints_path = joints_sidecar_path(a->output);
      const std::string stem_path = sidecar_stem(a->output);
      std::vector<NamedFile> files = {{"--config", a->config, false},
                                      {"--output", a->output},
                                      {"--output's FILE.joints.trc", joints_path}};
      if (a->keypoints) {
        files.push_back({"--output's FILE.truth.mot", stem_path + ".truth.mot"});
        files.push_back({"--output's FILE.injected.csv", stem_path + ".injected.csv"});
      }
      // What the name says is what a reader expects: a TRC named .csv was written as TRC.
      if (!has_suffix_ci(a->output, ".trc"))
        throw std::invalid_argument("--output: '" + a->output +
                                    "': synth writes a TRC file: name it .trc");
      require_usable_outputs(files);
      if (a->keypoints) {
        a->k.seed = a->o.seed;
        const KeypointTrial t = make_keypoint_trial(load_synth_setup(a->config), a->o, a->k);
        io::write_trc(a->output, t.keypoints, a->units);
        io::write_trc(joints_path, t.truth.joints, a->units);
        write_truth_mot(stem_path + ".truth.mot", t.truth);
        write_injected_csv(stem_path + ".injected.csv", t);
        std::size_t swaps = 0;
        for (const InjectedRun& r : t.injected) swaps += r.kind != InjectedRun::Kind::dropout;
        std::fprintf(stderr,
                     "synth: %s: %zu frames x %zu keypoints at %g Hz, jitter %g mm, %zu dropouts, "
                     "%zu swaps; truth: %s, %s.truth.mot; injected: %s.injected.csv\n",
                     safe_lines(a->output).c_str(), t.keypoints.frames(), t.keypoints.markers(),
                     t.keypoints.rate_hz, a->k.jitter_mm, t.injected.size() - swaps, swaps,
                     safe_lines(joints_path).c_str(), safe_lines(stem_path).c_str(),
                     safe_lines(stem_path).c_str());
        return;
      }
      const SynthTrial t = make_synth_trial(load_synth_setup(a->config), a->o);
      io::write_trc(a->output, t.markers, a->units);
      io::write_trc(joints_path, t.joints, a->units);
      std::fprintf(stderr, "synth: %s: %zu frames x %zu markers at %g Hz, %zu gaps; joints: %s\n",
                   safe_lines(a->output).c_str(), t.markers.frames(), t.markers.markers(),
                   t.markers.rate_hz, t.gaps.size(), safe_lines(joints_path).c_str());
    });
  });
}

namespace {

struct SimArgs {
  std::string file, bind = "127.0.0.1", file_up;
  SimScriptArgs script;
  bool loop = false, keep_zeros = false;
  double rate_scale = 1.0;
  std::int64_t frames = -1;
  int base_port = 22222;                          // QTM
  int command_port = 1510, data_port = 1511;     // NatNet
  bool unicast = false;
  std::string multicast_group = "239.255.42.99", up_axis = "+y", version = "4.1", subject;
};

void add_common_sim_options(CLI::App* cmd, SimArgs& a) {
  cmd->add_option("file", a.file, "Recording (.trc or .c3d)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--bind", a.bind, "Address to serve on (0.0.0.0: every interface)")
      ->capture_default_str();
  cmd->add_option("--file-up", a.file_up,
                  "The recording's up axis (+x, -y, +z, ...; default +y for TRC, +z for C3D)")
      ->check(CLI::IsMember({"+x", "-x", "+y", "-y", "+z", "-z"}));
  cmd->add_option("--rate-scale", a.rate_scale, "Serve at this multiple of the file's rate")
      ->check(cli::range(0.01, 100.0))
      ->capture_default_str();
  cmd->add_flag("--loop", a.loop, "Start over at the end (frame numbers keep increasing)");
  cmd->add_option("--frames", a.frames,
                  "Stop after N frames (default: the file, or forever with --loop)")
      ->check(cli::range(std::int64_t{1}, std::numeric_limits<std::int64_t>::max()));
  cmd->add_option("--pause-at", a.script.pauses, "T:S holds the stream for S s at time T (repeatable)");
  cmd->add_option("--drop", a.script.drops,
                  "NAME:T0:T1: the server does not see NAME from T0 to T1 s (repeatable)");
  cmd->add_option("--rename-at", a.script.renames,
                  "T:OLD=NEW: the server's label OLD becomes NEW at T s (repeatable)");
  cmd->add_option("--restart-at", a.script.restarts,
                  "T:S: the server goes away at T s and comes back S s later (repeatable)");
  cmd->add_flag("--keep-zeros", a.keep_zeros,
                "Serve exact (0, 0, 0) samples as positions (default: as not seen)");
}

std::pair<bridges::SimRecording, bridges::SimScript> sim_inputs(const char* command, const SimArgs& a) {
  io::MarkerTrial trial = io::read_trial(a.file, {.zeros_are_missing = !a.keep_zeros});
  for (const std::string& w : trial.warnings)
    std::fprintf(stderr, "fabrik %s: warning: %s: %s\n", command, safe_lines(a.file).c_str(),
                 safe_lines(w).c_str());
  io::require_marker_data(trial, a.file);
  bridges::SimRecording recording = sim_recording(trial, a.file_up);
  bridges::SimScript script = sim_script(a.script, recording);
  script.loop = a.loop;
  script.rate_scale = a.rate_scale;
  script.max_frames = a.frames;
  std::fprintf(stderr, "%s: %s: %zu frames x %zu markers at %g Hz (up %s), served at %g Hz%s\n", command,
               safe_lines(a.file).c_str(), recording.p_mm.size(), recording.names.size(), recording.rate_hz,
               recording.up.c_str(), recording.rate_hz * a.rate_scale, a.loop ? ", looping" : "");
  return {std::move(recording), std::move(script)};
}

// Serves on a thread of its own until the script ends or Ctrl-C, printing progress.
template <class Server>
void serve_until_stopped(const char* command, Server& server) {
  catch_stop_signals();
  std::atomic<bool> done{false};
  std::jthread thread([&](std::stop_token stop) {
    try {
      server.run(stop);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "\nfabrik %s: %s\n", command, safe_lines(e.what()).c_str());
    }
    done = true;
  });
  std::uint64_t shown = ~std::uint64_t{0};
  while (!done.load() && !g_stop.load()) {
    // This command's own thread: nothing waits on it, it only reports.
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const auto p = server.progress();
    if (p.frames_sent != shown)
      std::fprintf(stderr, "\r%s: %llu frames served, %d client(s)   ", command,
                   static_cast<unsigned long long>(p.frames_sent), p.clients);
    shown = p.frames_sent;
  }
  thread.request_stop();
  thread.join();
  std::fprintf(stderr, "\n%s: served %llu frames%s\n", command,
               static_cast<unsigned long long>(server.progress().frames_sent),
               g_stop.load() ? ", stopped by signal" : ", end of the script");
}

// "4.1" as a NatNet version, or nothing when it is not MAJOR.MINOR with each part 0-255.
std::optional<natnet::Version> natnet_version_of(const std::string& text) {
  int major = 0, minor = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%d.%d%c", &major, &minor, &tail) != 2 || major < 0 ||
      major > 255 || minor < 0 || minor > 255)
    return std::nullopt;
  return natnet::Version{static_cast<std::uint8_t>(major), static_cast<std::uint8_t>(minor), 0, 0};
}

std::uint16_t port_of(int port, const char* option) {
  if (port < 0 || port > 65535) throw std::invalid_argument(std::string(option) + " must be 0-65535");
  return static_cast<std::uint16_t>(port);
}

}  // namespace

void add_sim_command(CLI::App& app) {
  CLI::App* sim = app.add_subcommand(
      "sim", "Serve a TRC/C3D recording as a mocap system streams it live: Qualisys QTM (RT protocol) or "
             "OptiTrack Motive (NatNet), to try fabrikd's \"source\" input without the lab's system");
  sim->require_subcommand(1);

  auto q = std::make_shared<SimArgs>();
  CLI::App* qtm_cmd = sim->add_subcommand(
      "qtm", "A QTM RT server (protocol 1.8 and later, over TCP; the 3D component, labels from the 3D "
             "parameters, events on label changes): fabrikd connects with \"source\": \"qtm://HOST\"");
  add_common_sim_options(qtm_cmd, *q);
  qtm_cmd
      ->add_option("--base-port", q->base_port,
                   "QTM's base port: little endian on base + 1, big endian on base + 2")
      ->check(cli::range(0, 65533))
      ->capture_default_str();
  qtm_cmd->callback([q] {
    run_command("sim qtm", [&] {
      auto [recording, script] = sim_inputs("sim qtm", *q);
      qtm::QtmSimServer::Options o;
      o.bind_address = q->bind;
      o.base_port = port_of(q->base_port, "--base-port");
      qtm::QtmSimServer server(std::move(recording), std::move(script), o);
      std::fprintf(stderr,
                   "sim qtm: serving on %s port %u (little endian; fabrikd: \"qtm://%s:%u\"%s) and "
                   "%u (big endian)\n",
                   safe_lines(q->bind).c_str(), server.port_little_endian(),
                   url_host(q->bind).c_str(), server.port_little_endian(),
                   wildcard(q->bind) ? ", HOST: this machine's address" : "",
                   server.port_big_endian());
      serve_until_stopped("sim qtm", server);
    });
  });

  auto n = std::make_shared<SimArgs>();
  CLI::App* natnet_cmd = sim->add_subcommand(
      "natnet", "A Motive NatNet server (command channel, model definitions, frames of data in metres, "
                "Y up by default): fabrikd connects with \"source\": \"natnet://HOST\"");
  add_common_sim_options(natnet_cmd, *n);
  // Each value is checked here, before the recording is read (a long one took seconds to be
  // told its group was wrong).
  natnet_cmd->add_option("--command-port", n->command_port, "Command port")
      ->check(cli::range(0, 65535))
      ->capture_default_str();
  natnet_cmd->add_option("--data-port", n->data_port, "Data port")
      ->check(cli::range(0, 65535))
      ->capture_default_str();
  natnet_cmd->add_flag("--unicast", n->unicast, "Send frames to each connected client instead of the group");
  natnet_cmd->add_option("--multicast-group", n->multicast_group, "Multicast group of the frames")
      ->check(CLI::Validator(
          [](std::string& text) {
            const std::string problem = bridges::multicast_group_problem(text);
            return problem.empty() ? problem : problem + "; Motive's default is 239.255.42.99";
          },
          "GROUP"))
      ->capture_default_str();
  natnet_cmd
      ->add_option("--up-axis", n->up_axis,
                   "Motive's streaming up axis (+y as Motive's default, or +z)")
      ->check(CLI::IsMember({"+x", "-x", "+y", "-y", "+z", "-z"}))
      ->capture_default_str();
  natnet_cmd->add_option("--natnet-version", n->version, "NatNet version served, e.g. 3.1 or 4.1")
      ->check(CLI::Validator(
          [](std::string& text) {
            const std::optional<natnet::Version> v = natnet_version_of(text);
            if (!v) return "'" + text + "': expected MAJOR.MINOR, e.g. 4.1";
            if (!natnet::supported(*v))
              return "NatNet " + text + " cannot be served (3.x and 4.x can)";
            return std::string();
          },
          "MAJOR.MINOR"))
      ->capture_default_str();
  natnet_cmd
      ->add_option("--subject", n->subject,
                   "Motive's marker set (asset) name: a client reads each marker as "
                   "SUBJECT:MARKER")
      ->default_str(bridges::kSimMarkerSet);
  natnet_cmd->callback([n] {
    run_command("sim natnet", [&] {
      auto [recording, script] = sim_inputs("sim natnet", *n);
      script.subject_prefix = n->subject;
      bridges::NatNetSimServer::Options o;
      o.bind_address = n->bind;
      o.command_port = port_of(n->command_port, "--command-port");
      o.data_port = port_of(n->data_port, "--data-port");
      o.multicast = !n->unicast;
      o.multicast_group = n->multicast_group;
      o.up_axis = n->up_axis;
      o.version = natnet_version_of(n->version).value();  // checked at the parse
      bridges::NatNetSimServer server(std::move(recording), std::move(script), o);
      // What the client's config needs besides the URL: unicast, or a group and data port
      // other than NatNet's defaults.
      std::string options;
      const auto option = [&](const std::string& text) {
        options += (options.empty() ? " with " : ", ") + text;
      };
      if (!o.multicast) option("\"natnet_data\": \"unicast\"");
      if (o.multicast && o.multicast_group != bridges::NatNetSimServer::Options{}.multicast_group)
        option("\"multicast_group\": \"" + safe_lines(o.multicast_group) + "\"");
      if (o.multicast && server.data_port() != bridges::NatNetSimServer::Options{}.data_port)
        option("\"data_port\": " + std::to_string(server.data_port()));
      if (wildcard(n->bind)) options += ", HOST: this machine's address";
      std::fprintf(
          stderr,
          "sim natnet: commands on %s:%u, data %s port %u (fabrikd: \"natnet://%s:%u\"%s)\n",
          safe_lines(n->bind).c_str(), server.command_port(),
          o.multicast ? ("to " + safe_lines(o.multicast_group)).c_str() : "unicast,",
          server.data_port(), url_host(n->bind).c_str(), server.command_port(), options.c_str());
      serve_until_stopped("sim natnet", server);
    });
  });
}

}  // namespace fabrik::tools
