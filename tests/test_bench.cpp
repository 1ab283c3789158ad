// The benchmarks' own checks: the paper experiment's postures (free joints and
// with range-of-motion limits) and the full-body run with limits on and off.
#include <catch2/catch.hpp>

#include <fstream>

#include "bench/bench.hpp"
#include "bench/generic_static.hpp"
#include "bench/latency_bench.hpp"
#include "bench/pipeline_bench.hpp"
#include "bench/subjects_bench.hpp"
#include "bench/wake_probe.hpp"
#include "bench/zmq_floor.hpp"
#include "calib/calibrate.hpp"
#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"
#include "synth/synthetic_motion.hpp"
#include "temp_file.hpp"
#ifdef FABRIK_PATH
#include "run_fabrik.hpp"
#endif
#include "transport/marker_codec.hpp"

using namespace fabrik;

TEST_CASE("The paper experiment passes its posture checks, also with joint limits", "[bench]") {
  bench::PaperOptions o;
  o.repeats = 3;  // the checks, not the times
  const nlohmann::json r = bench::run_paper(o);
  for (const auto& [name, c] : r["checks"].items()) {
    CAPTURE(name, c.dump());
    CHECK(c["pass"].get<bool>());
  }
  REQUIRE(r.contains("with_limits"));
  for (const auto& [name, c] : r["with_limits"]["checks"].items()) {
    CAPTURE(name, c.dump());
    CHECK(c["pass"].get<bool>());
  }
  // The limits change the answer: the elbows may not hyperextend, so both
  // wrists end further than without limits.
  const auto& free = r["algorithms"]["fabrik"]["error_mm"];
  const auto& limited = r["with_limits"]["algorithms"]["fabrik"]["error_mm"];
  CHECK(limited["r_wrist"].get<double>() > free["r_wrist"].get<double>() + 1.0);
  CHECK(r["all_checks_pass"].get<bool>());
}

