#include "tools.hpp"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>

#include "common/safe_text.hpp"
#include "replay.hpp"
#include "run_command.hpp"
#include "synth.hpp"
#include "watch.hpp"

namespace fabrik::tools {

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) {
  g_stop.store(true);
}

// Ctrl-C (or SIGTERM) ends a replay or a watch cleanly, with its summary.
void catch_stop_signals() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

}  // namespace

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
      ->check(CLI::Range(0.0, 1000.0));
  cmd->add_flag("--loop", a->loop, "Start over at the end (frame numbers keep increasing)");
  cmd->add_option("--drop", a->drops,
                  "NAME:T0:T1 sends marker NAME as null from T0 to T1 s (repeatable)");
  cmd->add_option("--encoding", a->encoding, "Payload encoding")
      ->check(CLI::IsMember({"json", "msgpack"}));
  cmd->add_option("--frames", a->frames, "Stop after N frames (0: all)");
  cmd->add_option("--wait-subscriber", a->wait_subscriber_s,
                  "Wait up to S seconds for a `markers` subscriber before sending");
  cmd->add_flag("--keep-zeros", a->keep_zeros,
                "Send exact (0, 0, 0) samples as positions (default: as null, missing)");
  cmd->callback([a] {
    run_command("replay", [&] {
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
        o.orientations = &table;
        std::fprintf(stderr, "replay: %s: %zu rows x %zu sensors at %g Hz%s\n",
                     safe_lines(a->orientations).c_str(), table.rows(), table.sensors.size(),
                     table.rate_hz, a->file.empty() ? " (the frames)" : ", joined on time");
      }
      o.endpoint = a->to;
      o.bind = a->bind;
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
      if (!a->file.empty())
        std::fprintf(stderr, "replay: %s: %zu frames x %zu markers at %g Hz -> %s (%s%s)\n",
                     safe_lines(a->file).c_str(), trial.frames(), trial.markers(), trial.rate_hz,
                     safe_lines(a->to).c_str(), a->encoding.c_str(), a->bind ? ", bound" : "");
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
    std::string from;
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
      ->check(CLI::Range(0.0, 1e9));
  cmd->add_flag("--json", a->json,
                "Print the final summary as one JSON object on stdout (live lines go to stderr)");
  cmd->callback([a] {
    run_command("watch", [&] {
      WatchOptions o;
      o.endpoint = a->from;
      o.bind = a->bind;
      o.seconds = a->seconds;
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
    std::string config, output;
    SynthOptions o;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a synthetic TRC of a daemon config's model: smooth motion, Gaussian marker noise, "
      "occlusion gaps; the true joint centres go to FILE.joints.trc");
  cmd->add_option("--config", a->config, "Daemon config (fabrikd-config/1)")->required();
  cmd->add_option("--output", a->output, "TRC file to write")->required();
  cmd->add_option("--seconds", a->o.seconds, "Duration")->check(CLI::Range(0.01, 86400.0));
  cmd->add_option("--rate", a->o.rate_hz, "Frame rate (Hz)")->check(CLI::Range(1.0, 10000.0));
  cmd->add_option("--noise-mm", a->o.noise_mm, "Marker noise, standard deviation per axis")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--gaps", a->o.gaps, "Occlusion windows of 0.2-1 s on random markers")
      ->check(CLI::Range(0, 1000000));
  cmd->add_option("--seed", a->o.seed, "Motion, noise and gap seed");
  cmd->callback([a] {
    run_command("synth", [&] {
      const SynthTrial t = make_synth_trial(load_synth_setup(a->config), a->o);
      const std::string joints = joints_sidecar_path(a->output);
      io::write_trc(a->output, t.markers, "mm");
      io::write_trc(joints, t.joints, "mm");
      std::fprintf(stderr, "synth: %s: %zu frames x %zu markers at %g Hz, %zu gaps; joints: %s\n",
                   safe_lines(a->output).c_str(), t.markers.frames(), t.markers.markers(),
                   t.markers.rate_hz, t.gaps.size(), safe_lines(joints).c_str());
    });
  });
}

}  // namespace fabrik::tools
