// `fabrik`: the command-line tool (benchmarks, replay/watch/synth).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <iostream>

#include "bench/bench.hpp"
#include "bench/convergence_bench.hpp"
#include "bench/latency_bench.hpp"
#include "bench/pipeline_bench.hpp"
#include "bench/subjects_bench.hpp"
#include "bench/view_bench.hpp"
#include "calibrate_command.hpp"
#include "cli_exit.hpp"
#include "eval_command.hpp"
#include "info_command.hpp"
#include "solve_command.hpp"
#include "tools/cli_checks.hpp"
#include "tools/tools.hpp"
#include "version.hpp"
#include "view_command.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fabrik: prioritized FABRIK inverse kinematics for motion capture"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(fabrik::kVersion));

  CLI::App* bench = app.add_subcommand("bench", "Benchmarks that print figures");
  bench->require_subcommand(1);

  fabrik::bench::PaperOptions paper;
  bool paper_json = false;
  CLI::App* b_paper = bench->add_subcommand(
      "paper",
      "The paper's experiment: FABRIK with and without priorities against the Jacobian transpose");
  b_paper->add_option("--experiment", paper.experiment,
                      "Experiment JSON (default: the embedded config/paper_experiment.json)");
  b_paper
      ->add_option("--repeats", paper.repeats, "Solves per algorithm (default: the experiment's)")
      ->check(fabrik::cli::range(1, 100000000));
  b_paper->add_flag("--json", paper_json, "Print one JSON object instead of a table");

  fabrik::bench::FullbodyOptions body;
  bool body_json = false;
  CLI::App* b_body =
      bench->add_subcommand("fullbody", "Full-body tracking of synthetic motion, warm-started");
  b_body->add_option("--frames", body.frames, "Frames to track")
      ->check(fabrik::cli::range(2, 10000000));
  b_body->add_option("--rate", body.rate_hz, "Frame rate (Hz)")
      ->check(fabrik::cli::range(1.0, 100000.0));
  b_body->add_option("--noise-mm", body.noise_mm, "Marker noise, standard deviation per axis (mm)")
      ->check(fabrik::cli::range(0.0, 100.0));
  b_body->add_option("--seed", body.seed, "Motion and noise seed");
  b_body->add_option("--model", body.model,
                     "Model file (default: the built-in config/models/fullbody.json)");
  b_body->add_option("--segment-fit", body.segment_fit, "paper or rigid")
      ->check(CLI::IsMember({"paper", "rigid"}));
  b_body->add_flag("--json", body_json, "Print one JSON object instead of a table");
  b_body->add_option("--config", body.config,
                     "Measure this daemon config alone (as `fabrik calibrate` writes it: its "
                     "model, ranges and solver options), with the subtree carry on and off in "
                     "alternate frames, instead of the built-in model and the calibrated "
                     "shipped template");
  b_body->add_option("--template", body.template_path,
                     "Template calibrated for the figure users get (default: the shipped "
                     "config/templates/gait2354.json)");
  b_body->add_option(
      "--static", body.static_trial,
      "Static trial it is calibrated on (default ../shared/data/subject01_static.trc; "
      "a generated one when absent)");
  b_body->add_option("--trial", body.trials,
                     "Recorded trials to replay through the calibrated config (default "
                     "../shared/data/subject01_walk1.trc, if present)");
  b_body
      ->add_option("--step", body.steps,
                   "Replay every k-th frame of each trial, for each k given (default 1 2 3)")
      ->check(fabrik::cli::range(1, 100));
  b_body
      ->add_option("--speed", body.speeds,
                   "Synthetic motion of the calibrated model at these multiples of the default "
                   "cycle frequency (default 1 3)")
      ->check(fabrik::cli::range(0.01, 100.0));
  bool builtin_only = false;
  b_body->add_flag("--builtin-only", builtin_only,
                   "Only the built-in model (no calibrated template)");

  fabrik::bench::LatencyOptions latency;
  bool latency_json = false;
  CLI::App* b_latency = bench->add_subcommand(
      "latency",
      "End-to-end latency of the daemon pipeline over loopback tcp and ipc, against a bare "
      "ZeroMQ echo of the same sizes run alternately");
  b_latency->add_option("--rate", latency.rate_hz, "Marker frames per second")
      ->check(fabrik::cli::range(1.0, 100000.0));
  b_latency
      ->add_option("--seconds", latency.seconds,
                   "Duration per transport, for the daemon and for the floor each")
      ->check(fabrik::cli::range(0.1, 3600.0));
  b_latency
      ->add_option("--block-seconds", latency.block_seconds,
                   "The daemon and the floor take turns in blocks this long")
      ->check(fabrik::cli::range(0.001, 3600.0));
  b_latency
      ->add_option("--config", latency.config,
                   "Daemon config to run (as `fabrik calibrate` writes it; default: the "
                   "built-in one); its model's synthetic motion makes the frames")
      ->check(CLI::ExistingFile);
  b_latency->add_option("--transport", latency.transports, "tcp and/or ipc")
      ->check(CLI::IsMember({"tcp", "ipc"}));
  b_latency->add_option("--encoding", latency.encoding, "json or msgpack")
      ->check(CLI::IsMember({"json", "msgpack"}));
  b_latency->add_option("--orientations", latency.orientations,
                        "none; mixed: markers and a sensor on every segment; only: sensors alone")
      ->check(CLI::IsMember({"none", "mixed", "only"}));
  b_latency
      ->add_option("--source", latency.sources,
                   "Compare a vendor source with the ZeroMQ input (qtm, natnet; repeatable or a "
                   "list): one daemon fed by a simulated server and ZeroMQ alternately, "
                   "--rate then the total (default 500)")
      ->delimiter(',')
      ->check(CLI::IsMember({"qtm", "natnet"}));
  b_latency
      ->add_option("--view", latency.view_parts,
                   "Subscribe to a pose view (output.views) of these optional parts (e.g. "
                   "angles; none: the required fields only) instead of to pose, as a client "
                   "that wants only them: the full pose is then not made")
      ->delimiter(',');
  b_latency->add_flag("--json", latency_json, "Print one JSON object instead of a table");

  fabrik::bench::PipelineOptions pipeline;
  bool pipeline_json = false;
  CLI::App* b_pipeline = bench->add_subcommand(
      "pipeline", "The daemon's frame path in-process: decode, solve, encode and send per frame");
  b_pipeline
      ->add_option("--config", pipeline.configs,
                   "Daemon configs to measure beside the default one (as `fabrik calibrate` "
                   "writes them; repeatable)")
      ->check(CLI::ExistingFile);
  b_pipeline->add_option("--frames", pipeline.frames, "Frames measured per config")
      ->check(fabrik::cli::range(10, 10000000))
      ->capture_default_str();
  b_pipeline->add_option("--rate", pipeline.rate_hz, "Sampling rate of the synthetic motion (Hz)")
      ->check(fabrik::cli::range(1.0, 100000.0))
      ->capture_default_str();
  b_pipeline->add_option("--transport", pipeline.transport, "The output's: tcp or ipc")
      ->check(CLI::IsMember({"tcp", "ipc"}))
      ->capture_default_str();
  b_pipeline->add_option("--encoding", pipeline.encoding, "json or msgpack, in and out")
      ->check(CLI::IsMember({"json", "msgpack"}))
      ->capture_default_str();
  b_pipeline
      ->add_option("--pose-content", pipeline.pose_content,
                   "output.pose_content for every config: the pose's optional parts to send "
                   "(e.g. angles; none: the required fields only); default each config's own")
      ->delimiter(',');
  b_pipeline->add_flag("--json", pipeline_json, "Print one JSON object instead of a table");

  fabrik::bench::SubjectsOptions subjects;
  bool subjects_json = false;
  CLI::App* b_subjects = bench->add_subcommand(
      "subjects",
      "Several subjects in one daemon over loopback tcp: per-frame latency to the last "
      "subject's pose, and dropped frames, against the subject count");
  b_subjects->add_option("--counts", subjects.counts, "Subject counts, run in turn")
      ->delimiter(',')
      ->check(fabrik::cli::range(1, 64))
      ->capture_default_str();
  b_subjects->add_option("--rate", subjects.rate_hz, "Frames per second")
      ->check(fabrik::cli::range(1.0, 100000.0))
      ->capture_default_str();
  b_subjects->add_option("--seconds", subjects.seconds, "Duration per count")
      ->check(fabrik::cli::range(0.1, 3600.0))
      ->capture_default_str();
  b_subjects
      ->add_option("--config", subjects.config,
                   "One subject's config (as `fabrik calibrate` writes it; default: the built-in "
                   "one), every subject tracked with it")
      ->check(CLI::ExistingFile);
  b_subjects->add_flag("--json", subjects_json, "Print one JSON object instead of a table");

  fabrik::bench::ViewBenchOptions view_bench;
  bool view_json = false;
  CLI::App* b_view = bench->add_subcommand(
      "view", "fabrik view in-process at 1 kHz input: poses/s to 1 and 5 WebSocket clients, "
              "latency, the view's CPU");
  b_view->add_option("--input-hz", view_bench.input_hz, "Poses per second into the view")
      ->capture_default_str()
      ->check(fabrik::cli::range(1.0, 100000.0));
  b_view->add_option("--rate-hz", view_bench.rate_hz, "The view's per-client cap")
      ->capture_default_str()
      ->check(fabrik::cli::range(0.1, 1000.0));
  b_view->add_option("--seconds", view_bench.seconds, "Duration per client count")
      ->capture_default_str()
      ->check(fabrik::cli::range(0.1, 3600.0));
  b_view->add_option("--clients", view_bench.clients, "Client counts to run")
      ->delimiter(',')
      ->check(fabrik::cli::range(1, 64));
  b_view->add_flag("--json", view_json, "Print one JSON object instead of a table");

  fabrik::bench::ConvergenceOptions convergence;
  bool convergence_json = false;
  CLI::App* b_convergence = bench->add_subcommand(
      "convergence",
      "Convergence on reachable targets: stars of 10-50 end effectors, chains of 100-200 "
      "segments, cold and warm");
  b_convergence->add_option("--solves", convergence.solves, "Solves per case and start")
      ->check(fabrik::cli::range(1, 10000000))
      ->capture_default_str();
  b_convergence->add_option("--seed", convergence.seed, "Pose seed")->capture_default_str();
  b_convergence
      ->add_option("--stall-ratio", convergence.stall_ratio,
                   "Stall tolerance as a fraction of the tolerance")
      ->check(fabrik::cli::range(0.0, 1.0))
      ->capture_default_str();
  b_convergence
      ->add_option("--max-turn", convergence.max_turn_rad,
                   "Each joint of a target posture turned by up to this from rest (rad; "
                   "default 0.1 for stars, 0.4 for chains)")
      ->check(fabrik::cli::range(0.0, 3.2));
  b_convergence
      ->add_option("--max-iterations", convergence.max_iterations,
                   "Iteration budget (default: the solver's)")
      ->check(fabrik::cli::range(1, 1000000));
  b_convergence
      ->add_option("--case", convergence.cases,
                   "Only these cases (star10 star20 star50 chain100 chain100_10um chain200 "
                   "chain200_10um)")
      ->delimiter(',');
  b_convergence->add_flag("--json", convergence_json, "Print one JSON object instead of a table");

  fabrik::apps::add_solve_command(app);
  fabrik::apps::add_info_command(app);
  fabrik::add_calibrate_command(app);
  fabrik::apps::add_eval_command(app);
  fabrik::apps::add_view_command(app);
  fabrik::tools::add_tool_commands(app);  // run from their own callbacks
  fabrik::cli::refuse_surprising_values(app);
  if (const std::string unknown = fabrik::apps::unknown_command(app, argc, argv);
      !unknown.empty()) {
    std::fputs(fabrik::safe_lines(unknown).c_str(), stderr);
    return 2;
  }

  try {
    app.parse(argc, argv);  // subcommands with callbacks run here
    if (b_paper->parsed()) {
      const auto r = fabrik::bench::run_paper(paper);
      std::cout << (paper_json ? r.dump(2) + "\n" : fabrik::bench::paper_table(r));
    } else if (b_latency->parsed()) {
      if (b_latency->count("--rate") > 0) latency.source_rate_hz = latency.rate_hz;
      const auto r = fabrik::bench::run_latency(latency);
      std::cout << (latency_json ? r.dump(2) + "\n" : fabrik::bench::latency_table(r));
    } else if (b_convergence->parsed()) {
      const auto r = fabrik::bench::run_convergence(convergence);
      std::cout << (convergence_json ? r.dump(2) + "\n" : fabrik::bench::convergence_table(r));
    } else if (b_pipeline->parsed()) {
      const auto r = fabrik::bench::run_pipeline(pipeline);
      std::cout << (pipeline_json ? r.dump(2) + "\n" : fabrik::bench::pipeline_table(r));
    } else if (b_subjects->parsed()) {
      const auto r = fabrik::bench::run_subjects(subjects);
      std::cout << (subjects_json ? r.dump(2) + "\n" : fabrik::bench::subjects_table(r));
    } else if (b_view->parsed()) {
      const auto r = fabrik::bench::run_view_bench(view_bench);
      std::cout << (view_json ? r.dump(2) + "\n" : fabrik::bench::view_bench_table(r));
    } else if (b_body->parsed()) {
      body.calibrated = !builtin_only;
      if (!body.config.empty()) {
        const auto r = fabrik::bench::run_calibrated(body);
        std::cout << (body_json ? r.dump(2) + "\n" : fabrik::bench::calibrated_table(r));
      } else {
        const auto r = fabrik::bench::run_fullbody(body);
        std::cout << (body_json ? r.dump(2) + "\n" : fabrik::bench::fullbody_table(r));
      }
    }
  } catch (const CLI::Error& e) {  // parse errors, and RuntimeError(code) from commands
    return fabrik::apps::exit_safely(app, e, "fabrik");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fabrik: %s\n", fabrik::safe_lines(e.what()).c_str());
    return 2;
  }
  // A command's results on standard output (a table, `--json`) lost to a full disk.
  if (!fabrik::apps::standard_output_written("fabrik")) return 2;
  return 0;
}