TEST_CASE("The full-body benchmark tracks a model with limits with and without them", "[bench]") {
  // The built-in full-body model with its knees as hinges.
  std::ifstream in(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  nlohmann::json model = nlohmann::json::parse(in);
  for (auto& s : model["segments"])
    if (s["name"] == "r_shank" || s["name"] == "l_shank")
      s["joint"] = {{"type", "hinge"}, {"range_deg", {{"z", {-140, 5}}}}};
  test::TempFile file(".json");
  std::ofstream(file.path()) << model.dump();
  bench::FullbodyOptions o;
  o.frames = 50;
  o.model = file.path();
  const nlohmann::json r = bench::run_fullbody(o);
  REQUIRE(r["model"]["joint_limits"].get<bool>());
  REQUIRE(r.contains("without_limits"));
  CHECK(r["iterations_mean"].get<double>() > 0.0);
  CHECK(r["without_limits"]["iterations_mean"].get<double>() > 0.0);
}

TEST_CASE("The figure users get: the shipped gait2354 calibrated on a generated static trial",
          "[bench]") {
  // No recorded static trial: the bench calibrates on its generated one, then tracks
  // synthetic motion of the calibrated model with the carry on and off.
  bench::FullbodyOptions o;
  o.frames = 40;
  o.static_trial = "";
  o.template_path = std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json";
  o.trials.clear();
  o.speeds = {1.0};
  const nlohmann::json r = bench::run_calibrated(o);
  CAPTURE(r.dump(1));
  CHECK_THAT(r["config"].get<std::string>(), Catch::Contains("a generated static trial"));
  CHECK(r["solver"]["subtree_carry"].get<double>() > 0.0);  // as calibrate writes it
  REQUIRE(r["runs"].size() == 1);
  const nlohmann::json& run = r["runs"][0];
  REQUIRE(run.contains("without_carry"));
  CHECK(run["carry"]["median_ratio"].get<double>() > 0.0);
  for (const char* key : {"as_configured", "without_carry"}) {
    const nlohmann::json& t = run[key];
    CAPTURE(key);
    CHECK(t["frames"].get<int>() == 39);  // the cold first frame is reported apart
    const nlohmann::json& st = t["status"];
    CHECK(st["converged"].get<int>() + st["stalled"].get<int>() + st["max_iterations"].get<int>() ==
          39);
    CHECK(t["iterations_mean"].get<double>() >= 1.0);
  }
  // The generated subject is a plausible body: its motion is tracked to about the noise.
  const nlohmann::json& t = run["as_configured"];
  CHECK(t["marker_residual_mm"]["rms_mean"].get<double>() < 4.0);
  CHECK(t["joint_centre_error_mm"]["rms_mean"].get<double>() < 8.0);
}

namespace {

// The shipped gait2354 as `fabrik calibrate` writes it, calibrated on the generated static trial.
void write_calibrated_gait2354(const std::string& path) {
  const calib::CalibTemplate tmpl =
      calib::load_template_file(std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json");
  const calib::CalibrationResult cal =
      calib::calibrate(tmpl, bench::generic_gait2354_static(), "generic.trc");
  std::ofstream(path) << cal.config.dump();
}

}  // namespace

TEST_CASE("bench fullbody --config replays a recorded trial forward and back, every k-th frame",
          "[bench]") {
  // A config as `fabrik calibrate` writes it, and a short trial of its model's markers.
  test::TempFile config(".json"), trc(".trc");
  write_calibrated_gait2354(config.path());
  const DaemonConfig loaded = load_daemon_config_file(config.path());
  const Model& m = *loaded.tracker.model;
  SyntheticMotion motion(m, MotionSettings{});
  Posture p = Posture::rest(m);
  io::MarkerTrial trial;
  trial.rate_hz = 100.0;
  std::vector<int> points;
  for (const MarkerTarget& t : loaded.tracker.markers) {
    trial.labels.push_back(t.marker);
    points.push_back(t.point);
  }
  std::vector<Eigen::Vector3d> frame(points.size());
  for (int f = 0; f < 30; ++f) {
    motion.posture_at(f / 100.0, p);
    motion.sample(p, points, 0.0, frame);
    trial.positions_m.insert(trial.positions_m.end(), frame.begin(), frame.end());
  }
  io::write_trc(trc.path(), trial);
  bench::FullbodyOptions o;
  o.config = config.path();
  o.frames = 100;  // more than the trial's 30: played back and forth
  o.trials = {trc.path()};
  o.steps = {1, 3};
  o.speeds.clear();
  const nlohmann::json r = bench::run_calibrated(o);
  CAPTURE(r.dump(1));
  REQUIRE(r["runs"].size() == 2);
  CHECK_THAT(r["runs"][1]["source"].get<std::string>(), Catch::Contains("1 frame in 3 (3x speed)"));
  CHECK(r["runs"][1]["rate_hz"].get<double>() == Approx(100.0 / 3));
  for (const nlohmann::json& run : r["runs"]) {
    CHECK(run["as_configured"]["frames"].get<int>() == 99);
    // Noise-free markers of the model itself, turning back at each end: tracked closely (the
    // worst frames, up to 8 mm, follow the cold first one, which stalls short of the fit).
    CHECK(run["as_configured"]["marker_residual_mm"]["rms_mean"].get<double>() < 2.0);
  }
}

#ifdef FABRIK_PATH
TEST_CASE("fabrik bench fullbody --config tracks that config's model and prints the carry's cost",
          "[bench]") {
  // A calibrated gait2354 (the carry on, as calibrate writes it) and the embedded default
  // (the built-in model, the carry off): each run reports the other setting beside it.
  test::TempFile calibrated(".json"), out(".json");
  write_calibrated_gait2354(calibrated.path());
  for (const std::string& path :
       {calibrated.path(), std::string(FABRIK_SOURCE_DIR) + "/config/default.json"}) {
    CAPTURE(path);
    const DaemonConfig config = load_daemon_config_file(path);
    const auto [code, err] = test::run_fabrik(
        {"bench", "fullbody", "--config", path, "--frames", "30", "--speed", "1", "--json"},
        out.path());
    CAPTURE(err);
    REQUIRE(code == 0);
    const nlohmann::json r = nlohmann::json::parse(test::slurp(out.path()));
    CAPTURE(r.dump(1));
    // That config's model, not the built-in one or the shipped template's.
    const Model& m = *config.tracker.model;
    CHECK(r["model"]["markers"].get<std::size_t>() == config.tracker.markers.size());
    REQUIRE(r["model"]["segment_names"].size() == m.segments.size());
    for (std::size_t i = 0; i < m.segments.size(); ++i)
      CHECK(r["model"]["segment_names"][i] == m.segments[i].name);
    const double carry = config.tracker.solver.subtree_carry;
    CHECK(r["solver"]["subtree_carry"].get<double>() == carry);
    // The carry's cost in every run, against the setting the config does not have.
    REQUIRE(r["runs"].size() >= 1);
    for (const nlohmann::json& run : r["runs"]) {
      CHECK(run.contains(carry > 0.0 ? "without_carry" : "with_carry"));
      CHECK(run["carry"]["subtree_carry"].get<double>() == (carry > 0.0 ? carry : 0.5));
      CHECK(run["carry"]["median_ratio"].get<double>() > 0.0);
      CHECK(run["carry"]["iterations_ratio"].get<double>() > 0.0);
    }
  }
}
#endif

TEST_CASE("bench latency --source: QTM and NatNet frames and ZeroMQ frames all come back as poses",
          "[bench][latency][source]") {
  bench::LatencyOptions o;
  o.sources = {"qtm", "natnet"};
  o.source_rate_hz = 200.0;  // 100 Hz on each input
  o.seconds = 0.2;           // 20 frames each: the plumbing, not the times
  const nlohmann::json r = bench::run_latency(o);
  REQUIRE(r["source_runs"].size() == 2);
  for (const nlohmann::json& run : r["source_runs"]) {
    CAPTURE(run.dump());
    REQUIRE(run["inputs"].size() == 2);
    CHECK(run["inputs"][0]["input"] == "zmq");
    CHECK(run["inputs"][1]["input"] == run["source"]);
    for (const nlohmann::json& in : run["inputs"]) {
      // Every frame the server wrote (the hook saw them all, in order) had a
      // ZeroMQ frame after it. Poses: some of each (a loaded machine's stall
      // may make the daemon drop a backlog, which is not what this checks).
      CHECK(in["frames_sent"] == 20);
      CHECK(in["poses_received"].get<int>() > 0);
      CHECK(in["latency_us"]["p50"].get<double>() > 0.0);
    }
    CHECK(run["daemon_decode_errors"] == 0);
    CHECK(run["daemon_unknown_markers"] == 0);
  }
}

TEST_CASE("bench latency reports the daemon and the floor for each transport and their differences",
          "[bench][latency]") {
  bench::LatencyOptions o;
  o.seconds = 0.5;        // 500 frames each at 1 kHz: the report, not the times
  o.block_seconds = 0.1;  // several turns each
  const nlohmann::json r = bench::run_latency(o);
  REQUIRE(r["runs"].size() == 2);
  CHECK(r["runs"][0]["transport"] == "tcp");
  CHECK(r["runs"][1]["transport"] == "ipc");
  for (const nlohmann::json& run : r["runs"]) {
    CAPTURE(run.dump());
    for (const char* path : {"daemon", "floor"}) {
      CAPTURE(path);
      REQUIRE(run.contains(path));
      const nlohmann::json& x = run[path];
      CHECK(x["frames_sent"] == 500);
      // Some of each (a loaded machine's stall may make the daemon drop a
      // backlog, which is not what this checks).
      CHECK(x["poses_received"].get<int>() > 0);
      CHECK(x["latency_us"]["p50"].get<double>() > 0.0);
      CHECK(x["latency_us"]["p99"].get<double>() >= x["latency_us"]["p50"].get<double>());
    }
    const nlohmann::json& d = run["daemon"];
    const nlohmann::json& f = run["floor"];
    CHECK(run["daemon_minus_floor_us"]["p50"].get<double>() ==
          Approx(d["latency_us"]["p50"].get<double>() - f["latency_us"]["p50"].get<double>()));
    CHECK(run["daemon_minus_floor_us"]["p99"].get<double>() ==
          Approx(d["latency_us"]["p99"].get<double>() - f["latency_us"]["p99"].get<double>()));
    CHECK(run["goals"]["p50_met"].is_boolean());
    CHECK(run["goals"]["p99_met"].is_boolean());
    // The floor answers with the daemon's pose size (the poses' numbers vary by a few digits).
    CHECK(f["pose_bytes"].get<double>() ==
          Approx(d["pose_bytes_mean"].get<double>()).epsilon(0.02));
    CHECK(d["decode_errors"] == 0);
    // The daemon's own stages, read from the stats it published during the run (JSON here).
    const nlohmann::json& st = run["daemon_stages_us"];
    REQUIRE(st["intervals"].get<int>() > 0);
    for (const char* stage : {"decode", "solve", "encode", "send"})
      CHECK(st[stage].get<double>() > 0.0);
    CHECK(st["decode_solve_encode"].get<double>() ==
          Approx(st["decode"].get<double>() + st["solve"].get<double>() +
                 st["encode"].get<double>()));
  }
}

TEST_CASE("daemon_stages: per stage the median of the intervals' p50s, idle intervals left out",
          "[bench][latency]") {
  const auto stats = [](double decode, double solve, double encode, double send) {
    const auto q = [](double p50) {
      return nlohmann::json{{"p50", p50}, {"p99", 2 * p50}, {"max", 3 * p50}};
    };
    return nlohmann::json{
        {"frames_out", 10},
        {"stages_us",
         {{"decode", q(decode)}, {"solve", q(solve)}, {"encode", q(encode)}, {"send", q(send)}}}};
  };
  const std::vector<nlohmann::json> intervals = {
      stats(1, 10, 5, 7),
      stats(6, 40, 1, 20),
      stats(2, 20, 2, 8),                             // medians, not means
      stats(0, 0, 0, 0),                              // served no frame: left out
      {{"stages_us", {{"solve", {{"p50", 99.0}}}}}},  // stages missing: left out
      {{"frames_out", 0}}};                           // no stages at all: left out
  for (const char* encoding : {"json", "msgpack"}) {
    CAPTURE(encoding);
    std::vector<std::string> bodies;
    for (const nlohmann::json& j : intervals) {
      if (std::string(encoding) == "json") {
        bodies.push_back(j.dump());
      } else {
        const std::vector<std::uint8_t> b = nlohmann::json::to_msgpack(j);
        bodies.emplace_back(b.begin(), b.end());
      }
    }
    bodies.push_back("not stats");  // unreadable: left out
    const nlohmann::json st = bench::daemon_stages(bodies, encoding);
    CHECK(st["intervals"] == 3);
    CHECK(st["decode"].get<double>() == 2.0);
    CHECK(st["solve"].get<double>() == 20.0);
    CHECK(st["encode"].get<double>() == 2.0);
    CHECK(st["send"].get<double>() == 8.0);
    CHECK(st["decode_solve_encode"].get<double>() == 24.0);
  }
  CHECK(bench::daemon_stages({}, "json")["intervals"] == 0);
}

TEST_CASE("bench pipeline reports each stage, and the solve split into the solver and the rest",
          "[bench][pipeline]") {
  for (const char* encoding : {"json", "msgpack"}) {
    CAPTURE(encoding);
    bench::PipelineOptions o;
    o.frames = 300;  // the report, not the times
    o.encoding = encoding;
    const nlohmann::json r = bench::run_pipeline(o);
    REQUIRE(r["models"].size() == 1);
    const nlohmann::json& m = r["models"][0];
    CAPTURE(m.dump());
    CHECK(m["frames"].get<int>() + m["lost"].get<int>() == 300);
    REQUIRE(m["frames"].get<int>() > 0);
    CHECK(m["pose_bytes"].get<int>() > 1000);
    for (const char* stage : {"decode", "solve", "encode", "send"})
      CHECK(m["stages_us"][stage]["p50"].get<double>() > 0.0);
    // The solver is part of the solve stage, frame by frame, so of its quantiles too.
    const double solve = m["stages_us"]["solve"]["p50"], solver = m["solver_us"]["p50"];
    CHECK(solver > 0.0);
    CHECK(solver <= solve);
    CHECK(m["tracker_besides_solver_us"]["p50"].get<double>() >= 0.0);
    CHECK(m["tracker_besides_solver_us"]["p50"].get<double>() <= solve);
    // Warm frames at 1 kHz: at least one iteration, within the warm budget at p50.
    CHECK(m["iterations"]["mean"].get<double>() >= 1.0);
    CHECK(m["iterations"]["p50"].get<double>() <= 50.0);
    // The machine's wake-up price, sampled between the frames.
    CHECK(r["wake_us"]["sleeping_thread"]["p50"].get<double>() > 0.0);
    CHECK(r["wake_us"]["write_alone"]["p50"].get<double>() > 0.0);
    // One wake sampled after each frame, or counted as dropped.
    CHECK(r["wake_us"]["sleeping_thread_samples"].get<int>() +
              r["wake_us"]["sleeping_thread_samples_dropped"].get<int>() ==
          300);
  }
}

TEST_CASE("The wake probe's sleeper takes each wake, so every sample finds it asleep again",
          "[bench][pipeline]") {
  bench::WakeProbe probe;
  for (int i = 0; i < 200; ++i) {
    CAPTURE(i);
    // Negative: the previous wake was not taken within 2 s (the sleeper lost it); the
    // bench's 10 ms would also fail on a machine busy for a moment.
    REQUIRE(probe.wake_sleeping_us(std::chrono::milliseconds(2000)) >= 0.0);
    CHECK(probe.write_alone_us() >= 0.0);
  }
}

TEST_CASE("bench latency --view subscribes to a view alone, and the floor answers with its size",
          "[bench][latency][views]") {
  bench::LatencyOptions o;
  o.transports = {"tcp"};
  o.seconds = 0.2;
  o.encoding = "msgpack";
  const nlohmann::json full = bench::run_latency(o);
  o.view_parts = {"none"};
  const nlohmann::json lean = bench::run_latency(o);
  CAPTURE(full.dump(), lean.dump());
  CHECK(full["subscribed_to"] == "pose");
  CHECK(lean["subscribed_to"]["view"] == nlohmann::json::array({"none"}));
  const nlohmann::json& d = lean["runs"][0]["daemon"];
  REQUIRE(d["poses_received"].get<int>() > 0);
  // Its stats read in MessagePack, the output's encoding.
  CHECK(lean["runs"][0]["daemon_stages_us"]["solve"].get<double>() > 0.0);
  CHECK(d["decode_errors"] == 0);
  // The required fields only: well under the full pose.
  const double full_bytes = full["runs"][0]["daemon"]["pose_bytes_mean"].get<double>();
  CHECK(d["pose_bytes_mean"].get<double>() < 0.8 * full_bytes);
  CHECK(lean["runs"][0]["floor"]["pose_bytes"].get<double>() ==
        Approx(d["pose_bytes_mean"].get<double>()).epsilon(0.02));
}

TEST_CASE("bench latency --config runs that config's model against the floor", "[bench][latency]") {
  const calib::CalibTemplate tmpl =
      calib::load_template_file(std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json");
  const calib::CalibrationResult cal =
      calib::calibrate(tmpl, bench::generic_gait2354_static(), "generic.trc");
  test::TempFile config(".json");
  std::ofstream(config.path()) << cal.config.dump();
  const DaemonConfig loaded = load_daemon_config_file(config.path());
  bench::LatencyOptions o;
  o.config = config.path();
  o.transports = {"tcp"};
  o.seconds = 0.2;
  const nlohmann::json r = bench::run_latency(o);
  CAPTURE(r.dump());
  CHECK(r["model"]["markers"] == loaded.tracker.markers.size());
  REQUIRE(r["runs"].size() == 1);
  const nlohmann::json& run = r["runs"][0];
  CHECK(run["daemon"]["poses_received"].get<int>() > 0);
  CHECK(run["floor"]["poses_received"].get<int>() > 0);
  CHECK(run["daemon"]["decode_errors"] == 0);
  // The source sends the config's markers: the daemon knows every one.
  CHECK(run["daemon"]["unknown_markers"] == 0);
}

TEST_CASE("The floor finds a frame number where both encoders write it", "[bench][latency]") {
  const std::vector<std::string> names = {"A"};
  const std::vector<Eigen::Vector3d> p_m = {Eigen::Vector3d(0.1, 0.2, 0.3)};
  const std::vector<std::uint8_t> visible = {1};
  std::string out;
  for (auto encoding : {wire::PayloadEncoding::json, wire::PayloadEncoding::msgpack})
    for (std::uint64_t frame : {std::uint64_t{5}, std::uint64_t{1234567}}) {
      const double t_s = 1.5;
      wire::encode_marker_frame(frame, &t_s, names, p_m, visible, "mm", encoding, out);
      const auto n =
          bench::frame_number({reinterpret_cast<const std::uint8_t*>(out.data()), out.size()});
      CAPTURE(out, frame);
      REQUIRE(n.has_value());
      CHECK(*n == frame);
    }
  // A MessagePack map of 16 entries or more has a 3-byte header (a pose with all its parts).
  const std::vector<std::uint8_t> map16 = {0xde, 0x00, 0x10, 0xa5, 'f', 'r', 'a', 'm', 'e',
                                           0xcf, 0,    0,    0,    0,   0,   1,   0,   2};
  CHECK(bench::frame_number(map16) == std::uint64_t{65538});
  CHECK_FALSE(bench::frame_number(std::vector<std::uint8_t>{'{', '}'}).has_value());
}

TEST_CASE("bench subjects answers every frame for every count and reports it", "[bench][subjects]") {
  bench::SubjectsOptions o;
  o.counts = {1, 3};
  o.seconds = 0.5;  // 120 frames each at 240 Hz: the report, not the times
  const nlohmann::json r = bench::run_subjects(o);
  REQUIRE(r["runs"].size() == 2);
  CHECK(r["markers_per_subject"] == default_daemon_config().tracker.markers.size());
  for (std::size_t k = 0; k < 2; ++k) {
    const nlohmann::json& run = r["runs"][k];
    CAPTURE(run.dump());
    CHECK(run["subjects"] == o.counts[k]);
    CHECK(run["frames"] == 120);
    // Answered: the last subject's pose of the frame arrived. A loaded
    // machine's stall may make the daemon drop a backlog, but every frame
    // left unanswered is one the daemon counted as dropped.
    CHECK(run["unanswered"].get<int>() <= run["daemon_frames_dropped"].get<int>());
    CHECK(run["answered"].get<int>() > 0);
    CHECK(run["p99_us"].get<double>() >= run["p50_us"].get<double>());
    CHECK(run["p50_us"].get<double>() > 0.0);
  }
  CHECK(bench::subjects_table(r).find("subjects  frames") != std::string::npos);
}

TEST_CASE("QuietDeadline: a run stops waiting half a second after its last frame, stats or not",
          "[bench]") {
  using namespace std::chrono_literals;
  using bench::QuietDeadline;
  const QuietDeadline::Clock::time_point t0{};
  QuietDeadline quiet(500ms);
  // While sending, a late answer is no reason to stop, however long it takes.
  quiet.frame(t0 + 1s);
  CHECK_FALSE(quiet.expired(t0 + 10s));
  // Sending done at 10 s: the wait ends 500 ms later unless a frame comes.
  quiet.sending_done(t0 + 10s);
  CHECK_FALSE(quiet.expired(t0 + 10s + 499ms));
  quiet.frame(t0 + 10s + 400ms);
  CHECK_FALSE(quiet.expired(t0 + 10s + 899ms));
  CHECK(quiet.expired(t0 + 10s + 900ms));
  // Seeing "done" again (each pass of the loop) does not move the deadline.
  quiet.sending_done(t0 + 10s + 800ms);
  CHECK(quiet.expired(t0 + 10s + 900ms));
  // No frame at all after sending: lost frames end the wait at 500 ms, not never.
  QuietDeadline lost(500ms);
  lost.sending_done(t0);
  CHECK(lost.expired(t0 + 500ms));
}
