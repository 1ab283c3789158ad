// The `fabrik replay|watch|synth` cores: synthetic trials with gaps, replay onto a SUB socket
// (inproc and tcp, JSON and MessagePack), --drop parsing, and the watch decoder and tally.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <thread>
#include <zmq_addon.hpp>

#include "config/daemon_config.hpp"
#include "eval/eval.hpp"
#include "io/marker_trial.hpp"
#include "io/opensim_table.hpp"
#include "mot_steps.hpp"
#include "offline/marker_match.hpp"
#include "offline/solve_trial.hpp"
#include "process.hpp"
#include "run_fabrik.hpp"
#include "temp_file.hpp"
#include "tools/distinct_files.hpp"
#include "tools/replay.hpp"
#include "tools/sim.hpp"
#include "tools/synth.hpp"
#include "tools/watch.hpp"
#include "tools/wire.hpp"
#include "trc_text.hpp"

namespace fs = std::filesystem;
using fabrik::io::MarkerTrial;
using nlohmann::json;
using namespace fabrik::tools;

namespace {

const std::string kSourceDir = FABRIK_SOURCE_DIR;

using fabrik::test::TempFile;

// 3 markers x 50 frames at 100 Hz; marker B missing in frames 10-14.
MarkerTrial small_trial() {
  MarkerTrial t;
  t.labels = {"A", "B", "Subj:C"};
  t.rate_hz = 100.0;
  t.first_frame = 1;
  for (int f = 0; f < 50; ++f)
    for (int m = 0; m < 3; ++m) t.positions_m.emplace_back(0.001 * f, 1.0 + m, -0.5);
  for (int f = 10; f < 15; ++f) t.at(f, 1).setConstant(std::numeric_limits<double>::quiet_NaN());
  return t;
}

// Runs the replay on its own thread while this one receives: a bound SUB socket only
// handles a new connection (and sends its subscription) when its own thread calls into it.
class ReplayThread {
 public:
  ReplayThread(zmq::context_t& context, const MarkerTrial& trial, const ReplayOptions& options)
      : thread_([&context, &trial, options, this] {
          try {
            summary_ = replay_trial(context, trial, options);
          } catch (...) {
            error_ = std::current_exception();
          }
        }) {}
  ReplaySummary join() {
    thread_.join();
    if (error_) std::rethrow_exception(error_);
    return summary_;
  }

 private:
  ReplaySummary summary_;
  std::exception_ptr error_;
  std::thread thread_;
};

// Receives `count` messages, then checks that nothing else is queued.
std::vector<std::pair<std::string, json>> receive(zmq::socket_t& sub, std::size_t count) {
  std::vector<std::pair<std::string, json>> out;
  while (out.size() < count) {
    std::vector<zmq::message_t> parts;
    zmq::pollitem_t item{sub.handle(), 0, ZMQ_POLLIN, 0};
    REQUIRE(zmq::poll(&item, 1, std::chrono::milliseconds(5000)) == 1);
    REQUIRE(zmq::recv_multipart(sub, std::back_inserter(parts)));
    REQUIRE(parts.size() == 2);
    REQUIRE(parts[0].to_string() == "markers");
    out.emplace_back(std::string(parts[1].to_string_view()),
                     decode_payload(parts[1].to_string_view()));
  }
  return out;
}

ReplayOptions fast_options(const std::string& endpoint) {
  ReplayOptions o;
  o.endpoint = endpoint;
  o.speed = 0.0;               // as fast as possible: the test checks content, not pacing
  o.wait_subscriber_s = 10.0;  // the subscription is the synchronisation, not a sleep
  return o;
}

}  // namespace

TEST_CASE("synth writes a readable TRC with the requested gaps and a joints sidecar") {
  const SynthSetup setup = load_synth_setup(kSourceDir + "/config/default.json");
  REQUIRE(setup.marker_names.size() == 45);
  SynthOptions o;
  o.seconds = 3.0;
  o.rate_hz = 100.0;
  o.noise_mm = 0.5;
  o.gaps = 7;
  o.seed = 3;
  const SynthTrial t = make_synth_trial(setup, o);
  REQUIRE(t.gaps.size() == 7);

  TempFile file(".trc");
  file.also_remove(joints_sidecar_path(file.path()));
  fabrik::io::write_trc(file.path(), t.markers, "mm");
  fabrik::io::write_trc(joints_sidecar_path(file.path()), t.joints, "mm");
  const MarkerTrial back = fabrik::io::read_trc(file.path());
  REQUIRE(back.frames() == 300);
  REQUIRE(back.labels == setup.marker_names);
  CHECK(back.rate_hz == 100.0);

  // Each gap is one run of missing samples of 0.2-1 s; nothing else is missing.
  int runs = 0;
  std::size_t missing = 0;
  for (std::size_t m = 0; m < back.markers(); ++m) {
    int run = 0;
    for (std::size_t f = 0; f <= back.frames(); ++f) {
      const bool gap = f < back.frames() && !back.at(f, m).allFinite();
      if (gap) {
        ++run;
        ++missing;
      } else if (run > 0) {
        ++runs;
        CHECK(run >= 20);
        CHECK(run <= 100);
        run = 0;
      }
    }
  }
  CHECK(runs == 7);
  std::size_t expected = 0;
  for (const GapWindow& g : t.gaps) expected += static_cast<std::size_t>(g.frames);
  CHECK(missing == expected);

  const MarkerTrial joints = fabrik::io::read_trc(joints_sidecar_path(file.path()));
  CHECK(joints.frames() == 300);
  CHECK(joints.markers() == 15);
  for (const auto& p : joints.positions_m) CHECK(p.allFinite());
  CHECK(joints_sidecar_path("a/walk.TRC") == "a/walk.joints.trc");
  CHECK(joints_sidecar_path("walk") == "walk.joints.trc");
  CHECK(sidecar_stem("a/walk.TRC") == "a/walk");  // .truth.mot and .injected.csv beside it
  CHECK(sidecar_stem("walk") == "walk");
}

TEST_CASE("synth refuses gaps that cannot fit") {
  const SynthSetup setup = load_synth_setup(kSourceDir + "/config/default.json");
  SynthOptions o;
  o.seconds = 0.3;
  o.gaps = 1000;
  CHECK_THROWS_AS(make_synth_trial(setup, o), std::invalid_argument);
}

TEST_CASE("replay over inproc: every frame, numbered, in mm, nulls for missing and dropped") {
  zmq::context_t context;
  zmq::socket_t sub(context, zmq::socket_type::sub);
  sub.set(zmq::sockopt::rcvhwm, 0);
  sub.set(zmq::sockopt::subscribe, "markers");
  sub.bind("inproc://replay-json");

  const MarkerTrial trial = small_trial();
  ReplayOptions o = fast_options("inproc://replay-json");
  o.drops = {parse_drop_spec("Subj:C:0.2:0.3")};
  ReplayThread replay(context, trial, o);
  const auto msgs = receive(sub, 50);
  const ReplaySummary s = replay.join();
  CHECK(s.frames_sent == 50);
  CHECK(s.markers_nulled == 5 + 10);
  CHECK(s.markers_missing == 5);
  CHECK(s.markers_dropped == 10);
  zmq::message_t extra;
  CHECK_FALSE(sub.recv(extra, zmq::recv_flags::dontwait));

  for (std::size_t k = 0; k < msgs.size(); ++k) {
    const auto& [raw, doc] = msgs[k];
    INFO("frame index " << k);
    CHECK(raw.front() == '{');
    CHECK(doc["frame"] == k + 1);
    CHECK(doc["time"].get<double>() == Approx(static_cast<double>(k) / 100.0));
    CHECK(doc["units"] == "mm");
    CHECK(doc["markers"]["A"][0].get<double>() == Approx(static_cast<double>(k)).margin(1e-9));
    CHECK(doc["markers"]["A"][1].get<double>() == Approx(1000.0));
    CHECK(doc["markers"]["B"].is_null() == (k >= 10 && k < 15));
    CHECK(doc["markers"]["Subj:C"].is_null() == (k >= 20 && k < 30));
  }
}

TEST_CASE("replay over tcp in MessagePack, looping with --frames") {
  zmq::context_t context;
  zmq::socket_t sub(context, zmq::socket_type::sub);
  sub.set(zmq::sockopt::rcvhwm, 0);
  sub.set(zmq::sockopt::subscribe, "markers");
  sub.bind("tcp://127.0.0.1:*");  // a free port per test
  const std::string endpoint = sub.get(zmq::sockopt::last_endpoint);

  const MarkerTrial trial = small_trial();
  ReplayOptions o = fast_options(endpoint);
  o.encoding = WireEncoding::msgpack;
  o.loop = true;
  o.max_frames = 120;
  ReplayThread replay(context, trial, o);
  const auto msgs = receive(sub, 120);
  const ReplaySummary s = replay.join();
  CHECK(s.frames_sent == 120);
  CHECK(s.loops == 2);

  for (std::size_t k = 0; k < msgs.size(); ++k) {
    const auto& [raw, doc] = msgs[k];
    INFO("frame index " << k);
    CHECK(detect_encoding(raw) == WireEncoding::msgpack);
    CHECK(doc["frame"] == k + 1);  // numbers keep increasing across passes
    CHECK(doc["time"].get<double>() == Approx(static_cast<double>(k) / 100.0));
    CHECK(doc["markers"]["B"].is_null() == (k % 50 >= 10 && k % 50 < 15));
  }
}

TEST_CASE("fabrik sim: a trial becomes the servers' recording in mm, its script in frames") {
  MarkerTrial t;
  t.labels = {"RASI", "LASI"};
  t.rate_hz = 50.0;
  t.source.format = "TRC";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  t.positions_m = {{1.0, 2.0, 3.0}, {nan, nan, nan}, {0.5, 0.25, -1.0}, {0.001, 0, 0}};
  fabrik::bridges::SimRecording r = fabrik::tools::sim_recording(t, "");
  CHECK(r.up == "+y");  // OpenSim's TRC
  CHECK(r.rate_hz == 50.0);
  REQUIRE(r.p_mm.size() == 2);
  CHECK(r.p_mm[0][0] == Eigen::Vector3d(1000, 2000, 3000));
  CHECK(r.p_mm[0][1].array().isNaN().all());
  CHECK(r.p_mm[1][1] == Eigen::Vector3d(1, 0, 0));
  t.source.format = "C3D";
  CHECK(fabrik::tools::sim_recording(t, "").up == "+z");
  CHECK(fabrik::tools::sim_recording(t, "-x").up == "-x");

  fabrik::tools::SimScriptArgs a;
  a.pauses = {"1:0.5"};
  a.drops = {"LASI:0.1:0.3"};
  a.renames = {"2:RASI=R_ASIS"};
  a.restarts = {"0.5:2"};
  const fabrik::bridges::SimScript s = fabrik::tools::sim_script(a, r);
  REQUIRE(s.pauses.size() == 1);
  CHECK(s.pauses[0].at_frame == 50);
  CHECK(s.pauses[0].seconds == 0.5);
  REQUIRE(s.drops.size() == 1);
  CHECK(s.drops[0].marker == "LASI");
  CHECK(s.drops[0].from_frame == 5);
  CHECK(s.drops[0].to_frame == 15);
  REQUIRE(s.renames.size() == 1);
  CHECK(s.renames[0].at_frame == 100);
  CHECK(s.renames[0].from == "RASI");
  CHECK(s.renames[0].to == "R_ASIS");
  REQUIRE(s.restarts.size() == 1);
  CHECK(s.restarts[0].at_frame == 25);
  CHECK(s.restarts[0].down_seconds == 2.0);

  // The error of a script with one spec in the list `field` of SimScriptArgs.
  using Field = std::vector<std::string> fabrik::tools::SimScriptArgs::*;
  const auto error = [&](Field field, const std::string& spec) -> std::string {
    fabrik::tools::SimScriptArgs bad;
    (bad.*field).push_back(spec);
    try {
      (void)fabrik::tools::sim_script(bad, r);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::pauses, "1"), Catch::Contains("--pause-at '1': expected T:S"));
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::pauses, "x:1"), Catch::Contains("T 'x' is not a time in seconds"));
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::restarts, "1:-2"), Catch::Contains("S '-2' is not a time in seconds"));
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::renames, "1:RASI"), Catch::Contains("expected T:OLD=NEW"));
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::renames, "1:NOPE=X"), Catch::Contains("the recording has no marker 'NOPE'"));
  CHECK_THAT(error(&fabrik::tools::SimScriptArgs::drops, "NOPE:0:1"), Catch::Contains("the recording has no marker 'NOPE'"));
  MarkerTrial empty;
  CHECK_THROWS_WITH(fabrik::tools::sim_recording(empty, ""), Catch::Contains("no marker frames"));
}

TEST_CASE("replay rejects a drop of a marker that is not in the recording") {
  zmq::context_t context;
  ReplayOptions o = fast_options("inproc://nobody");
  o.drops = {parse_drop_spec("RASI:0:1")};
  CHECK_THROWS_WITH(replay_trial(context, small_trial(), o),
                    Catch::Contains("'RASI' is not in the recording"));
}

TEST_CASE("replay: a stop request ends the wait for a frame due far ahead, not at its deadline") {
  zmq::context_t context;
  ReplayOptions o = fast_options("inproc://nobody-slow");
  o.bind = true;
  o.wait_subscriber_s = -1.0;  // no subscriber: frames go nowhere, the pacing is what is tested
  o.speed = 1.0 / 3000.0;      // 100 Hz: the second frame is due 30 s after the first
  const auto start = std::chrono::steady_clock::now();
  o.stop_requested = [&] {
    return std::chrono::steady_clock::now() - start > std::chrono::milliseconds(200);
  };
  const ReplaySummary summary = replay_trial(context, small_trial(), o);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  CHECK(summary.stopped);
  CHECK(summary.frames_sent == 1);
  CHECK(took_s < 5.0);  // it waited out the 30 s before
}

TEST_CASE(
    "replay --bind that cannot bind names the option and the endpoint (watch opens its socket the "
    "same way)") {
  zmq::context_t context;
  zmq::socket_t holder(context, zmq::socket_type::pub);
  holder.set(zmq::sockopt::linger, 0);
  holder.bind("tcp://127.0.0.1:*");
  const std::string taken = holder.get(zmq::sockopt::last_endpoint);
  ReplayOptions o = fast_options(taken);
  o.bind = true;
  int opened = 0;  // the start line is printed from here: never for a socket not open
  o.opened = [&] { ++opened; };
  CHECK_THROWS_WITH(replay_trial(context, small_trial(), o),
                    Catch::StartsWith("--to: cannot bind to '" + taken + "'") &&
                        Catch::Contains("leave out --bind"));
  CHECK(opened == 0);
  o.endpoint = "tcp://127.0.0.1:*";
  o.wait_subscriber_s = -1.0;  // no one listens: sent to nobody
  (void)replay_trial(context, small_trial(), o);
  CHECK(opened == 1);
}

TEST_CASE("drop specs parse NAME T0 T1, names may contain colons, bad ones say why") {
  const DropSpec d = parse_drop_spec("RASI:0.5:1.25");
  CHECK(d.marker == "RASI");
  CHECK(d.t0_s == 0.5);
  CHECK(d.t1_s == 1.25);
  CHECK(parse_drop_spec("Subject:RASI:0:2").marker == "Subject:RASI");

  CHECK_THROWS_WITH(parse_drop_spec("RASI"), Catch::Contains("'RASI': expected NAME:T0:T1"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:1"), Catch::Contains("expected NAME:T0:T1"));
  CHECK_THROWS_WITH(parse_drop_spec(":0:1"), Catch::Contains("marker name is empty"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:a:1"), Catch::Contains("T0 'a' is not a time"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:0:1s"), Catch::Contains("T1 '1s' is not a time"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:-1:1"), Catch::Contains("T0 '-1'"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:0:nan"), Catch::Contains("T1 'nan'"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:2:1"), Catch::Contains("T1 must be greater than T0"));
  CHECK_THROWS_WITH(parse_drop_spec("RASI:1:1"), Catch::Contains("T1 must be greater than T0"));
}

TEST_CASE("watch decodes JSON and MessagePack payloads by their first byte") {
  const json pose = {{"frame", 7},
                     {"units", "mm"},
                     {"occluded", {"LASI"}},
                     {"residual", {{"rms", 1.5}, {"max", 3.0}, {"worst", "RASI"}, {"count", 44}}},
                     {"solver", {{"status", "converged"}, {"iterations", 3}, {"solve_us", 9.0}}}};
  CHECK(decode_payload(encode_payload(pose, WireEncoding::json)) == pose);
  CHECK(decode_payload(encode_payload(pose, WireEncoding::msgpack)) == pose);
  CHECK(decode_payload(" \n" + pose.dump()) == pose);
  CHECK(detect_encoding(encode_payload(pose, WireEncoding::msgpack)) == WireEncoding::msgpack);

  CHECK_THROWS_WITH(decode_payload(""), Catch::Contains("empty"));
  CHECK_THROWS_WITH(decode_payload("[1, 2]"), Catch::Contains("neither"));
  CHECK_THROWS_WITH(decode_payload(std::string("\xc1\x01\x02", 3)), Catch::Contains("0xc1"));
  CHECK_THROWS_WITH(decode_payload("{\"frame\": "), Catch::Contains("bad json"));
  std::string truncated = encode_payload(pose, WireEncoding::msgpack);
  truncated.resize(truncated.size() / 2);
  CHECK_THROWS_WITH(decode_payload(truncated), Catch::Contains("bad msgpack"));
}

TEST_CASE("watch --topic tallies the poses of its topic only, not of topics it starts") {
  zmq::context_t context;
  zmq::socket_t pub(context, zmq::socket_type::pub);
  pub.set(zmq::sockopt::linger, 0);
  pub.bind("inproc://watch-topic");
  WatchOptions o;
  o.endpoint = "inproc://watch-topic";
  o.topic = "joints";
  o.seconds = 20.0;  // a bound: it stops at 20 poses long before
  WatchTally tally;
  o.stop_requested = [&] { return tally.poses() >= 20; };
  std::atomic<bool> done{false};
  std::thread publisher([&] {
    // Until the subscription has propagated, PUB drops: publish until the watch has enough.
    for (std::uint64_t f = 1; !done && f < 10000000; ++f) {
      const std::pair<const char*, std::uint64_t> messages[] = {
          {"pose", f}, {"joints", 100000000 + f}, {"joints.mp", 200000000 + f}};
      for (const auto& [topic, frame] : messages) {
        const std::string pose = json{{"frame", frame},
                                      {"units", "mm"},
                                      {"occluded", json::array()},
                                      {"residual", {{"rms", 1.0}, {"max", 2.0}, {"count", 3}}},
                                      {"solver", {{"status", "converged"}, {"solve_us", 5.0}}}}
                                     .dump();
        pub.send(zmq::buffer(std::string_view(topic)), zmq::send_flags::sndmore);
        pub.send(zmq::buffer(pose));
      }
      std::this_thread::yield();
    }
  });
  const json s = watch(context, o, tally);
  done = true;
  publisher.join();
  CHECK(tally.poses() >= 20);
  CHECK(s["first_frame"].get<std::uint64_t>() > 100000000);
  CHECK(s["last_frame"].get<std::uint64_t>() < 200000000);
}

TEST_CASE("watch on pose names the subjects' topics of a multi-subject daemon and the fix") {
  zmq::context_t context;
  zmq::socket_t pub(context, zmq::socket_type::pub);
  pub.bind("inproc://watch-subjects");
  WatchOptions o;
  o.endpoint = "inproc://watch-subjects";
  o.seconds = 20.0;  // a bound: it stops at 5 of each long before
  WatchTally tally;
  o.stop_requested = [&] {
    const json others = tally.summary()["other_topics"];
    return others.value("pose/Alice", 0) >= 5 && others.value("pose/Bob", 0) >= 5;
  };
  std::atomic<bool> done{false};
  std::thread publisher([&] {
    for (std::uint64_t f = 1; !done && f < 10000000; ++f) {
      for (const char* topic : {"pose/Alice", "pose/Bob", "posex"}) {
        const std::string pose = json{{"frame", f}, {"units", "mm"}}.dump();
        pub.send(zmq::buffer(std::string_view(topic)), zmq::send_flags::sndmore);
        pub.send(zmq::buffer(pose));
      }
      std::this_thread::yield();
    }
  });
  const json s = watch(context, o, tally);
  done = true;
  publisher.join();
  CHECK(tally.poses() == 0);
  CHECK(s["other_topics"].size() == 2);  // not "posex": another topic, not a subject's
  CHECK_THAT(tally.summary_text(), Catch::Contains("poses arrived on pose/Alice (") &&
                                       Catch::Contains("pose/Bob (") &&
                                       Catch::Contains("Fix: --topic pose/Alice"));
}

TEST_CASE("watch's summary names the solver's stop beside the contract's status") {
  WatchTally tally;
  for (std::uint64_t f = 1; f <= 3; ++f)
    tally.add_pose(
        json{{"frame", f},
             {"units", "mm"},
             {"residual", {{"rms", 1.0}, {"max", 2.0}, {"count", 3}}},
             {"solver", {{"status", "converged"}, {"stop", f == 3 ? "converged" : "stalled"}}}},
        0.01 * static_cast<double>(f));
  CHECK_THAT(tally.summary_text(),
             Catch::EndsWith("status: converged 3 (solver stop: converged 1 stalled 2)\n"));
  CHECK(tally.summary()["stop"]["stalled"] == 2);
  // A peer's words: at most 32 kept, a line break shown escaped, not as a new line.
  for (std::uint64_t k = 0; k < 40; ++k)
    tally.add_pose(
        json{{"frame", 10 + k},
             {"solver",
              {{"status", "s" + std::to_string(k)}, {"stop", "x\ny" + std::to_string(k)}}}},
        1.0 + static_cast<double>(k));
  CHECK(tally.summary()["stop"].size() == 32);
  CHECK(tally.summary()["status"].size() == 32);
  CHECK_THAT(tally.summary_text(), !Catch::Contains("x\ny"));
}

TEST_CASE("watch tally: a vendor source's connection shows in the live line, its error when it is down") {
  WatchTally tally;
  CHECK_THAT(tally.live_line(0.0), !Catch::Contains("source"));
  json source = {{"url", "qtm://lab"}, {"connected", true}, {"server", "QTM RT protocol 1.19"},
                 {"connections", 2}, {"reconnects", 1}, {"errors", 3}, {"bad_packets", 0},
                 {"frames", 1234}, {"frames_dropped", 0}, {"last_error", "QTM at lab: gone"}};
  tally.add_stats(json{{"decode_errors", 0}, {"source", source}}, 0.1);
  std::string line = tally.live_line(0.1);
  CHECK_THAT(line, Catch::Contains("source connected (1234 frames, 1 reconnects, 3 errors)"));
  CHECK_THAT(line, !Catch::Contains("gone"));
  source["connected"] = false;
  source["bad_packets"] = 2;
  tally.add_stats(json{{"decode_errors", 0}, {"source", source}}, 0.2);
  line = tally.live_line(0.2);
  CHECK_THAT(line, Catch::Contains("source NOT connected (1234 frames, 1 reconnects, 3 errors, 2 bad packets): "
                                   "QTM at lab: gone"));
}

TEST_CASE("watch's summary without a pose says so, with one gives frames and units") {
  WatchTally tally;
  const std::string none = tally.summary_text();
  CHECK_THAT(none, Catch::StartsWith("poses 0: no pose received"));
  CHECK(none.find("null") == std::string::npos);  // once "frames null..null", "max 0.000 ;"
  tally.add_pose(json{{"frame", std::uint64_t{7}},
                      {"units", "mm"},
                      {"occluded", json::array()},
                      {"residual", {{"rms", 1.0}, {"max", 2.0}, {"worst", "A"}, {"count", 3}}},
                      {"solver", {{"status", "converged"}, {"iterations", 2}, {"solve_us", 9.0}}}},
                 0.01);
  const std::string one = tally.summary_text();
  CHECK_THAT(one, Catch::Contains("poses 1 (frames 7..7)") && Catch::Contains("max 2.000 mm;"));
}

TEST_CASE("watch tally: gaps in frame numbers are loss, restarts are not") {
  WatchTally tally;
  const auto pose = [](std::uint64_t frame, double rms, const char* status) {
    return json{{"frame", frame},
                {"units", "mm"},
                {"occluded", json::array({"A", "B"})},
                {"residual", {{"rms", rms}, {"max", 2 * rms}, {"worst", "A"}, {"count", 3}}},
                {"solver", {{"status", status}, {"iterations", 2}, {"solve_us", 10.0 * rms}}}};
  };
  double t = 0.0;
  for (std::uint64_t f : {1, 2, 3, 6, 7, 10, 2, 3})  // 2 gaps (4 frames), then a restart
    tally.add_pose(pose(f, f == 7 ? 4.0 : 1.0, f == 10 ? "max_iterations" : "converged"),
                   t += 0.01);
  tally.add_pose(json{{"frame", "x"}}, t);
  tally.add_stats(json{{"decode_errors", 2}}, t);
  const std::string line = tally.live_line(t);
  CHECK_THAT(line, Catch::Contains("max_iterations 1"));
  CHECK_THAT(line, Catch::Contains("lost 4"));

  const json s = tally.summary();
  CHECK(s["poses"] == 8);
  CHECK(s["malformed"] == 1);
  CHECK(s["missing_frames"] == 4);
  CHECK(s["gap_events"] == 2);
  CHECK(s["restarts"] == 1);
  CHECK(s["loss_ratio"].get<double>() == Approx(4.0 / 12.0));
  CHECK(s["residual"]["max"].get<double>() == 8.0);
  CHECK(s["residual"]["rms_mean"].get<double>() == Approx(11.0 / 8.0));
  CHECK(s["occluded_mean"].get<double>() == 2.0);
  CHECK(s["status"]["converged"] == 7);
  CHECK(s["solve_us"]["max"].get<double>() == 40.0);
  CHECK(s["solve_us"]["p50"].get<double>() == 10.0);
  CHECK(s["last_stats"]["decode_errors"] == 2);
}

TEST_CASE("watch tally: a pose without a measured marker has no residual, not a perfect one") {
  WatchTally tally;
  const auto pose = [](std::uint64_t frame, int count, double rms) {
    return json{{"frame", frame},
                {"units", "mm"},
                {"occluded", json::array()},
                {"residual", {{"rms", rms}, {"max", rms}, {"worst", nullptr}, {"count", count}}},
                {"solver", {{"status", "converged"}, {"iterations", 1}, {"solve_us", 5.0}}}};
  };
  // No pose at all (the daemon idle): said so, not "no marker measured".
  CHECK_THAT(WatchTally{}.live_line(0.5), Catch::Contains("rms none (no pose this interval)"));
  // An IMU-only stream: every pose's count is 0 (its rms 0).
  tally.add_pose(pose(1, 0, 0.0), 0.01);
  tally.add_pose(pose(2, 0, 0.0), 0.02);
  CHECK_THAT(tally.live_line(0.03), Catch::Contains("rms none (no marker measured)"));
  json s = tally.summary();
  CHECK(s["residual"]["rms_mean"].is_null());
  CHECK(s["residual"]["poses"] == 0);
  CHECK_THAT(tally.summary_text(), Catch::Contains("residual none: no pose had a measured marker"));
  // Markers come: the mean is theirs alone, not diluted by the poses before.
  tally.add_pose(pose(3, 4, 3.0), 0.04);
  CHECK_THAT(tally.live_line(0.05), Catch::Contains("rms 3.000 max 3.000 mm"));
  s = tally.summary();
  CHECK(s["residual"]["rms_mean"].get<double>() == 3.0);
  CHECK(s["residual"]["poses"] == 1);
}

// ---- Recordings from other labs: zeros, files without markers, configs that fit nothing ----

namespace {

const std::string kDataDir = kSourceDir + "/../shared/data";

using fabrik::test::run_fabrik;
using fabrik::test::slurp;

// 2 s at 100 Hz of the default config's model moving, no noise, no gaps.
MarkerTrial default_model_trial() {
  const SynthSetup setup = load_synth_setup(kSourceDir + "/config/default.json");
  SynthOptions o;
  o.seconds = 2.0;
  o.noise_mm = 0.0;
  return make_synth_trial(setup, o).markers;
}

}  // namespace

TEST_CASE("replay sends a recording's exact (0, 0, 0) samples as null and counts them") {
  MarkerTrial trial = small_trial();
  for (int f = 0; f < 50; ++f) trial.at(f, 2).setZero();  // Subj:C "not seen" throughout
  TempFile file(".trc");
  fabrik::io::write_trc(file.path(), trial);
  const MarkerTrial read = fabrik::io::read_trial(file.path());

  zmq::context_t context;
  zmq::socket_t sub(context, zmq::socket_type::sub);
  sub.set(zmq::sockopt::rcvhwm, 0);
  sub.set(zmq::sockopt::subscribe, "markers");
  sub.bind("inproc://replay-zeros");
  ReplayThread replay(context, read, fast_options("inproc://replay-zeros"));
  const auto msgs = receive(sub, 50);
  const ReplaySummary s = replay.join();
  CHECK(s.markers_nulled == 5 + 50);
  CHECK(s.markers_missing == 5 + 50);
  CHECK(s.markers_dropped == 0);
  for (const auto& [raw, doc] : msgs) CHECK(doc["markers"]["Subj:C"].is_null());
}

TEST_CASE("solve summary leaves frames without markers out of the residual and counts them") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  MarkerTrial trial = default_model_trial();
  REQUIRE(trial.frames() == 200);
  for (std::size_t f = 50; f < 80; ++f)  // 30 frames where nothing is seen
    for (std::size_t m = 0; m < trial.markers(); ++m)
      trial.at(f, m).setConstant(std::numeric_limits<double>::quiet_NaN());
  const int lasi = trial.find("LASI"), rasi = trial.find("RASI");
  REQUIRE(lasi >= 0);
  REQUIRE(rasi >= 0);
  for (std::size_t f = 0; f < 200; ++f) trial.at(f, std::size_t(lasi)).setConstant(NAN);
  for (std::size_t f = 0; f < 120; ++f) trial.at(f, std::size_t(rasi)).setConstant(NAN);

  const fabrik::TrialSolution s = fabrik::solve_trial(config, trial);
  const json summary = fabrik::solution_summary(s);
  CHECK(summary["frames"] == 200);
  CHECK(summary["frames_without_markers"] == 30);
  double sum_m = 0.0, all_m = 0.0;
  for (std::size_t f = 0; f < 200; ++f) {
    all_m += s.rms_m[f];
    if (f < 50 || f >= 80) sum_m += s.rms_m[f];
  }
  CHECK(s.measured[60] == 0);
  CHECK(s.measured[10] == 43);
  CHECK(summary["residual_mm"]["rms_mean"].get<double>() == Approx(sum_m / 170 * 1e3));
  CHECK(sum_m / 170 > all_m / 200);  // the 0 mm of unseen frames no longer dilute it

  // Tracked markers missing in most of the trial, and one never seen.
  CHECK(summary["markers_missing_in_trial"] == json::array({"LASI"}));
  const json mostly = summary["markers_mostly_missing"];
  REQUIRE(mostly.size() == 2);
  CHECK(mostly[0]["marker"] == "LASI");
  CHECK(mostly[0]["missing_frames"] == 200);
  CHECK(mostly[1]["marker"] == "RASI");
  CHECK(mostly[1]["missing_frames"] == 120 + 0);  // frames 50-79 lie inside the first 120
}

TEST_CASE(
    "fabrik solve --report carries the file readers' warnings, for a batch that reads no stderr") {
  MarkerTrial trial = default_model_trial();
  REQUIRE(trial.rate_hz == 100.0);
  TempFile file(".trc"), joints(".trc"), report(".json");
  fabrik::io::write_trc(file.path(), trial);
  std::string text = slurp(file.path());
  const std::string rates = "\n100\t100\t";  // DataRate and CameraRate: the Time column's 100 Hz
  REQUIRE(text.find(rates) != std::string::npos);
  text.replace(text.find(rates), rates.size(), "\n50\t50\t");
  std::ofstream(file.path()) << text;
  const auto [code, err] = run_fabrik({"solve", "--input", file.path(), "--output", joints.path(),
                                       "--report", report.path(), "--quiet"});
  CAPTURE(err);
  REQUIRE(code == 0);
  const json r = json::parse(slurp(report.path()));
  REQUIRE(r["warnings"].size() == 1);
  CHECK_THAT(r["warnings"][0].get<std::string>(),
             Catch::StartsWith(file.path() + ": the Time column runs at 100 Hz") &&
                 Catch::Contains("DataRate says 50 Hz"));
}

TEST_CASE("fabrik solve warns of a --filter-hz below one cycle over the trial") {
  TempFile file(".trc"), joints(".trc");
  fabrik::io::write_trc(file.path(), default_model_trial());  // 2 s
  const auto warning_of = [&](const std::string& cutoff_hz) {
    const auto [code, err] = run_fabrik({"solve", "--input", file.path(), "--output", joints.path(),
                                         "--filter-hz", cutoff_hz, "--quiet"});
    CAPTURE(err);
    CHECK(code == 0);
    return err.find("is below one cycle over the trial's 2 s") != std::string::npos;
  };
  CHECK(warning_of("0.3"));  // 0.6 of a cycle in 2 s
  CHECK_FALSE(warning_of("6"));
}

TEST_CASE(
    "Frames before the first measurement have no pose: missing in the outputs, not in the .mot") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  MarkerTrial trial = default_model_trial();
  for (std::size_t f = 0; f < 5; ++f)  // nothing seen in the first 5 frames
    for (std::size_t m = 0; m < trial.markers(); ++m)
      trial.at(f, m).setConstant(std::numeric_limits<double>::quiet_NaN());
  for (std::size_t f = 60; f < 65; ++f)  // nor in 5 later ones
    for (std::size_t m = 0; m < trial.markers(); ++m)
      trial.at(f, m).setConstant(std::numeric_limits<double>::quiet_NaN());
  const fabrik::TrialSolution s = fabrik::solve_trial(config, trial);
  CHECK(s.first_measured == 5);
  const std::size_t joints = s.joints.labels.size(), coords = s.coordinate_names.size();
  for (std::size_t f = 0; f < 7; ++f) {
    CAPTURE(f);
    CHECK(s.joints.at(f, 0).allFinite() == (f >= 5));
    CHECK(s.model_markers.at(f, 0).allFinite() == (f >= 5));
    CHECK(std::isfinite(s.coordinates[f * coords]) == (f >= 5));
  }
  // A later frame without markers is solved on the markers filled from both sides: it moves
  // on between the frames around it (it repeated the pose before it).
  CHECK(s.solved_on_filled_markers);
  CHECK(s.joints.at(62, joints - 1).allFinite());
  CHECK_FALSE(s.joints.at(62, joints - 1).isApprox(s.joints.at(59, joints - 1)));
  const fabrik::io::OpenSimTable mot = fabrik::angles_table(s);
  CHECK(mot.rows == trial.frames() - 5);
  CHECK(mot.time_s.front() == Approx(trial.file_time_s(5)));
  CHECK(fabrik::solution_summary(s)["frames_before_first_measurement"] == 5);
}

TEST_CASE(
    "sim natnet and sim qtm bound to every interface name HOST and the client's options "
    "in their fabrikd hint") {
  // They said "natnet://0.0.0.0:PORT", which no client can connect to, and left out the
  // data port a client needs when it is not NatNet's 1511.
  TempFile trial(".trc");
  fabrik::io::write_trc(trial.path(), default_model_trial());
  const auto [code, err] =
      run_fabrik({"sim", "natnet", trial.path(), "--bind", "0.0.0.0", "--command-port", "0",
                  "--data-port", "0", "--rate-scale", "100"});
  CAPTURE(err);
  CHECK(code == 0);
  CHECK_THAT(err, Catch::Contains("(fabrikd: \"natnet://HOST:") &&
                      Catch::Contains(" with \"data_port\": ") &&
                      Catch::Contains(", HOST: this machine's address)"));
  const auto [qtm_code, qtm_err] = run_fabrik(
      {"sim", "qtm", trial.path(), "--bind", "0.0.0.0", "--base-port", "0", "--rate-scale", "100"});
  CAPTURE(qtm_err);
  CHECK(qtm_code == 0);
  CHECK_THAT(qtm_err, Catch::Contains("fabrikd: \"qtm://HOST:"));
}

TEST_CASE("Frames after the last measurement have no pose either: missing, not in the .mot") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  MarkerTrial trial = default_model_trial();
  const std::size_t frames = trial.frames(), tail = 12;
  for (std::size_t f = frames - tail; f < frames; ++f)
    for (std::size_t m = 0; m < trial.markers(); ++m)
      trial.at(f, m).setConstant(std::numeric_limits<double>::quiet_NaN());
  const fabrik::TrialSolution s = fabrik::solve_trial(config, trial);
  CHECK(s.first_measured == 0);
  CHECK(s.end_measured == frames - tail);
  // They repeated the last pose for as long as the empty tail (a held pose, 12 rows).
  for (std::size_t f = frames - tail - 2; f < frames; ++f) {
    CAPTURE(f);
    CHECK(s.joints.at(f, 0).allFinite() == (f < frames - tail));
    CHECK(std::isfinite(s.coordinates[f * s.coordinate_names.size()]) == (f < frames - tail));
  }
  const fabrik::io::OpenSimTable mot = fabrik::angles_table(s);
  CHECK(mot.rows == frames - tail);
  CHECK(mot.time_s.back() == Approx(trial.file_time_s(frames - tail - 1)));
  CHECK(fabrik::solution_summary(s)["frames_after_last_measurement"] == tail);
  // A trial with no measurement at all has no pose anywhere and an empty .mot.
  MarkerTrial empty = default_model_trial();
  for (Eigen::Vector3d& p : empty.positions_m)
    p.setConstant(std::numeric_limits<double>::quiet_NaN());
  const fabrik::TrialSolution none = fabrik::solve_trial(config, empty);
  CHECK(none.first_measured == frames);
  CHECK(fabrik::angles_table(none).rows == 0);
  for (std::size_t f = 0; f < frames; ++f) CHECK_FALSE(none.joints.at(f, 0).allFinite());
}

TEST_CASE("An output to stdout gets stdout alone: the text summary goes to stderr") {
  // stdout redirected to a file, as `> out.json` does: the summary written there after the
  // output (opened anew at /dev/stdout) overwrote its start; a pipe got both, mixed.
  TempFile trc(".trc"), out(".json"), joints(".trc");
  fabrik::io::write_trc(trc.path(), default_model_trial(), "mm");
  {
    const auto [code, err] = run_fabrik({"solve", "--input", trc.path(), "--output", joints.path(),
                                         "--report", "/dev/stdout", "--quiet"},
                                        out.path());
    CAPTURE(err);
    REQUIRE(code == 0);
    CHECK(json::parse(slurp(out.path())).contains("residual_mm"));
    CHECK_THAT(err, Catch::Contains("marker residual   RMS "));
  }
  {
    const auto [code, err] = run_fabrik(
        {"eval", "synthetic", "--seconds", "0.5", "--noise-mm", "0", "--json", "/dev/stdout"},
        out.path());
    CAPTURE(err);
    REQUIRE(code == 0);
    CHECK(json::parse(slurp(out.path())).at(0).contains("joint_rms_mm"));
    CHECK_THAT(err, Catch::Contains("Joint centres vs the synthetic truth"));
  }
  // Without an output there, the summary stays on stdout.
  const auto [code, err] = run_fabrik(
      {"solve", "--input", trc.path(), "--output", joints.path(), "--quiet"}, out.path());
  REQUIRE(code == 0);
  CHECK_THAT(slurp(out.path()), Catch::Contains("marker residual   RMS "));
}

TEST_CASE("fabrik solve refuses a trial in which no tracked marker is measured, saying why") {
  TempFile file(".trc"), joints(".trc"), mot(".mot");
  MarkerTrial trial = default_model_trial();
  const auto message_of = [&](const MarkerTrial& t, const std::string& units) {
    fabrik::io::write_trc(file.path(), t, units);
    const auto [code, err] = run_fabrik({"solve", "--input", file.path(), "--output", joints.path(),
                                         "--angles", mot.path(), "--quiet"});
    CAPTURE(err);
    CHECK(code != 0);
    return err;
  };
  // A file in mm labelled m: most samples dropped as implausible, the solve made of the few
  // near the origin; with every one dropped it exited 0 with an empty .mot. Refused by its
  // span (calibrate too: it wrote thighs of 400 m).
  MarkerTrial far = trial;
  for (Eigen::Vector3d& p : far.positions_m) p *= 1e3;
  CHECK_THAT(message_of(far, "m"),
             Catch::Contains(".trc: the markers spread over ") &&
                 Catch::Contains("(more than 100 m, where a body spans about a metre)") &&
                 Catch::Contains("Fix: correct Units (line 3) (mm labelled m"));
  {
    fabrik::io::write_trc(file.path(), far, "m");
    TempFile config(".json");
    const auto [code, err] =
        run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/gait2354.json",
                    "--static", file.path(), "--output", config.path()});
    CAPTURE(err);
    CHECK(code != 0);
    CHECK_THAT(err, Catch::Contains("the markers spread over "));
  }
  // The other way: metres labelled mm (a solve reported 528 mm RMS and exited 0).
  MarkerTrial small = trial;
  for (Eigen::Vector3d& p : small.positions_m) p *= 1e-3;
  CHECK_THAT(message_of(small, "mm"), Catch::Contains(".trc: the markers spread over ") &&
                                          Catch::Contains("(less than 10 mm, where a body spans "
                                                          "about a metre)"));
  // Every sample beyond input.max_abs_coordinate_mm where no frame has 3 markers to span.
  MarkerTrial two = trial;
  for (std::size_t f = 0; f < two.frames(); ++f)
    for (std::size_t m = 0; m < two.markers(); ++m)
      two.at(f, m) = m < 2 ? Eigen::Vector3d(trial.at(f, m) * 1e3)
                           : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  CHECK_THAT(message_of(two, "m"),
             Catch::Contains(": no tracked marker is measured in any of the " +
                             std::to_string(trial.frames()) + " frames: ") &&
                 Catch::Contains("samples were farther than input.max_abs_coordinate_mm") &&
                 Catch::Contains("Fix: check the file's unit (it says 'm')"));
  MarkerTrial zeros = trial;
  for (Eigen::Vector3d& p : zeros.positions_m) p.setZero();
  CHECK_THAT(message_of(zeros, "mm"),
             Catch::Contains("samples are exactly (0, 0, 0), which is read as missing") &&
                 Catch::Contains("--keep-zeros"));
}

TEST_CASE("Offline the joint centres and angles in a gap are solved on the filled markers") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  const MarkerTrial full = default_model_trial();
  MarkerTrial gapped = full;
  // The right forearm's and hand's markers gone for 0.6 s, the right knee's for 0.4 s.
  std::vector<std::size_t> hidden;
  for (const char* name : {"RWRA", "RWRB", "RFIN", "RELB", "RKNE"}) {
    const int c = gapped.find(name);
    REQUIRE(c >= 0);
    hidden.push_back(static_cast<std::size_t>(c));
  }
  for (std::size_t f = 60; f < 120; ++f)
    for (std::size_t c : hidden)
      if (gapped.labels[c] != "RKNE" || f < 100) gapped.at(f, c).setConstant(NAN);
  const fabrik::TrialSolution truth = fabrik::solve_trial(config, full);
  const fabrik::TrialSolution s = fabrik::solve_trial(config, gapped);
  REQUIRE(s.solved_on_filled_markers);
  CHECK_FALSE(truth.solved_on_filled_markers);  // nothing to fill
  // Known answer: the joint centres are those of a solve of the filled markers as a trial.
  MarkerTrial filled = s.markers;
  const fabrik::TrialSolution again = fabrik::solve_trial(config, filled);
  CHECK_FALSE(again.solved_on_filled_markers);
  const std::size_t joints = s.joints.labels.size();
  double worst_m = 0.0;
  std::size_t finite_differs = 0;
  for (std::size_t f = 0; f < gapped.frames(); ++f)
    for (std::size_t j = 0; j < joints; ++j) {
      finite_differs += s.joints.at(f, j).allFinite() != again.joints.at(f, j).allFinite();
      if (s.joints.at(f, j).allFinite())
        worst_m = std::max(worst_m, (s.joints.at(f, j) - again.joints.at(f, j)).norm());
    }
  CHECK(finite_differs == 0);
  CHECK(worst_m < 1e-12);
  // The live pass keeps the causal joints: what fabrik view --trial draws and what an
  // evaluation of the live path measures.
  const fabrik::TrialSolution live =
      fabrik::solve_trial(config, gapped, {}, nullptr, {}, fabrik::TrialPass::live);
  CHECK_FALSE(live.solved_on_filled_markers);
  // And nearer the full trial's than the causal pass's, which held or predicted the arm and
  // lagged after the markers came back.
  fabrik::Tracker causal(config.tracker);
  std::vector<Eigen::Vector3d> measured(gapped.markers());
  std::vector<std::uint8_t> visible(gapped.markers());
  double causal_sq = 0.0, refit_sq = 0.0;
  std::size_t count = 0;
  for (std::size_t f = 0; f < gapped.frames(); ++f) {
    for (std::size_t i = 0; i < config.tracker.markers.size(); ++i) {
      measured[i] =
          gapped.at(f, static_cast<std::size_t>(gapped.find(config.tracker.markers[i].marker)));
      visible[i] = measured[i].allFinite() ? 1 : 0;
    }
    const fabrik::TrackResult& r = causal.track(gapped.time_s(f), measured, visible);
    if (f < 60 || f >= 130) continue;
    for (std::size_t j = 0; j < joints; ++j) {
      causal_sq += (r.joints_world_m[j] - truth.joints.at(f, j)).squaredNorm();
      refit_sq += (s.joints.at(f, j) - truth.joints.at(f, j)).squaredNorm();
      ++count;
    }
  }
  const double causal_mm = std::sqrt(causal_sq / count) * 1e3,
               refit_mm = std::sqrt(refit_sq / count) * 1e3;
  INFO("joint centres in and after the gaps, RMS from the full trial's: causal "
       << causal_mm << " mm, solved on the filled markers " << refit_mm << " mm");
  CHECK(refit_mm < 0.8 * causal_mm);
}

TEST_CASE("A trial that shares no marker name with the config is refused, with the closest") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  MarkerTrial trial = default_model_trial();
  for (std::string& l : trial.labels) {
    if (l == "RASI") l = "Subj:RASI";
    else if (l == "LASI") l = "lasi";
    else if (l == "RKNE") l = "R.KNE";
    else if (l == "LKNE") l = "L_KNEE";
    else l = "X" + l + "X" + l;
  }
  std::string message;
  try {
    fabrik::require_shared_markers(config, trial, "walk.trc", "--subject");
  } catch (const std::runtime_error& e) {
    message = e.what();
  }
  INFO(message);
  CHECK_THAT(message, Catch::StartsWith("walk.trc: shares none of the 45 marker names of the "
                                        "config <embedded>/default.json (45 labels in the file)"));
  CHECK_THAT(message, Catch::Contains("\n  config: LASI, LPSI, RASI,"));
  CHECK_THAT(message, Catch::Contains("\n  file:   lasi, "));
  CHECK_THAT(message, Catch::Contains("\n  closest: LASI ~ lasi (case), RASI ~ Subj:RASI (after "
                                      "'Subj:'), RKNE ~ R.KNE (punctuation), "));
  CHECK_THAT(message, Catch::Contains("LKNE ~ L_KNEE (1 edit)"));
  CHECK_THAT(message, Catch::Contains("\nFix: "));
  CHECK_THAT(message, Catch::Contains("; to track one subject of this file, give --subject Subj"));
  try {  // a caller without such an option (Python's solve) offers none
    fabrik::require_shared_markers(config, trial, "walk.trc");
  } catch (const std::runtime_error& e) {
    CHECK_THAT(e.what(), !Catch::Contains("to track one subject"));
  }
  // One shared name is enough.
  trial.labels[0] = config.tracker.markers[0].marker;
  CHECK_NOTHROW(fabrik::require_shared_markers(config, trial, "walk.trc"));
}

TEST_CASE(
    "A trial with fewer than half of the config's marker names is refused where the "
    "caller can allow it, naming the missing, the closest and the option") {
  const fabrik::DaemonConfig config = fabrik::default_daemon_config();
  MarkerTrial trial = default_model_trial();
  const std::size_t n = trial.labels.size();
  REQUIRE(n == 45);
  // 22 of 45 kept (fewer than half), the rest respelled as another export would.
  for (std::size_t i = 22; i < n; ++i) trial.labels[i] = trial.labels[i] + "_";
  auto refusal = [&](bool allow_few) {
    try {
      fabrik::require_shared_markers(config, trial, "walk.trc", "--subject", allow_few,
                                     "--allow-missing-markers");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string message = refusal(false);
  INFO(message);
  CHECK_THAT(message, Catch::StartsWith("walk.trc: has only 22 of the 45 marker names of the "
                                        "config <embedded>/default.json (fewer than half)"));
  CHECK_THAT(message, Catch::Contains("\n  closest: "));
  std::string first_missing;  // in the config's order, as the message lists them
  for (const fabrik::MarkerTarget& m : config.tracker.markers)
    if (first_missing.empty() && trial.find(m.marker) < 0) first_missing = m.marker;
  CHECK_THAT(message, Catch::Contains("\n  closest: " + first_missing + " ~ " + first_missing +
                                      "_ (punctuation)"));
  CHECK_THAT(message, Catch::EndsWith("to track with the 22 markers it has, give "
                                      "--allow-missing-markers"));
  CHECK(refusal(true) == "accepted");  // the caller allows it (eval, view, the option given)
  // Half of them (23 of 45 is more) is tracked.
  trial.labels[22] = config.tracker.markers[22].marker;
  CHECK(refusal(false) == "accepted");
  // The labels all there, but 23 of the columns without a sample: the same refusal (it passed
  // as ok and good, the pelvis and legs solved from nothing).
  MarkerTrial blank = default_model_trial();
  for (std::size_t f = 0; f < blank.frames(); ++f)
    for (std::size_t i = 0; i < 23; ++i)
      blank.at(f, i).setConstant(std::numeric_limits<double>::quiet_NaN());
  trial = blank;
  const std::string empty = refusal(false);
  CHECK_THAT(empty, Catch::StartsWith("walk.trc: has samples for only 22 of the 45 markers of "
                                      "the config <embedded>/default.json (fewer than half): the "
                                      "columns of 23 of its labels hold none ("));
  // Its fix is the trial's, not a marker set's (it offered to map the labels, which match).
  CHECK_THAT(empty, Catch::Contains("\nFix: check the trial's export") &&
                        !Catch::Contains("file:") && !Catch::Contains("targets.markers"));
  CHECK(refusal(true) == "accepted");
}

TEST_CASE("A config whose names carry a subject prefix the file's labels lack is told so") {
  // A config calibrated from one subject of a Nexus C3D names its markers `Daphnee:LASI`; that
  // subject's own TRC export says `LASI`, another subject's `Other:LASI`: no closest was named.
  fabrik::DaemonConfig config = fabrik::default_daemon_config();
  for (fabrik::MarkerTarget& m : config.tracker.markers) m.marker = "Daphnee:" + m.marker;
  MarkerTrial trial = default_model_trial();
  auto refusal = [&] {
    try {
      fabrik::require_shared_markers(config, trial, "walk.trc", "--subject");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  std::string message = refusal();
  INFO(message);
  CHECK_THAT(message, Catch::Contains("\n  closest: Daphnee:LASI ~ LASI (without 'Daphnee:')"));
  CHECK_THAT(message, Catch::Contains("(the config's names carry the subject prefix 'Daphnee:': "
                                      "remove it from its targets, or calibrate from this "
                                      "subject's own file)"));
  CHECK_THAT(message, !Catch::Contains("--subject"));
  for (std::string& l : trial.labels) l = "Other:" + l;
  message = refusal();
  CHECK_THAT(message,
             Catch::Contains("Daphnee:LASI ~ Other:LASI (after 'Other:', not 'Daphnee:')"));
  CHECK_THAT(message, Catch::Contains("remove it from its targets, then give --subject Other, or "
                                      "calibrate"));
}

TEST_CASE("fabrik solve and calibrate on a C3D without 3D points: the truth, exit 2") {
  MarkerTrial none;
  none.rate_hz = 100.0;
  TempFile c3d(".c3d"), out(".trc");
  fabrik::io::write_c3d(c3d.path(), none,
                        fabrik::io::C3dWriteOptions{.analog_channels = 12,
                                                    .analog_samples_per_frame = 10,
                                                    .frames_without_points = 300});
  const std::string expected = c3d.path() +
                               ": the file has no 3D marker data; it has 12 analog channels at "
                               "1000 Hz over 300 frames";
  const auto [solve_code, solve_err] =
      run_fabrik({"solve", "--input", c3d.path(), "--output", out.path(), "--quiet"});
  CHECK(solve_code == 2);
  CHECK_THAT(solve_err, Catch::StartsWith("fabrik solve: " + expected));
  const auto [calib_code, calib_err] =
      run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/gait2354.json",
                  "--static", c3d.path(), "--output", out.path()});
  CHECK(calib_code == 2);
  CHECK_THAT(calib_err, Catch::StartsWith("fabrik calibrate: " + expected));
  CHECK_FALSE(fs::exists(out.path()));
}

TEST_CASE("fabrik solve --angles: the source's times from frame 23, no step above 10 deg") {
  MarkerTrial trial = default_model_trial();
  trial.first_frame = 23;
  trial.first_time_frames = 23;  // Frame# 23 at Time 0.23, as rajagopal_run.trc
  TempFile trc(".trc"), out(".trc"), mot(".mot");
  fabrik::io::write_trc(trc.path(), trial);
  const auto [code, err] = run_fabrik({"solve", "--input", trc.path(), "--output", out.path(),
                                       "--angles", mot.path(), "--quiet"});
  INFO(err);
  REQUIRE(code == 0);
  const fabrik::io::OpenSimTable t = fabrik::io::read_opensim_table(mot.path());
  REQUIRE(t.rows == trial.frames());
  CHECK(t.time_s.front() == 0.23);
  CHECK(t.time_s[7] == Approx(0.30).margin(1e-12));
  const fabrik::test::TableStep step = fabrik::test::largest_step(t);
  INFO("largest step " << step.step << " (" << step.column << " at " << step.time_s << " s)");
  CHECK(step.step <= fabrik::test::kMaxCoordinateStepDeg);
}

TEST_CASE(
    "fabrik solve's CSV joint centres carry the source's frame numbers and times, as its TRC, "
    "and its report counts every fit verdict") {
  MarkerTrial trial = default_model_trial();
  trial.first_frame = 23;
  trial.first_time_frames = 23;  // Frame# 23 at Time 0.23
  TempFile trc(".trc"), csv(".csv"), joints(".trc"), report(".json");
  fabrik::io::write_trc(trc.path(), trial);
  for (const TempFile* out : {&csv, &joints}) {
    const auto [code, err] = run_fabrik({"solve", "--input", trc.path(), "--output", out->path(),
                                         "--report", report.path(), "--quiet"});
    INFO(err);
    REQUIRE(code == 0);
  }
  // The report counts every fit verdict, a zero too (before: {"good": N} alone).
  const json quality = json::parse(slurp(report.path()))["quality"];
  CHECK(quality.size() == 3);
  CHECK(quality.value("good", -1) + quality.value("poor", -1) + quality.value("none", -1) ==
        static_cast<int>(trial.frames()));
  CHECK(quality.value("poor", -1) == 0);
  std::istringstream rows(slurp(csv.path()));
  std::string header, first, second;
  std::getline(rows, header);
  std::getline(rows, first);
  std::getline(rows, second);
  CHECK_THAT(header, Catch::StartsWith("frame,time_s,"));
  CHECK_THAT(first, Catch::StartsWith("23,0.23,"));  // before: "23,0," (time from the first row)
  CHECK_THAT(second, Catch::StartsWith("24,0.24,"));
  const MarkerTrial written = fabrik::io::read_trc(joints.path());
  CHECK(written.first_frame == 23);
  CHECK(written.file_time_s(0) == Approx(0.23).margin(1e-12));
  // Times past 1000 s at 240 Hz keep every row apart (an ostream's 6 digits wrote "1000" twice).
  MarkerTrial late;
  late.labels = {"A"};
  late.rate_hz = 240.0;
  late.first_frame = 240000;
  late.first_time_frames = 240000.0;
  late.positions_m = {Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(0.1, 0.2, 0.3)};
  TempFile late_csv(".csv");
  fabrik::write_trial_file(late_csv.path(), late);
  std::istringstream late_rows(slurp(late_csv.path()));
  std::getline(late_rows, header);
  for (int f = 0; f < 2; ++f) {
    std::string row;
    std::getline(late_rows, row);
    const std::string time =
        row.substr(row.find(',') + 1, row.find(',', row.find(',') + 1) - row.find(',') - 1);
    CAPTURE(row);
    CHECK(std::stod(time) == late.file_time_s(static_cast<std::size_t>(f)));
  }
}

TEST_CASE("fabrik view --pose takes bind: and connect: before its endpoint, and checks the rest") {
  // Before: "fabrik view: Protocol not supported" (ZeroMQ's, the prefix taken as a transport).
  for (const std::string prefix : {"connect:", "bind:"}) {
    CAPTURE(prefix);
    const auto [code, err] =
        run_fabrik({"view", "--pose", prefix + "tcp://127.0.0.1:99999", "--listen", "127.0.0.1:0"});
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("--pose: port '99999' of 'tcp://127.0.0.1:99999' is out of "
                                    "range"));
  }
  // A bind that fails names the option and the endpoint (before: ZeroMQ's bare message).
  const auto [code, err] =
      run_fabrik({"view", "--pose", "bind:tcp://192.0.2.1:22608", "--listen", "127.0.0.1:0"});
  CHECK(code == 2);
  CHECK_THAT(err, Catch::Contains("--pose: cannot bind to 'tcp://192.0.2.1:22608'") &&
                      Catch::Contains("Fix: "));
}

TEST_CASE("fabrik view names a wildcard bind as every address of the host, not as 0.0.0.0") {
  // ZeroMQ names the bound endpoint tcp://0.0.0.0:PORT, which no sender can connect to.
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"bind:tcp://*:*", ", bound on every address of this host: a sender connects to one of them"},
      {"bind:tcp://127.0.0.1:*", ", bound; page from"}};
  for (const auto& [pose, said] : cases) {
    CAPTURE(pose);
    fabrik::test::Process view({"/bin/sh", "-c",
                                "exec '" + std::string(FABRIK_PATH) + "' view --pose '" + pose +
                                    "' --listen 127.0.0.1:0 1>&2"});
    REQUIRE(view.wait_for_output("page from", std::chrono::seconds(20)));
    CHECK_THAT(view.stderr_text(), Catch::Contains(said));
    view.signal(SIGTERM);
    CHECK(view.wait(std::chrono::seconds(10)) == 0);
  }
}

TEST_CASE("fabrik view refuses a --pose that is its own --listen address, exit 2 at once") {
  // Before: the view subscribed to its own web server, ZeroMQ's handshake met HTTP, and the page
  // stayed empty without a word. A view that starts runs until the limit: the test then fails.
  const std::vector<std::pair<std::string, std::string>> clashes = {
      {"tcp://127.0.0.1:28081", "127.0.0.1:28081"},
      {"tcp://localhost:28081", "127.0.0.1:28081"},
      {"tcp://127.0.0.1:28081", "0.0.0.0:28081"},
      {"bind:tcp://*:28081", "127.0.0.1:28081"}};
  for (const auto& [pose, listen] : clashes) {
    CAPTURE(pose, listen);
    const auto [code, err] = run_fabrik({"view", "--pose", pose, "--listen", listen}, "/dev/null",
                                        std::chrono::seconds(20));
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("is the view's own --listen address '" + listen + "'"));
  }
}

TEST_CASE("fabrik solve prints its summary when --angles cannot be honoured, then refuses, exit 2") {
  // A model without coordinates: nothing to write as angles.
  TempFile config(".json"), trc(".trc"), out(".trc"), mot(".mot"), summary(".txt");
  std::ofstream(config.path()) << R"({"format": "fabrikd-config/1", "model": {
      "format": "fabrikd-model/1", "units": "mm",
      "segments": [
        {"name": "body", "base": "root", "points": {"j": [0, 300, 0]},
         "markers": {"A": [100, 0, 0], "B": [0, 200, 0], "C": [0, 0, 100]}},
        {"name": "arm", "parent": "body", "base": "j",
         "markers": {"D": [200, 0, 0], "E": [0, -100, 50]}}]}})";
  MarkerTrial trial;
  trial.labels = {"A", "B", "C", "D", "E"};
  trial.rate_hz = 100.0;
  for (int f = 0; f < 20; ++f)
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0, 0.2, 0),
                                     Eigen::Vector3d(0, 0, 0.1), Eigen::Vector3d(0.2, 0.3, 0),
                                     Eigen::Vector3d(0, 0.2, 0.05)})
      trial.positions_m.push_back(p + Eigen::Vector3d(0.001 * f, 0, 0));
  fabrik::io::write_trc(trc.path(), trial);
  const auto [code, err] = run_fabrik({"solve", "--config", config.path(), "--input", trc.path(),
                                       "--output", out.path(), "--angles", mot.path(), "--quiet"},
                                      summary.path());
  CHECK(code == 2);
  CHECK_THAT(err, Catch::Contains("--angles: the model has no named coordinates, so " + mot.path() +
                                  " was not written (the other outputs were)"));
  const std::string printed = slurp(summary.path());
  CHECK_THAT(printed, Catch::Contains("frames            20"));
  CHECK_THAT(printed, Catch::Contains("marker residual   RMS"));
  CHECK(fs::exists(out.path()));
  CHECK_FALSE(fs::exists(mot.path()));
}

TEST_CASE("fabrik solve refuses a config that fits nothing up front, exit 2") {
  MarkerTrial trial = small_trial();  // labels A, B, Subj:C; the default config has none
  TempFile trc(".trc"), out(".trc");
  fabrik::io::write_trc(trc.path(), trial);
  const auto [code, err] =
      run_fabrik({"solve", "--input", trc.path(), "--output", out.path(), "--quiet"});
  CHECK(code == 2);
  CHECK_THAT(err, Catch::StartsWith("fabrik solve: " + trc.path() + ": shares none of the 45"));
  CHECK_FALSE(fs::exists(out.path()));
}

TEST_CASE("fabrik info --json describes a recording for scripts") {
  MarkerTrial trial = small_trial();
  trial.at(3, 0).setZero();
  TempFile c3d(".c3d"), json_out(".json");
  fabrik::io::write_c3d(c3d.path(), trial,
                        fabrik::io::C3dWriteOptions{.processor = fabrik::io::C3dProcessor::mips,
                                                    .analog_channels = 2});
  const auto [code, err] = run_fabrik({"info", "--json", c3d.path()}, json_out.path());
  CHECK(code == 0);
  const json j = json::parse(slurp(json_out.path()));
  CHECK(j["format"] == "C3D");
  CHECK(j["number_format"] == "MIPS float");
  CHECK(j["rate_hz"] == 100.0);
  CHECK(j["units"] == "mm");
  CHECK(j["frames"] == 50);
  CHECK(j["first_frame"] == 1);
  CHECK(j["last_frame"] == 50);
  REQUIRE(j["markers"].size() == 3);
  CHECK(j["markers"][0] == json({{"label", "A"}, {"missing", 1}, {"zeros", 1}, {"longest_gap", 1}}));
  CHECK(j["markers"][1]["missing"] == 5);
  CHECK(j["markers"][1]["longest_gap"] == 5);
  CHECK(j["analog"]["channels"] == 2);
  CHECK(j["rotations"]["count"] == 0);
  CHECK(j["warnings"].size() == 1);  // the zero

  const auto [bad_code, bad_err] = run_fabrik({"info", kSourceDir + "/README.md"});
  CHECK(bad_code == 2);
  CHECK_THAT(bad_err, Catch::Contains("unknown file type '.md': fabrik info reads"));
}

TEST_CASE("fabrik info on every recording in the shared data folder") {
  if (!fs::exists(kDataDir)) {
    WARN("skipped: " << kDataDir << " not found");
    return;
  }
  std::vector<std::string> args = {"info"};
  for (const auto& entry : fs::directory_iterator(kDataDir))
    if (entry.path().extension() != ".md") args.push_back(entry.path().string());
  REQUIRE(args.size() >= 9);
  TempFile text(".txt");
  const auto [code, err] = run_fabrik(args, text.path());
  INFO(err);
  CHECK(code == 0);
  const std::string out = slurp(text.path());
  CHECK(std::count(out.begin(), out.end(), '\n') > 100);
  CHECK_THAT(out, Catch::Contains("analog      38 channels at 2000 Hz"));
  CHECK_THAT(out, Catch::Contains("rows        2432, time 0 to 24.31 s"));
}

TEST_CASE("walk1 with a tracked marker at (0, 0, 0) throughout tracks as without that marker") {
  const std::string walk = kDataDir + "/subject01_walk1.trc";
  if (!fs::exists(walk)) {
    WARN("skipped: " << walk << " not found");
    return;
  }
  const fabrik::DaemonConfig config = fabrik::eval::calibrate_config(
      kSourceDir + "/config/templates/gait2354.json", kDataDir + "/subject01_static.trc");
  MarkerTrial without = fabrik::io::read_trial(walk), zeros = without;
  const int m = without.find("R.Thigh.Front");
  REQUIRE(m >= 0);
  for (std::size_t f = 0; f < without.frames(); ++f) {
    without.at(f, std::size_t(m)).setConstant(NAN);
    zeros.at(f, std::size_t(m)).setZero();
  }
  TempFile copy(".trc");
  fabrik::io::write_trc(copy.path(), zeros);

  const auto joints_rms_mm = [&](const fabrik::TrialSolution& a, const fabrik::TrialSolution& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < a.joints.positions_m.size(); ++i)
      sum += (a.joints.positions_m[i] - b.joints.positions_m[i]).squaredNorm();
    return std::sqrt(sum / static_cast<double>(a.joints.positions_m.size())) * 1e3;
  };
  const fabrik::TrialSolution reference = fabrik::solve_trial(config, without);
  const fabrik::TrialSolution read = fabrik::solve_trial(config, fabrik::io::read_trial(copy.path()));
  CHECK(joints_rms_mm(read, reference) < 0.5);
  const json summary = fabrik::solution_summary(read);
  CHECK(summary["markers_missing_in_trial"] == json::array({"R.Thigh.Front"}));
  CHECK(summary["markers_mostly_missing"][0]["zero_frames"] == 151);
  // Read as positions, the zeros are outliers (left out of every frame's solve); with the
  // outlier rule off they pull the thigh towards the origin.
  const MarkerTrial kept_zeros = fabrik::io::read_trial(copy.path(), {.zeros_are_missing = false});
  const fabrik::TrialSolution kept = fabrik::solve_trial(config, kept_zeros);
  // Not to the digit: the two trackings differ in their cold first frame (the zeros take part
  // in its rigid alignment) and in the gap prediction's weak pull on the thigh, which only the
  // reference has; solved to convergence they end 0.38 mm apart, and where the loop stops
  // adds a little either way.
  CHECK(joints_rms_mm(kept, reference) < 1.0);
  fabrik::DaemonConfig no_outliers = config;
  no_outliers.tracker.outliers.enabled = false;
  CHECK(joints_rms_mm(fabrik::solve_trial(no_outliers, kept_zeros), reference) > 10.0);
}

TEST_CASE("replay sends an orientation table: joined on time with markers, or alone") {
  fabrik::io::OrientationTable table;
  table.sensors = {"pelvis_imu", "femur_imu"};
  table.rate_hz = 50.0;
  for (int r = 0; r < 30; ++r) {
    table.time_s.push_back(r / 50.0);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.01 * r, Eigen::Vector3d::UnitZ()));
    table.q.push_back(q);
    table.q.push_back(r == 4 ? Eigen::Quaterniond(NAN, NAN, NAN, NAN) : q);
  }
  zmq::context_t context;
  zmq::socket_t sub(context, zmq::socket_type::sub);
  sub.set(zmq::sockopt::rcvhwm, 0);
  sub.set(zmq::sockopt::subscribe, "markers");
  sub.bind("inproc://replay-orientations");

  SECTION("alone: the table's rows are the frames") {
    ReplayOptions o = fast_options("inproc://replay-orientations");
    o.orientations = &table;
    const MarkerTrial no_markers;
    ReplayThread replay(context, no_markers, o);
    const auto msgs = receive(sub, 30);
    const ReplaySummary s = replay.join();
    CHECK(s.frames_sent == 30);
    CHECK(s.orientations_nulled == 1);
    for (std::size_t k = 0; k < msgs.size(); ++k) {
      const auto& doc = msgs[k].second;
      INFO("frame index " << k);
      CHECK(doc["time"].get<double>() == Approx(static_cast<double>(k) / 50.0));
      CHECK(doc["orientations"]["pelvis_imu"][3].get<double>() ==
            Approx(std::sin(0.005 * static_cast<double>(k))).margin(1e-12));
      CHECK(doc["orientations"]["femur_imu"].is_null() == (k == 4));
    }
  }
  SECTION("with markers at 100 Hz: interpolated at each marker frame's time") {
    const MarkerTrial trial = small_trial();
    REQUIRE(trial.rate_hz == 100.0);
    ReplayOptions o = fast_options("inproc://replay-orientations");
    o.orientations = &table;
    ReplayThread replay(context, trial, o);
    const auto msgs = receive(sub, 50);
    replay.join();
    for (std::size_t k = 0; k < msgs.size(); ++k) {
      const auto& doc = msgs[k].second;
      INFO("frame index " << k);
      const double t_s = (trial.first_frame - 1 + static_cast<double>(k)) / 100.0;
      if (t_s > 29.0 / 50.0 + 0.01) {  // beyond the table by more than half a sample
        CHECK(doc["orientations"]["pelvis_imu"].is_null());
        continue;
      }
      CHECK(doc["markers"].contains("A"));
      CHECK(doc["orientations"]["pelvis_imu"][3].get<double>() ==
            Approx(std::sin(0.5 * 0.01 * std::min(t_s * 50.0, 29.0))).margin(1e-9));
    }
  }
}

// ---- What OpenSim refuses, and ports ZeroMQ would wrap ----

using fabrik::test::two_marker_trc;

TEST_CASE(
    "fabrik solve and calibrate refuse a repeated label and time going back, info reports "
    "them and time standing still") {
  TempFile repeated(".trc"), back(".trc"), still(".trc"), out(".trc"), json_out(".json"),
      text_out(".txt");
  std::ofstream(repeated.path()) << two_marker_trc("R.ASIS", "R.ASIS", {"0", "0.01", "0.02"});
  std::ofstream(back.path()) << two_marker_trc("R.ASIS", "L.ASIS", {"0", "0.01", "0.005", "0.02"});
  std::ofstream(still.path()) << two_marker_trc("R.ASIS", "L.ASIS", {"0", "0.01", "0.01", "0.02"});

  const auto solve = [&](const std::string& input) {
    return run_fabrik({"solve", "--input", input, "--output", out.path(), "--quiet"});
  };
  const auto [rep_code, rep_err] = solve(repeated.path());
  CHECK(rep_code == 2);
  CHECK_THAT(rep_err, Catch::StartsWith("fabrik solve: " + repeated.path() +
                                        ": line 4: marker 'R.ASIS' labels columns 3 and 6") &&
                          Catch::Contains("Fix: rename one of them"));
  const auto [back_code, back_err] = solve(back.path());
  CHECK(back_code == 2);
  CHECK_THAT(back_err, Catch::StartsWith("fabrik solve: " + back.path() +
                                         ": the Time column goes back in time at 1 row (the first "
                                         "at line 8, frame 3") &&
                           Catch::Contains("Fix: put the rows in time order"));
  const auto [calib_code, calib_err] =
      run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/gait2354.json",
                  "--static", repeated.path(), "--output", out.path()});
  CHECK(calib_code == 2);
  CHECK_THAT(calib_err, Catch::StartsWith("fabrik calibrate: " + repeated.path() + ": line 4"));
  // Standing still is read (time comes from the rate), with a warning; the solve goes on to
  // the config, which knows neither marker name here.
  const auto [still_code, still_err] = solve(still.path());
  CHECK(still_code == 2);  // "shares none of the 45"
  CHECK_THAT(still_err, Catch::Contains("fabrik solve: warning: " + still.path() +
                                        ": the Time column stands still at 1 row (the first at "
                                        "line 8, frame 3"));
  CHECK_FALSE(fs::exists(out.path()));

  // info describes all three, in text and in JSON (additions: repeated_labels, time_column).
  const auto [info_code, info_err] =
      run_fabrik({"info", repeated.path(), back.path(), still.path()}, text_out.path());
  CHECK(info_code == 0);
  const std::string text = slurp(text_out.path());
  CHECK_THAT(text, Catch::Contains("warning     line 4: marker 'R.ASIS' labels columns 3 and 6: "
                                   "ambiguous, `fabrik solve` refuses the file") &&
                       Catch::Contains("warning     the Time column goes back in time at 1 row") &&
                       Catch::Contains("warning     the Time column stands still at 1 row"));
  const auto [json_code, json_err] =
      run_fabrik({"info", "--json", repeated.path(), back.path(), still.path()}, json_out.path());
  CHECK(json_code == 0);
  const json j = json::parse(slurp(json_out.path()));
  REQUIRE(j.size() == 3);
  CHECK(j[0]["repeated_labels"] ==
        json::array({{{"label", "R.ASIS"}, {"first", 3}, {"second", 6}}}));
  CHECK(j[0]["markers"].size() == 2);
  CHECK(j[1]["repeated_labels"].empty());
  CHECK(j[1]["time_column"]["backwards"] == json({{"rows", 1},
                                                  {"first_frame", 3},
                                                  {"first_line", 8},
                                                  {"time_s", 0.005},
                                                  {"previous_s", 0.01}}));
  CHECK(j[1]["time_column"]["standing"] == json({{"rows", 0}}));
  CHECK(j[2]["time_column"]["standing"]["rows"] == 1);
  CHECK(j[2]["time_column"]["backwards"]["rows"] == 0);
}

TEST_CASE("fabrik replay and watch refuse ports ZeroMQ would wrap, exit 2 naming the option") {
  TempFile trc(".trc");
  fabrik::io::write_trc(trc.path(), small_trial());
  const auto [replay_code, replay_err] =
      run_fabrik({"replay", trc.path(), "--to", "tcp://127.0.0.1:99999", "--bind"});
  CHECK(replay_code == 2);
  CHECK_THAT(replay_err, Catch::Contains("fabrik replay: --to: port '99999' of "
                                         "'tcp://127.0.0.1:99999' is out of range") &&
                             Catch::Contains("Fix: use a port from 1 to 65535"));
  const auto [watch_code, watch_err] =
      run_fabrik({"watch", "--from", "tcp://127.0.0.1:-1", "--bind", "--seconds", "1"});
  CHECK(watch_code == 2);
  CHECK_THAT(watch_err, Catch::StartsWith("fabrik watch: --from: port '-1'"));
  // Bytes that are not UTF-8 in the endpoint come out escaped.
  const auto [raw_code, raw_err] =
      run_fabrik({"watch", "--from", "tcp://\xff:1\xfe", "--seconds", "1"});
  CHECK(raw_code == 2);
  CHECK_THAT(raw_err, Catch::Contains("'tcp://\\xff:1\\xfe'"));
  CHECK(raw_err.find('\xff') == std::string::npos);
}

// `calibrate --nominal` once printed a window of "frames 1 to 1", an empty lengths table and a
// comparison with a static trial there is none of; a marker template given --nominal was told
// to give --static "instead of --trial".
TEST_CASE("calibrate --nominal reports the nominal lengths and no trial it did not read") {
  using fabrik::test::run_fabrik;
  TempFile config(".json"), report(".txt");
  REQUIRE(run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/halpe26.json",
                      "--nominal", "--output", config.path()},
                     report.path())
              .first == 0);
  const std::string text = fabrik::test::slurp(report.path());
  CHECK_THAT(text, Catch::Contains("Segment lengths: the template's nominal ones (no trial)") &&
                       !Catch::Contains("Length window") &&
                       !Catch::Contains("Rest posture vs static means"));
  const auto [code, err] =
      run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/gait2354.json",
                  "--nominal", "--output", config.path()});
  CHECK(code == 2);
  CHECK_THAT(err, Catch::Contains("Fix: give --static instead of --nominal"));
  // --trial and --nominal together: the usage line names the three that exclude each other.
  const auto [both_code, both_err] =
      run_fabrik({"calibrate", "--template", kSourceDir + "/config/templates/halpe26.json",
                  "--nominal", "--trial", "t.trc", "--output", config.path()});
  CHECK(both_code == 2);
  CHECK_THAT(both_err,
             Catch::Contains("one of --static (a marker template), --trial or --nominal"));
}

// The header of `eval markerless --trial` once described the generator's options (20 s at 60 Hz,
// jitter 15 mm, dropouts 1/s) instead of the file evaluated.
TEST_CASE("eval markerless --trial describes the file it evaluates, not the generator's options") {
  using fabrik::test::run_fabrik;
  using fabrik::test::slurp;
  const std::string halpe = kSourceDir + "/config/templates/halpe26.json";
  TempFile config(".json"), trial(".trc"), table(".txt"), report(".json");
  const std::string stem = trial.path().substr(0, trial.path().size() - 4);
  for (const char* side : {".joints.trc", ".truth.mot", ".injected.csv"})
    trial.also_remove(stem + side);
  TempFile lengths(".json");
  REQUIRE(run_fabrik({"calibrate", "--template", halpe, "--nominal", "--output", config.path(),
                      "--lengths-json", lengths.path()})
              .first == 0);
  CHECK(json::parse(slurp(lengths.path())).contains("lengths"));  // --nominal writes it too
  REQUIRE(run_fabrik({"synth", "--keypoints", "--config", config.path(), "--seconds", "1", "--rate",
                      "120", "--jitter-mm", "3", "--output", trial.path()})
              .first == 0);
  {  // a keypoint option without --keypoints would be ignored: refused instead
    const auto [ignored_code, ignored_err] = run_fabrik(
        {"synth", "--config", config.path(), "--jitter-mm", "3", "--output", trial.path()});
    CHECK(ignored_code == 2);
    CHECK_THAT(ignored_err, Catch::Contains("--jitter-mm requires --keypoints"));
  }
  const auto [code, err] =
      run_fabrik({"eval", "markerless", "--trial", trial.path(), "--template", halpe}, table.path(),
                 std::chrono::seconds(120));
  CAPTURE(err);
  REQUIRE(code == 0);
  const std::string text = slurp(table.path());
  CHECK_THAT(text, Catch::StartsWith("markerless trial: " + trial.path() +
                                     " (120 frames at 120 Hz, 0 dropouts and 0 swaps"));
  CHECK_THAT(text, !Catch::Contains("jitter 15.0 mm") && !Catch::Contains("60 Hz"));
  REQUIRE(run_fabrik({"eval", "markerless", "--trial", trial.path(), "--template", halpe, "--json",
                      report.path()},
                     "/dev/null", std::chrono::seconds(120))
              .first == 0);
  const auto rows = nlohmann::json::parse(slurp(report.path()));
  REQUIRE(rows.size() == 1);
  CHECK(rows[0]["frames"] == 120);
  CHECK(rows[0]["jitter_mm"].is_null());  // the file's own is not known
  // The default template is the project's path: elsewhere, a hint, not "cannot open the file".
  const auto [missing_code, missing_err] = run_fabrik(
      {"eval", "markerless", "--template", "config/templates/nosuch.json", "--seconds", "1"});
  CHECK(missing_code == 2);
  CHECK_THAT(missing_err, Catch::Contains("config/templates/nosuch.json not found") &&
                              Catch::Contains("or pass --template"));
}

// CLI11 gives each kind of command-line error its own code (105-109 and more): `fabrik` says 2,
// as for every wrong input (README), in every subcommand; help still exits 0.
TEST_CASE("A command line fabrik cannot take exits 2 and says what was wrong, help exits 0") {
  const std::vector<std::vector<std::string>> wrong = {
      {"solve", "--bogus"},
      {"eval", "nosuch"},
      {"replay", "/nonexistent.trc", "--to", "tcp://127.0.0.1:5555"},
      {"bench", "pipeline", "--frames", "3"},
      {"watch", "--seconds", "soon"},
      {"nosuch"},
  };
  for (const std::vector<std::string>& args : wrong) {
    CAPTURE(args);
    const auto [code, err] = fabrik::test::run_fabrik(args);
    CAPTURE(err);
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("--help"));
  }
  // A number below its range says so in words (CLI11's PositiveNumber printed its range to
  // 308 digits).
  const auto [frames_code, frames_err] =
      fabrik::test::run_fabrik({"calibrate", "--template", "t.json", "--static", "s.trc",
                                "--output", "o.json", "--frames", "0"});
  CHECK(frames_code == 2);
  CHECK_THAT(frames_err,
             Catch::Contains("--frames: must be more than 0, not 0") && !Catch::Contains("000000"));
  // NaN is in no range (CLI11's Range let it through: every comparison with NaN is false), and
  // a negative count does not wrap to 2^64 - 1.
  const std::vector<std::pair<std::vector<std::string>, std::string>> out_of_range = {
      {{"bench", "fullbody", "--builtin-only", "--frames", "2", "--rate", "nan"},
       "--rate: 'nan' is not a number"},
      {{"watch", "--from", "tcp://127.0.0.1:5556", "--seconds", "nan"},
       "--seconds: 'nan' is not a number"},
      {{"solve", "--input", kSourceDir + "/config/default.json", "--output", "o.csv", "--filter-hz",
        "nan"},
       "--filter-hz: 'nan' is not a number"},
      {{"solve", "--input", kSourceDir + "/config/default.json", "--output", "o.csv", "--filter-hz",
        "abc"},
       "--filter-hz: 'abc' is not a number"},  // was "Value abc not in range 0.000000 to ..."
      {{"replay", kSourceDir + "/config/default.json", "--frames", "-1"},
       "--frames: '-1' is below 0"},
      {{"calibrate", "--template", "t.json", "--static", "s.trc", "--output", "o.json",
        "--first-frame", "-5"},
       "--first-frame: Value -5 not in range"},
      {{"sim", "qtm", kSourceDir + "/config/default.json", "--file-up", "+w"},
       "--file-up: +w not in"},  // sim natnet refused it, sim qtm served it
      // The simulated Motive's own values are refused before its recording is read (here a
      // config, which would be refused as a recording): the group once only after.
      {{"sim", "natnet", kSourceDir + "/config/default.json", "--multicast-group", "10.0.0.5"},
       "--multicast-group: '10.0.0.5' is not an IPv4 multicast group"},
      {{"sim", "natnet", kSourceDir + "/config/default.json", "--natnet-version", "2.0"},
       "--natnet-version: NatNet 2.0 cannot be served"},
      {{"sim", "natnet", kSourceDir + "/config/default.json", "--natnet-version", "4"},
       "--natnet-version: '4': expected MAJOR.MINOR"},
      {{"sim", "natnet", kSourceDir + "/config/default.json", "--up-axis", "y"},
       "--up-axis: y not in"},
      {{"sim", "natnet", kSourceDir + "/config/default.json", "--data-port", "65536"},
       "--data-port: Value 65536 not in range"},
      {{"sim", "qtm", kSourceDir + "/config/default.json", "--base-port", "65534"},
       "--base-port: Value 65534 not in range"},
      // An unsigned number below 0 is quoted as written (it was "Could not convert: --seed =
      // -1000").
      {{"bench", "fullbody", "--builtin-only", "--frames", "2", "--seed", "-1e3"},
       "--seed: '-1e3' is below 0"},
      {{"bench", "fullbody", "--builtin-only", "--frames", "2", "--seed", "-7"},
       "--seed: '-7' is below 0"},
  };
  for (const auto& [args, said] : out_of_range) {
    CAPTURE(args);
    const auto [code, err] = fabrik::test::run_fabrik(args);
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains(said));
  }
  // A refused --to is refused before the replay says where it sends (it once printed
  // "replay: ... -> tcp://127.0.0.1:99999 (json)" first).
  TempFile trial(".trc");
  REQUIRE(fabrik::test::run_fabrik({"synth", "--config", kSourceDir + "/config/default.json",
                                    "--output", trial.path(), "--seconds", "0.05"})
              .first == 0);
  const auto [to_code, to_err] =
      fabrik::test::run_fabrik({"replay", trial.path(), "--to", "tcp://127.0.0.1:99999"});
  CHECK(to_code == 2);
  CHECK_THAT(to_err, Catch::StartsWith("fabrik replay: --to: port '99999'") &&
                         !Catch::Contains("replay: " + trial.path()));
  // A word that names no command is named (CLI11 said "A subcommand is required").
  for (const auto& [args, said] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"nosuch"}, "fabrik: 'nosuch' is not a command; the commands: bench, solve"},
           {{"bench", "nosuch", "--json"}, "fabrik bench: 'nosuch' is not a command"},
           {{"sim", "vicon"}, "fabrik sim: 'vicon' is not a command; the commands: qtm, natnet"}}) {
    CAPTURE(args);
    const auto [code, err] = fabrik::test::run_fabrik(args);
    CHECK(code == 2);
    CHECK_THAT(err, Catch::StartsWith(said) && Catch::Contains("--help"));
  }
  for (const std::vector<std::string>& args :
       std::vector<std::vector<std::string>>{{"--help"}, {"solve", "--help"}, {"bench", "--help"}}) {
    CAPTURE(args);
    CHECK(fabrik::test::run_fabrik(args).first == 0);
  }
}

TEST_CASE("An empty value is refused on every fabrik option, not read as its default") {
  // `--config ""` (an unset shell variable) ran solve and bench fullbody on the embedded default
  // and calibrate ignored `--lab-up ""`; fabrikd refused it. Each refusal comes before any work.
  TempFile out(".trc");
  const std::string trial = kSourceDir + "/config/default.json";  // never read: refused first
  const std::vector<std::vector<std::string>> empty = {
      {"solve", "--config", "", "--input", trial, "--output", out.path()},
      {"solve", "--input", trial, "--output", out.path(), "--report", ""},
      {"calibrate", "--template", "t.json", "--static", "s.trc", "--output", "o.json", "--lab-up",
       ""},
      {"bench", "fullbody", "--config", "", "--frames", "2"},
      {"view", "--config", "", "--listen", "127.0.0.1:0"},
      {"synth", "--config", "", "--output", out.path()},
      {"watch", "--from", "tcp://127.0.0.1:5556", "--topic", ""},
      // Numbers too: CLI11 read an empty whole number as 0, an empty one with a range as
      // "Value  not in range".
      {"bench", "fullbody", "--builtin-only", "--frames", "2", "--seed", ""},
      {"bench", "fullbody", "--builtin-only", "--frames", "2", "--noise-mm", ""},
      {"bench", "fullbody", "--builtin-only", "--frames", ""}};
  for (const std::vector<std::string>& args : empty) {
    CAPTURE(args);
    const auto [code, err] = fabrik::test::run_fabrik(args, "/dev/null", std::chrono::seconds(20));
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains(": is empty. Fix: give a value"));
  }
  CHECK(slurp(out.path()).empty());
  // A positional is named by its help's word; the message says which of several is empty.
  const auto [info_code, info_err] = fabrik::test::run_fabrik({"info", "", "x.trc"});
  CHECK(info_code == 2);
  CHECK_THAT(info_err, Catch::StartsWith("files: an empty value (\"\") was given"));
}

TEST_CASE("A write that fails is an error, not a truncated file and exit 0") {
  // /dev/full takes the open and fails each write (ENOSPC), as a full disk does. The report
  // and eval's JSON were streamed without a check after the last write: exit 0, nothing
  // written.
  if (!std::filesystem::exists("/dev/full")) {
    WARN("skipped: no /dev/full on this machine");
    return;
  }
  TempFile trial(".trc"), joints(".trc");
  REQUIRE(run_fabrik({"synth", "--config", kSourceDir + "/config/default.json", "--output",
                      trial.path(), "--seconds", "0.05"})
              .first == 0);
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"solve", "--input", trial.path(), "--output", joints.path(), "--report", "/dev/full",
            "--quiet"},
           {"solve", "--input", trial.path(), "--output", "/dev/full", "--quiet"},
           {"eval", "synthetic", "--seconds", "0.2", "--json", "/dev/full"}}) {
    CAPTURE(args);
    const auto [code, err] = run_fabrik(args, "/dev/null", std::chrono::seconds(60));
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("/dev/full: writing failed"));
    CHECK_THAT(err, Catch::Contains(std::string("(") + std::strerror(ENOSPC) + ")"));  // why
  }
  // Results on standard output (`info --json > FILE` on a full disk): exit 0 before.
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"info", trial.path(), "--json"},
           {"solve", "--input", trial.path(), "--output", joints.path()},
           // Help and version returned before the check: exit 0, nothing written.
           {"--help"},
           {"--version"},
           {"solve", "--help"}}) {
    CAPTURE(args);
    const auto [code, err] = run_fabrik(args, "/dev/full", std::chrono::seconds(60));
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("fabrik: writing the standard output failed"));
  }
}

TEST_CASE("The check that an output can be written leaves the names alone") {
  // It once opened the output's own name with O_EXCL: a link to a file not yet made was
  // "File exists", and a file another program made meanwhile could be removed.
  namespace fs = std::filesystem;
  TempFile trial(".trc"), joints(".trc");
  const fs::path folder =
      fs::path(joints.path()).parent_path() / ("probe-" + fs::path(joints.path()).stem().string());
  fs::create_directories(folder);
  REQUIRE(run_fabrik({"synth", "--config", kSourceDir + "/config/default.json", "--output",
                      trial.path(), "--seconds", "0.05"})
              .first == 0);
  fs::create_symlink("target.json", folder / "link.json");
  fs::create_symlink("no-folder/x.json", folder / "nowhere.json");
  // A link into a folder that does not exist is followed, and refused before the solve.
  const auto [nowhere_code, nowhere_err] =
      run_fabrik({"solve", "--input", trial.path(), "--output", joints.path(), "--report",
                  (folder / "nowhere.json").string(), "--quiet"});
  CHECK(nowhere_code == 2);
  CHECK_THAT(nowhere_err, Catch::Contains("nowhere.json' cannot be written (No such file"));
  CHECK_FALSE(fs::exists(joints.path()));
  const auto [code, err] = run_fabrik({"solve", "--input", trial.path(), "--output", joints.path(),
                                       "--report", (folder / "link.json").string(), "--markers",
                                       (folder / "m.trc").string(), "--quiet"});
  CAPTURE(err);
  CHECK(code == 0);
  CHECK(json::parse(slurp((folder / "target.json").string()), nullptr, false).is_object());
  // Nothing of the check's own is left behind (new outputs in this folder were tried).
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(folder))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  CHECK(names == std::vector<std::string>{"link.json", "m.trc", "m.trc.filled.csv", "nowhere.json",
                                          "target.json"});
  fs::remove_all(folder);
}

namespace {

// The names in the events an inotify watch holds (each is queued within the call that caused
// it: all are readable by now), "(the folder)" for its own.
std::vector<std::string> names_seen(int watch) {
  std::vector<std::string> seen;
  alignas(inotify_event) char buffer[4096];
  for (ssize_t n; (n = ::read(watch, buffer, sizeof buffer)) > 0;)
    for (ssize_t at = 0; at < n;) {
      const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
      seen.emplace_back(event->len > 0 ? event->name : "(the folder)");
      at += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
    }
  return seen;
}

}  // namespace

TEST_CASE("The check that a new output can be written makes no name a watcher could see") {
  // A program watching the output's folder (a lab's sync tool, an inotify trigger) must see
  // no file come and go: the check's own file has no name where the system allows it.
  namespace fs = std::filesystem;
  TempFile marker(".d");
  const fs::path folder = marker.path();
  fs::create_directories(folder);
  const int unnamed = ::open(folder.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0600);
  if (unnamed < 0) {
    fs::remove_all(folder);
    WARN("skipped: this temp folder's filesystem has no unnamed files (O_TMPFILE: "
         << std::strerror(errno) << "); the check makes a named one there");
    return;
  }
  ::close(unnamed);
  const int watch = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  REQUIRE(watch >= 0);
  REQUIRE(::inotify_add_watch(watch, folder.c_str(), IN_CREATE | IN_DELETE | IN_MOVED_TO) >= 0);
  CHECK_NOTHROW(fabrik::tools::require_output_folders(
      {{"--report", (folder / "r.json").string()}, {"--output", (folder / "j.trc").string()}}));
  CHECK(names_seen(watch).empty());
  ::close(watch);
  CHECK(fs::is_empty(folder));
  fs::remove_all(folder);
}

TEST_CASE("/dev/tty is the terminal it stands for: two outputs there are refused") {
  // /dev/tty is a device of its own (5, 0), not the terminal's node (/dev/pts/N). A child made
  // a session leader takes a new pseudo-terminal as its controlling one, and asks.
  int result[2];
  REQUIRE(::pipe2(result, O_CLOEXEC) == 0);
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    char verdict = 'e';  // no controlling terminal could be made
    const int master = ::setsid() >= 0 ? ::posix_openpt(O_RDWR | O_NOCTTY) : -1;
    const char* name = master >= 0 && ::grantpt(master) == 0 && ::unlockpt(master) == 0
                           ? ::ptsname(master)
                           : nullptr;
    if (name && ::open(name, O_RDWR) >= 0) {  // without O_NOCTTY: it becomes ours
      try {
        fabrik::tools::require_distinct_files({{"--json", name}, {"--csv", "/dev/tty"}});
        verdict = 'n';
      } catch (const std::invalid_argument& e) {
        verdict =
            std::string(e.what()).find("name the same device") != std::string::npos ? 'y' : 'm';
      } catch (...) {  // nothing may reach Catch in the child
        verdict = 'x';
      }
    }
    (void)!::write(result[1], &verdict, 1);
    ::_exit(0);
  }
  ::close(result[1]);
  pollfd readable{result[0], POLLIN, 0};
  char verdict = '?';
  if (::poll(&readable, 1, 10000) == 1) (void)!::read(result[0], &verdict, 1);
  ::close(result[0]);
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  if (verdict == 'e') {
    WARN("skipped: no pseudo-terminal can be made here");
    return;
  }
  CHECK(verdict == 'y');  // 'n': accepted; 'm', 'x': refused otherwise, or threw; '?': no answer
}

TEST_CASE("A device number is read as the kernel encodes it") {
  // new_encode_dev: minor's low 8 bits, 12 bits of major, minor's upper 12 bits.
  using fabrik::tools::detail::device_from_kernel;
  CHECK(major(device_from_kernel(0x8803u)) == 136);  // /dev/pts/3
  CHECK(minor(device_from_kernel(0x8803u)) == 3);
  CHECK(major(device_from_kernel(0x1208834u)) == 136);  // minor 0x1234: over 8 bits
  CHECK(minor(device_from_kernel(0x1208834u)) == 0x1234);
  CHECK(major(device_from_kernel(0xfff00u)) == 0xfff);
  CHECK(minor(device_from_kernel(0xfff00u)) == 0);
}

TEST_CASE("A console's name is read as sysfs spells it") {
  using fabrik::tools::detail::console_behind;
  using fabrik::tools::detail::device_from_sysfs;
  // The last of console/active is the one /dev/console writes to (the kernel's ABI notes).
  CHECK(console_behind("tty0 ttyS0\n") == "ttyS0");
  CHECK(console_behind("ttyS0 tty0\n") == "tty0");
  CHECK(console_behind("hvc0") == "hvc0");
  CHECK(console_behind(" \n").empty());
  CHECK(console_behind("").empty());
  REQUIRE(device_from_sysfs("4:64\n").has_value());
  CHECK(major(*device_from_sysfs("4:64\n")) == 4);
  CHECK(minor(*device_from_sysfs("4:64\n")) == 64);
  CHECK(minor(*device_from_sysfs("136:1234")) == 1234);
  CHECK_FALSE(device_from_sysfs("4").has_value());
  CHECK_FALSE(device_from_sysfs("4:").has_value());
  CHECK_FALSE(device_from_sysfs(":64").has_value());
  CHECK_FALSE(device_from_sysfs("4:64x").has_value());
  CHECK_FALSE(device_from_sysfs("").has_value());
}

TEST_CASE("/dev/console and /dev/tty0 are the terminal they stand for, /dev/ptmx a new one each") {
  using fabrik::tools::require_distinct_files;
  // Each open of /dev/ptmx makes a new terminal: two outputs there were refused.
  CHECK_NOTHROW(require_distinct_files({{"--json", "/dev/ptmx"}, {"--csv", "/dev/ptmx"}}));
  // The terminal behind each, as sysfs names it, read here apart from the code under test.
  auto last_word = [](const std::string& path) {
    std::ifstream in(path);
    std::string word, last;
    while (in >> word) last = word;
    return last;
  };
  const std::string front = last_word("/sys/class/tty/tty0/active");
  std::string console = last_word("/sys/class/tty/console/active");
  if (console == "tty0") console = front;
  int compared = 0;
  for (const auto& [alias, name] :
       {std::pair<std::string, std::string>{"/dev/tty0", front}, {"/dev/console", console}}) {
    struct stat st {};
    if (name.empty() || ::stat(alias.c_str(), &st) != 0 || !S_ISCHR(st.st_mode) ||
        !std::filesystem::is_character_file("/dev/" + name))
      continue;
    CAPTURE(alias, name);
    CHECK(fabrik::tools::detail::device_number(alias) ==
          fabrik::tools::detail::device_number("/dev/" + name));
    CHECK_THROWS_WITH(require_distinct_files({{"--json", alias}, {"--csv", "/dev/" + name}}),
                      Catch::Contains("name the same device"));
    ++compared;
  }
  if (compared == 0) WARN("skipped: no console or virtual console to compare here");
}

TEST_CASE("Two nodes of one disk are one output") {
  using fabrik::tools::require_distinct_files;
  TempFile base(".blk");
  const std::string a = base.path() + ".a", b = base.path() + ".b", other = base.path() + ".c";
  for (const std::string& p : {a, b, other}) base.also_remove(p);
  if (::mknod(a.c_str(), S_IFBLK | 0600, makedev(7, 0)) != 0) {
    WARN("skipped: no device node can be made here (" << std::strerror(errno) << ")");
    return;
  }
  REQUIRE(::mknod(b.c_str(), S_IFBLK | 0600, makedev(7, 0)) == 0);
  REQUIRE(::mknod(other.c_str(), S_IFBLK | 0600, makedev(7, 1)) == 0);
  CHECK_THROWS_WITH(
      require_distinct_files({{"--json", a}, {"--csv", b}}),
      Catch::Contains("name the same file") && Catch::Contains("one would overwrite the other"));
  CHECK_NOTHROW(require_distinct_files({{"--json", a}, {"--csv", other}}));
  // A disk's number is not read as a terminal's: block (5, 1) is no console.
  const std::string block_five = base.path() + ".d";
  base.also_remove(block_five);
  REQUIRE(::mknod(block_five.c_str(), S_IFBLK | 0600, makedev(5, 1)) == 0);
  CHECK(fabrik::tools::detail::device_number(block_five) == makedev(5, 1));
}

TEST_CASE("An output behind a loop of links is refused with the system's words for it") {
  namespace fs = std::filesystem;
  TempFile a(".json"), b(".json");
  fs::create_symlink(b.path(), a.path());
  fs::create_symlink(a.path(), b.path());
  CHECK_THROWS_WITH(fabrik::tools::require_output_folders({{"--report", a.path()}}),
                    Catch::Contains("too many levels of symbolic links"));
}

TEST_CASE("Without unnamed files, the write check's own file is removed at once") {
  // The fallback for a filesystem without O_TMPFILE (NFS, older overlayfs), asked for here:
  // its file comes and goes under a name of its own, and a folder refusing it is told.
  namespace fs = std::filesystem;
  using fabrik::tools::detail::cannot_make_file_in;
  TempFile marker(".d");
  const fs::path folder = marker.path();
  fs::create_directories(folder);
  const int watch = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  REQUIRE(watch >= 0);
  REQUIRE(::inotify_add_watch(watch, folder.c_str(), IN_CREATE | IN_DELETE) >= 0);
  CHECK(cannot_make_file_in(folder, false).empty());
  const std::vector<std::string> seen = names_seen(watch);
  ::close(watch);
  CHECK(seen.size() == 2);  // made, then removed
  if (seen.size() == 2) {
    CHECK(seen[0].starts_with(".fabrik-write-test-"));
    CHECK(seen[1] == seen[0]);
  }
  CHECK(fs::is_empty(folder));
  CHECK_THAT(cannot_make_file_in(folder / "missing", false),
             Catch::Contains("No such file or directory"));
  CHECK_FALSE(cannot_make_file_in("/proc", false).empty());  // not even root makes files there
  CHECK_FALSE(cannot_make_file_in("/proc").empty());
  fs::remove_all(folder);
}

TEST_CASE("Whole numbers on fabrik's command line are read in decimal") {
  // CLI11 reads integers with strtoll base 0: `--frames 010` ran 8 frames and `--frames 1e1`
  // was "not in range 2 to 10000000".
  const auto frames_of = [](const std::string& text) {
    TempFile json_out(".json");
    const auto [code, err] = fabrik::test::run_fabrik(
        {"bench", "fullbody", "--builtin-only", "--frames", text, "--json"}, json_out.path());
    CAPTURE(text, err);
    REQUIRE(code == 0);
    return json::parse(slurp(json_out.path())).at("motion").at("frames").get<int>();
  };
  CHECK(frames_of("10") == 10);
  CHECK(frames_of("010") == 10);
  CHECK(frames_of("1e1") == 10);
  CHECK(frames_of("10.0") == 10);
  CHECK(frames_of("0x0a") == 10);  // hexadecimal, written on purpose
  for (const auto& [text, said] : std::vector<std::pair<std::string, std::string>>{
           {"2.5", "'2.5' is not a whole number"},
           {" 010", "' 010' is not a whole number"},  // strtoll skipped the blank: 8
           {"+-10", "'+-10' is not a whole number"},
           {"-", "'-' is not a whole number"},
           {"1e16", "'1e16' is too large to write with a point or an exponent"}}) {
    CAPTURE(text);
    const auto [code, err] =
        fabrik::test::run_fabrik({"bench", "fullbody", "--builtin-only", "--frames", text});
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains("--frames: " + said));
  }
}

// Ctrl-C while a tool waits on ZeroMQ: zmq_poll then fails with EINTR whatever SA_RESTART
// says, which cppzmq throws. That once ended `fabrik watch` with "Interrupted system call",
// exit 2 and no summary. Both tools spend nearly all of such a wait in the poll, so the signal
// lands there.
TEST_CASE("Ctrl-C ends fabrik watch and a replay waiting for a subscriber with their summaries, exit 0") {
  using namespace std::chrono_literals;
  const std::string fabrik = FABRIK_PATH;
  {
    // Nobody at the endpoint: the watch waits; its first live line shows it is in its loop.
    TempFile out(".json");
    fabrik::test::Process watch({"/bin/sh", "-c",
                                 "exec '" + fabrik + "' watch --from tcp://127.0.0.1:1 --json > '" +
                                     out.path() + "'"});
    REQUIRE(watch.wait_for_output("(no stats)", 10s));
    watch.signal(SIGINT);
    const std::optional<int> code = watch.wait(10s);
    REQUIRE(code.has_value());
    INFO("stderr: " << watch.stderr_text());
    CHECK(*code == 0);
    CHECK(watch.stderr_text().find("Interrupted") == std::string::npos);
    const json summary = json::parse(fabrik::test::slurp(out.path()), nullptr, false);
    REQUIRE(summary.is_object());
    CHECK(summary["poses"] == 0);
    CHECK(summary["endpoint"] == "tcp://127.0.0.1:1");
  }
  {
    // The replay binds an ipc endpoint (its file appears at the bind, just before the wait).
    TempFile trc(".trc");
    fabrik::io::write_trc(trc.path(), small_trial());
    TempFile endpoint(".ipc");
    fabrik::test::Process replay({fabrik, "replay", trc.path(), "--to", "ipc://" + endpoint.path(),
                                  "--bind", "--wait-subscriber", "60"});
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (!fs::exists(endpoint.path()) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(5ms);  // polling a file, bounded
    REQUIRE(fs::exists(endpoint.path()));
    replay.signal(SIGINT);
    const std::optional<int> code = replay.wait(10s);
    REQUIRE(code.has_value());
    INFO("stderr: " << replay.stderr_text());
    CHECK(*code == 0);
    CHECK_THAT(replay.stderr_text(), Catch::Contains("sent 0 frames") &&
                                         Catch::Contains("stopped by signal"));
  }
}

// ---- Several subjects in one recording (docs/multi-subject.md) ----

TEST_CASE("solve --subject takes one subject of a Subject:Marker C3D, as its own one-person file",
          "[subjects]") {
  const MarkerTrial one = default_model_trial();
  const Eigen::Vector3d bob_offset_m(2.0, 0.0, 0.0);
  // A Vicon-style C3D of two subjects, and Bob alone in a TRC (as Pose2Sim
  // writes one file per person).
  MarkerTrial two = one, bob = one;
  two.labels.clear();
  for (const char* subject : {"Alice", "Bob"})
    for (const std::string& l : one.labels) two.labels.push_back(std::string(subject) + ":" + l);
  two.positions_m.clear();
  for (std::size_t f = 0; f < one.frames(); ++f) {
    for (std::size_t m = 0; m < one.markers(); ++m) two.positions_m.push_back(one.at(f, m));
    for (std::size_t m = 0; m < one.markers(); ++m)
      two.positions_m.push_back(one.at(f, m) + bob_offset_m);
  }
  for (Eigen::Vector3d& p : bob.positions_m) p += bob_offset_m;
  TempFile c3d(".c3d"), trc(".trc"), out_c3d(".trc"), out_trc(".trc"), report_c3d(".json"),
      report_trc(".json");
  fabrik::io::write_c3d(c3d.path(), two, fabrik::io::C3dProcessor::intel, true);
  fabrik::io::write_trc(trc.path(), bob);

  auto [code, err] = run_fabrik({"solve", "--input", c3d.path(), "--subject", "Bob", "--output",
                                 out_c3d.path(), "--report", report_c3d.path(), "--quiet"});
  INFO(err);
  REQUIRE(code == 0);
  auto [code_trc, err_trc] = run_fabrik({"solve", "--input", trc.path(), "--output", out_trc.path(),
                                         "--report", report_trc.path(), "--quiet"});
  INFO(err_trc);
  REQUIRE(code_trc == 0);
  const json r_c3d = json::parse(slurp(report_c3d.path())), r_trc = json::parse(slurp(report_trc.path()));
  CHECK(r_c3d["frames"] == r_trc["frames"]);
  CHECK(r_c3d["residual_mm"]["rms_mean"].get<double>() < 1.0);
  CHECK(r_c3d["residual_mm"]["rms_mean"].get<double>() ==
        Approx(r_trc["residual_mm"]["rms_mean"].get<double>()).margin(0.05));
  // Bob's joint centres, 2 m from Alice's: the same from either file.
  const MarkerTrial j_c3d = fabrik::io::read_trial(out_c3d.path()),
                    j_trc = fabrik::io::read_trial(out_trc.path());
  REQUIRE(j_c3d.positions_m.size() == j_trc.positions_m.size());
  double worst_m = 0.0, mean_x_m = 0.0;
  for (std::size_t i = 0; i < j_c3d.positions_m.size(); ++i) {
    worst_m = std::max(worst_m, (j_c3d.positions_m[i] - j_trc.positions_m[i]).norm());
    mean_x_m += j_c3d.positions_m[i].x() / static_cast<double>(j_c3d.positions_m.size());
  }
  CHECK(worst_m < 1e-3);
  double alice_x_m = 0.0;
  for (const Eigen::Vector3d& p : one.positions_m)
    alice_x_m += p.x() / static_cast<double>(one.positions_m.size());
  CHECK(mean_x_m - alice_x_m == Approx(2.0).margin(0.1));
  // A subject the file does not have: refused, naming those it has.
  auto [code_carol, err_carol] = run_fabrik({"solve", "--input", c3d.path(), "--subject", "Carol",
                                             "--output", out_c3d.path(), "--quiet"});
  CHECK(code_carol != 0);
  CHECK_THAT(err_carol, Catch::Contains("Alice, Bob"));
  // Bob's own config as `fabrik calibrate` writes it from such a file: targets named Bob:X.
  // It once shared no name with Bob's markers (refused, exit 2); it tracks them as the bare one.
  const fabrik::TrackerSetup& bare = fabrik::default_daemon_config().tracker;
  json markers = json::object();
  for (const fabrik::MarkerTarget& t : bare.markers)
    markers["Bob:" + t.marker] = {{"point", bare.model->points[t.point].name}, {"level", t.level}};
  TempFile bob_config(".json"), report_bob(".json");
  std::ofstream(bob_config.path()) << json{{"format", "fabrikd-config/1"},
                                           {"model", "models/fullbody.json"},
                                           {"targets", {{"markers", markers}}}}
                                          .dump();
  auto [code_bob, err_bob] =
      run_fabrik({"solve", "--config", bob_config.path(), "--input", c3d.path(), "--subject", "Bob",
                  "--output", out_c3d.path(), "--report", report_bob.path(), "--quiet"});
  INFO(err_bob);
  REQUIRE(code_bob == 0);
  const json r_bob = json::parse(slurp(report_bob.path()));
  CHECK(r_bob["residual_mm"]["rms_mean"].get<double>() ==
        Approx(r_c3d["residual_mm"]["rms_mean"].get<double>()).margin(1e-6));
}

TEST_CASE("An output that names an input or another output is refused before anything is written") {
  using fabrik::test::run_fabrik;
  using fabrik::test::slurp;
  TempFile trial(".trc"), joints(".trc"), config(".json");
  trial.also_remove(trial.path().substr(0, trial.path().size() - 4) + ".joints.trc");
  REQUIRE(run_fabrik({"synth", "--config", kSourceDir + "/config/default.json", "--output",
                      trial.path(), "--seconds", "0.1"})
              .first == 0);
  std::filesystem::copy_file(kSourceDir + "/config/default.json", config.path());
  const std::string trial_text = slurp(trial.path()), config_text = slurp(config.path());
  const std::vector<std::pair<std::vector<std::string>, std::string>> collisions = {
      {{"solve", "--input", trial.path(), "--output", trial.path(), "--quiet"},
       "--input and --output name the same file"},
      {{"solve", "--input", trial.path(), "--output", joints.path(), "--report", trial.path()},
       "--input and --report name the same file"},
      {{"solve", "--input", trial.path(), "--output", joints.path(), "--markers", joints.path()},
       "--output and --markers name the same file"},
      {{"synth", "--config", trial.path(), "--output", trial.path()},
       "--config and --output name the same file"},
      {{"calibrate", "--template", config.path(), "--static", trial.path(), "--output",
        trial.path()},
       "--static and --output name the same file"},
      // Outputs that would be written wrong (found after the solve, or never written).
      {{"solve", "--input", trial.path(), "--output", joints.path(), "--angles",
        joints.path() + ".trc"},
       "--angles: '" + joints.path() + ".trc': an OpenSim Coordinates table is written: use .mot"},
      {{"solve", "--input", trial.path(), "--output", joints.path() + ".xyz"},
       "--output: '" + joints.path() + ".xyz': unknown output format"},
      {{"synth", "--config", config.path(), "--output", joints.path() + ".csv"},
       "--output: '" + joints.path() + ".csv': synth writes a TRC file: name it .trc"},
      {{"calibrate", "--template", config.path(), "--static", trial.path(), "--output",
        joints.path(), "--lengths-json", joints.path()},
       "--output and --lengths-json name the same file"},
      // Outputs whose folder is missing, or that are folders: found before the work.
      {{"solve", "--input", trial.path(), "--output", joints.path(), "--report",
        joints.path() + ".d/r.json"},
       "--report: '" + joints.path() + ".d/r.json': the folder '" + joints.path() +
           ".d' does not exist"},
      {{"synth", "--config", config.path(), "--output", joints.path() + ".d/s.trc"},
       "--output: '" + joints.path() + ".d/s.trc': the folder '" + joints.path() +
           ".d' does not exist"},
      {{"calibrate", "--template", config.path(), "--static", trial.path(), "--output",
        std::filesystem::temp_directory_path().string()},
       "--output: '" + std::filesystem::temp_directory_path().string() + "' is a folder"},
      // eval's outputs too (one overwrote the other, after minutes on a walk).
      {{"eval", "walk", "--json", joints.path() + ".csv", "--csv", joints.path() + ".csv"},
       "--json and --csv name the same file"},
      {{"eval", "synthetic", "--json", "/proc/self/e.json"},
       "--json: '/proc/self/e.json' cannot be written ("},
      {{"eval", "imu", "--walk", trial.path(), "--json", trial.path()},
       "--walk and --json name the same file"},
      {{"eval", "markerless", "--trial", trial.path(), "--json",
        trial.path().substr(0, trial.path().size() - 4) + ".truth.mot"},
       "--trial's FILE.truth.mot and --json name the same file"},
      // A typo of a device makes no regular file in /dev.
      {{"eval", "synthetic", "--json", "/dev/fabrik-no-such-device"},
       "--json: '/dev/fabrik-no-such-device' cannot be written (no such device in /dev)"},
      // A folder where no file can be made (procfs, even for root, whom access() answers yes):
      // tried before the solve.
      {{"solve", "--input", trial.path(), "--output", joints.path(), "--report",
        "/proc/self/r.json"},
       "--report: '/proc/self/r.json' cannot be written ("},
      {{"calibrate", "--template", config.path(), "--static", trial.path(), "--output",
        joints.path() + ".json", "--lengths-json", joints.path()},
       "--lengths-json goes with --trial (the lengths measured from a keypoint trial) or "
       "--nominal"},
  };
  for (const auto& [args, said] : collisions) {
    CAPTURE(args);
    const auto [code, err] = run_fabrik(args);
    CHECK(code == 2);
    CHECK_THAT(err, Catch::Contains(said));
  }
  CHECK(slurp(trial.path()) == trial_text);
  CHECK(slurp(config.path()) == config_text);
  CHECK_FALSE(std::filesystem::exists(joints.path()));
  CHECK_FALSE(std::filesystem::exists(joints.path() + ".csv"));
  CHECK_FALSE(std::filesystem::exists("/dev/fabrik-no-such-device"));
  // A config's sensors recalibrated in place is not a collision (this one has none to calibrate).
  const auto [in_place_code, in_place_err] =
      run_fabrik({"calibrate", "--config", config.path(), "--static-orientations", "s.sto",
                  "--output", config.path()});
  CHECK(in_place_code == 2);
  CHECK_THAT(in_place_err, Catch::Contains("has no \"sensors\" to calibrate") &&
                               !Catch::Contains("the same file"));
}

TEST_CASE("Outputs to one file or device are refused, to /dev/null not, in any format") {
  using fabrik::tools::NamedFile;
  using fabrik::tools::require_distinct_files;
  TempFile file(".json");
  std::ofstream(file.path()) << "{}";
  CHECK_THROWS_WITH(require_distinct_files({{"--output", file.path()}, {"--report", file.path()}}),
                    Catch::Contains("--output and --report name the same file"));
  CHECK_THROWS_WITH(
      require_distinct_files({{"--input", file.path(), false}, {"--report", file.path()}}),
      Catch::Contains("the output would overwrite the other"));
  CHECK_NOTHROW(
      require_distinct_files({{"--input", file.path(), false}, {"--config", file.path(), false}}));
  // Discarding two outputs was refused as "the same file".
  CHECK_NOTHROW(
      require_distinct_files({{"--output", "/dev/null"}, {"--lengths-json", "/dev/null"}}));
  // Another device (a terminal, as /dev/stdout is on one; /dev/zero stands for it here) named
  // by two outputs would take both, under any of its names; an input may share it.
  CHECK_THROWS_WITH(require_distinct_files({{"--json", "/dev/zero"}, {"--csv", "/dev/zero"}}),
                    Catch::Contains("--json and --csv name the same device ('/dev/zero')"));
  const std::filesystem::path link = file.path() + ".zero";
  file.also_remove(link.string());
  std::filesystem::create_symlink("/dev/zero", link);
  CHECK_THROWS_WITH(require_distinct_files({{"--json", "/dev/zero"}, {"--csv", link.string()}}),
                    Catch::Contains("the same device ('/dev/zero' and '" + link.string() + "')"));
  std::filesystem::remove(link);
  CHECK_NOTHROW(require_distinct_files({{"--input", "/dev/zero", false}, {"--csv", "/dev/zero"}}));
  CHECK_NOTHROW(require_distinct_files({{"--csv", "/dev/zero"}, {"--input", "/dev/zero", false}}));
  CHECK_NOTHROW(require_distinct_files({{"--json", "/dev/zero"}, {"--csv", "/dev/null"}}));
  // A node of its own for a device is that device (/dev/null's too is /dev/null). Making one
  // takes root (CAP_MKNOD), as these tests have here and in CI.
  const std::string zero_node = file.path() + ".zero-node", null_node = file.path() + ".null-node";
  file.also_remove(zero_node);
  file.also_remove(null_node);
  struct stat zero {};
  REQUIRE(::stat("/dev/zero", &zero) == 0);
  if (::mknod(zero_node.c_str(), S_IFCHR | 0600, zero.st_rdev) == 0) {
    CHECK_THROWS_WITH(require_distinct_files({{"--json", "/dev/zero"}, {"--csv", zero_node}}),
                      Catch::Contains("name the same device"));
    std::filesystem::remove(zero_node);
    struct stat null {};
    REQUIRE(::stat("/dev/null", &null) == 0);
    REQUIRE(::mknod(null_node.c_str(), S_IFCHR | 0600, null.st_rdev) == 0);
    CHECK_NOTHROW(require_distinct_files({{"--json", null_node}, {"--csv", null_node}}));
    std::filesystem::remove(null_node);
  } else {
    WARN("skipped: no device node can be made here (" << std::strerror(errno) << ")");
  }
  // So would a pipe (/dev/stdout piped on).
  const std::string pipe = file.path() + ".fifo";
  file.also_remove(pipe);
  REQUIRE(::mkfifo(pipe.c_str(), 0600) == 0);
  CHECK_THROWS_WITH(require_distinct_files({{"--json", pipe}, {"--csv", pipe}}),
                    Catch::Contains("name the same pipe"));
  CHECK_NOTHROW(require_distinct_files({{"--input", pipe, false}, {"--csv", pipe}}));
  std::filesystem::remove(pipe);
  // A link to nothing names the file a write would make where it points.
  const std::string target = file.path() + ".target.json", dangling = file.path() + ".link.json";
  file.also_remove(dangling);
  std::filesystem::create_symlink(std::filesystem::path(target).filename(), dangling);
  CHECK_THROWS_WITH(require_distinct_files({{"--json", dangling}, {"--csv", target}}),
                    Catch::Contains("name the same file"));
  std::filesystem::remove(dangling);
  // ... and solve's extension checks refused /dev/null ("unknown output format").
  TempFile trial(".trc"), report(".json");
  trial.also_remove(trial.path().substr(0, trial.path().size() - 4) + ".joints.trc");
  REQUIRE(fabrik::test::run_fabrik({"synth", "--config", kSourceDir + "/config/default.json",
                                    "--output", trial.path(), "--seconds", "0.05"})
              .first == 0);
  const auto [code, err] = fabrik::test::run_fabrik(
      {"solve", "--input", trial.path(), "--output", "/dev/null", "--angles", "/dev/null",
       "--markers", "/dev/null", "--report", report.path(), "--quiet"});
  CAPTURE(err);
  CHECK(code == 0);
  CHECK(json::parse(slurp(report.path())).at("frames").get<int>() == 5);
  CHECK(std::filesystem::is_character_file("/dev/null"));
  // --markers /dev/null discards the markers and their list of filled runs: a FILE.filled.csv
  // beside a device would be a regular file in /dev.
  CHECK_FALSE(std::filesystem::exists("/dev/null.filled.csv"));
  // A pipe takes the joints as a TRC, as a terminal does: /dev/stdout piped on was refused
  // ("unknown output format") where a terminal was not.
  TempFile piped(".trc");
  fabrik::test::Process solve({"/bin/sh", "-c",
                               "'" + std::string(FABRIK_PATH) + "' solve --input '" + trial.path() +
                                   "' --output /dev/stdout --quiet | cat > '" + piped.path() +
                                   "'"});
  REQUIRE(solve.wait(std::chrono::seconds(60)).has_value());
  CAPTURE(solve.stderr_text());
  CHECK(slurp(piped.path()).starts_with("PathFileType"));
}

TEST_CASE("fabrik solve takes samples beyond input.max_abs_coordinate_mm as missing, as fabrikd") {
  using fabrik::test::run_fabrik;
  using fabrik::test::slurp;
  TempFile trial(".trc"), huge(".trc"), joints(".csv"), report(".json");
  trial.also_remove(trial.path().substr(0, trial.path().size() - 4) + ".joints.trc");
  REQUIRE(run_fabrik({"synth", "--config", kSourceDir + "/config/default.json", "--output",
                      trial.path(), "--seconds", "0.2"})
              .first == 0);
  MarkerTrial t = fabrik::io::read_trial(trial.path());
  for (std::size_t f = 0; f < 10; ++f) {
    for (std::size_t m = 0; m < t.markers(); ++m) t.at(f, m).setConstant(1e9);  // 1e6 km
    t.at(10 + f, 1) = Eigen::Vector3d(0.5, -150.0, 0.5);  // 150 m: beyond the default 100
  }
  const std::size_t beyond = 10 * t.markers() + 10;
  fabrik::io::write_trc(huge.path(), t);
  const auto [code, err] = run_fabrik({"solve", "--input", huge.path(), "--output", joints.path(),
                                       "--report", report.path(), "--quiet"});
  CAPTURE(err);
  REQUIRE(code == 0);
  CHECK_THAT(err, Catch::Contains("warning: " + std::to_string(beyond) +
                                  " samples farther than input.max_abs_coordinate_mm"));
  const json r = json::parse(slurp(report.path()));
  CAPTURE(r.dump());
  CHECK(r["frames_without_markers"] == 10);  // were solved to the 1e300 "markers"
  CHECK(r["residual_mm"]["rms_max"].get<double>() < 20.0);
}

// ---- Orientation tables (OpenSense .sto) in fabrik solve ----

TEST_CASE(
    "An orientation table's bad cell is missing for its sensor only, a time going back is "
    "refused") {
  TempFile sto(".sto"), back(".sto"), numbers(".mot");
  const std::string header = "DataRate=100\nDataType=Quaternion\nversion=3\nendheader\n";
  // Lines 6 to 11; a_imu: empty, 3 numbers, 5 numbers; b_imu: abc, not unit.
  std::ofstream(sto.path()) << header
                            << "time\ta_imu\tb_imu\n"
                               "0\t1,0,0,0\t1,0,0,0\n"
                               "0.01\t\t1,0,0,0\n"
                               "0.02\t1,0,0\t1,0,0,0\n"
                               "0.03\t1,0,0,0,0\tabc\n"
                               "0.04\t1,0,0,0\t1.05,0,0,0\n"
                               "0.05\t1,0,0,0\t0,1,0,0\n";
  const fabrik::io::OrientationTable t = fabrik::io::read_orientation_table(sto.path());
  REQUIRE(t.rows() == 6);
  CHECK(t.time_s[1] == 0.01);
  const std::vector<bool> a_missing = {false, true, true, true, false, false};
  const std::vector<bool> b_missing = {false, false, false, true, true, false};
  for (std::size_t r = 0; r < 6; ++r) {
    CAPTURE(r);
    CHECK(!t.at(r, 0).coeffs().allFinite() == a_missing[r]);
    CHECK(!t.at(r, 1).coeffs().allFinite() == b_missing[r]);
  }
  CHECK(t.at(5, 1).x() == 1.0);
  REQUIRE(t.warnings.size() == 2);
  CHECK(t.warnings[0] ==
        "4 cells (the first on line 7, column a_imu) are not 4 numbers: read as missing, their "
        "rows kept");
  CHECK(t.warnings[1] ==
        "1 quaternions are not finite or not of unit length (within 0.01): missing for their "
        "sensor only");
  // The join reaches half a sample period beyond the rows, no farther.
  CHECK(t.covers(-0.005));
  CHECK(t.covers(0.055));
  CHECK_FALSE(t.covers(0.0551));
  CHECK_FALSE(t.covers(NAN));

  // A first row whose first cell is "nan" (a sensor not streaming yet): the table's cells are
  // quaternions all the same (its DataType says so), that cell missing.
  TempFile late_start(".sto");
  std::ofstream(late_start.path()) << header
                                   << "time\ta_imu\tb_imu\n0\tnan\t1,0,0,0\n"
                                      "0.01\t1,0,0,0\t1,0,0,0\n";
  const fabrik::io::OrientationTable l = fabrik::io::read_orientation_table(late_start.path());
  REQUIRE(l.rows() == 2);
  CHECK_FALSE(l.at(0, 0).coeffs().allFinite());
  CHECK(l.at(0, 1).w() == 1.0);
  CHECK(l.at(1, 0).w() == 1.0);

  // OpenSense's dropout, nan in all four, is said too (it was silent); a tab ending every row
  // is no extra cell (every row was left out, then the file refused as "0 rows, not
  // quaternions").
  TempFile dropout(".sto");
  std::ofstream(dropout.path()) << header
                                << "time\ta_imu\tb_imu\t\n0\t1,0,0,0\t1,0,0,0\t\n"
                                   "0.01\t1,0,0,0\tnan,nan,nan,nan\t\n"
                                   "0.02\tNaN,NaN,NaN,NaN\tnan,nan,nan,nan\t\n";
  const fabrik::io::OrientationTable d = fabrik::io::read_orientation_table(dropout.path());
  REQUIRE(d.rows() == 3);
  CHECK(d.at(0, 1).w() == 1.0);
  CHECK_FALSE(d.at(1, 1).coeffs().allFinite());
  CHECK(d.warnings ==
        std::vector<std::string>{"3 cells are nan (the first at 0.01 s, column b_imu): missing for "
                                 "their sensor only"});
  // A table whose every row is left out says why, not that it holds no quaternions.
  TempFile no_rows(".sto");
  std::ofstream(no_rows.path()) << header << "time\ta_imu\n0\t1,0,0,0\t1\n0.01\t1,0,0,0\t1\n";
  REQUIRE_THROWS_WITH(fabrik::io::read_orientation_table(no_rows.path()),
                      no_rows.path() +
                          ": has no row that could be read: 2 rows left out (the "
                          "first on line 6): a different number of fields than "
                          "the 2 labels, no time, or a cell that is not a number");

  // Two rows swapped (lines 7 and 8), as the TRC reader refuses them.
  std::ofstream(back.path()) << header
                             << "time\ta_imu\n0\t1,0,0,0\n0.02\t1,0,0,0\n0.01\t1,0,0,0\n"
                                "0.03\t1,0,0,0\n";
  REQUIRE_THROWS_WITH(
      fabrik::io::read_orientation_table(back.path()),
      Catch::StartsWith(back.path() + ": the time column goes back in time at 1 row (the first "
                                      "at line 8: 0.01 s after 0.02 s at line 7)") &&
          Catch::Contains("Fix: put the rows in time order"));
  // A table of numbers is still no orientation table.
  std::ofstream(numbers.path()) << "version=3\nendheader\ntime\tknee\n0\t1\n0.01\t2\n";
  REQUIRE_THROWS_WITH(
      fabrik::io::read_orientation_table(numbers.path()),
      Catch::Contains("holds numbers in 2 columns") && Catch::Contains("not quaternions"));
}

namespace {

// The OpenSense placement table's one row as `rows` rows at 100 Hz from `first_s`, its
// label line with `from` renamed `to` (when given).
std::string placement_rows(std::size_t rows, double first_s, const std::string& from = "",
                           const std::string& to = "") {
  std::istringstream in(slurp(kDataDir + "/opensense_placement_orientations.sto"));
  std::string text, line;
  while (std::getline(in, line) && line != "endheader") text += line + "\n";
  std::string labels, row;
  std::getline(in, labels);
  std::getline(in, row);
  if (!from.empty()) labels.replace(labels.find(from), from.size(), to);
  text += "endheader\n" + labels + "\n";
  const std::string cells = row.substr(row.find('\t'));
  for (std::size_t r = 0; r < rows; ++r)
    text += std::to_string(first_s + static_cast<double>(r) / 100.0) + cells + "\n";
  return text;
}

}  // namespace

TEST_CASE(
    "fabrik solve --orientations: says what it cannot join, refuses what would change "
    "nothing") {
  const std::string static_trc = kDataDir + "/subject01_static.trc";
  if (!fs::exists(static_trc)) {
    WARN("skipped: " << static_trc << " not found");
    return;
  }
  TempFile config(".json"), walk(".sto"), renamed(".sto"), late(".sto"), joints(".trc"),
      report(".json"), text(".txt");
  REQUIRE(run_fabrik(
              {"calibrate", "--template", kSourceDir + "/config/templates/opensense_gait2354.json",
               "--static", static_trc, "--static-orientations",
               kDataDir + "/opensense_placement_orientations.sto", "--output", config.path()})
              .first == 0);
  std::ofstream(walk.path()) << placement_rows(100, 0.0);  // 0 to 0.99 s
  std::ofstream(renamed.path()) << placement_rows(100, 0.0, "calcn_l_imu", "foo_imu");
  std::ofstream(late.path()) << placement_rows(100, 10.0);  // 10 to 10.99 s

  SECTION("--filter-hz without markers is refused: it low-passes markers") {
    const auto [code, err] =
        run_fabrik({"solve", "--config", config.path(), "--orientations", walk.path(), "--output",
                    joints.path(), "--filter-hz", "6", "--quiet"});
    CHECK(code == 2);
    CHECK_THAT(err, Catch::StartsWith("fabrik solve: --filter-hz low-passes the markers "
                                      "(--input), and there are none") &&
                        Catch::Contains("Fix: leave out --filter-hz"));
    CHECK_FALSE(fs::exists(joints.path()));
  }
  SECTION("a configured sensor the table lacks is named in the summary and the report") {
    const auto [code, err] =
        run_fabrik({"solve", "--config", config.path(), "--orientations", renamed.path(),
                    "--output", joints.path(), "--report", report.path(), "--quiet"},
                   text.path());
    CAPTURE(err);
    REQUIRE(code == 0);
    CHECK_THAT(slurp(text.path()),
               Catch::Contains("not in the table   1 of 8 configured sensors (calcn_l_imu)") &&
                   Catch::Contains("not tracked        1 table column (foo_imu)") &&
                   // Orientations alone: said once, not as 41 markers "not in the trial", a fit
                   // quality of none and 0 outliers of markers never given.
                   Catch::Contains("frames            100 (orientations alone, no marker input)"));
    CHECK_THAT(slurp(text.path()),
               !Catch::Contains("not in the trial") && !Catch::Contains("fit quality") &&
                   !Catch::Contains("outliers") && !Catch::Contains("marker residual"));
    CHECK(json::parse(slurp(report.path()))["quality"]["none"] == 100);  // the report's count
    const json r = json::parse(slurp(report.path()));
    CHECK(r["orientations"]["sensors_missing_in_table"] == json::array({"calcn_l_imu"}));
    CHECK(r["orientations"]["table_columns_not_used"] == json::array({"foo_imu"}));
  }
  SECTION("a configured sensor whose column has no usable cell is missing too") {
    // calcn_l_imu's column kept, every cell of it "nan" (a sensor that never streamed).
    std::istringstream in(placement_rows(100, 0.0));
    std::string out, line;
    std::size_t column = 0;
    bool table = false;
    while (std::getline(in, line)) {
      std::vector<std::string> fields;
      std::istringstream cells(line);
      for (std::string f; std::getline(cells, f, '\t');) fields.push_back(f);
      if (table && column == 0) {
        column = static_cast<std::size_t>(std::find(fields.begin(), fields.end(), "calcn_l_imu") -
                                          fields.begin());
        REQUIRE(column < fields.size());
      } else if (table) {
        fields[column] = "nan,nan,nan,nan";
      }
      table = table || line == "endheader";
      for (std::size_t k = 0; k < fields.size(); ++k) out += (k ? "\t" : "") + fields[k];
      out += "\n";
    }
    TempFile silent(".sto");
    std::ofstream(silent.path()) << out;
    const auto [code, err] =
        run_fabrik({"solve", "--config", config.path(), "--orientations", silent.path(), "--output",
                    joints.path(), "--report", report.path(), "--quiet"},
                   text.path());
    CAPTURE(err);
    REQUIRE(code == 0);
    CHECK_THAT(slurp(text.path()),
               Catch::Contains("not in the table   1 of 8 configured sensors (calcn_l_imu)"));
    const json r = json::parse(slurp(report.path()));
    CHECK(r["orientations"]["sensors_missing_in_table"] == json::array({"calcn_l_imu"}));
  }
  SECTION("a table beside the marker trial in time is refused, one covering part is warned") {
    const auto [code, err] =
        run_fabrik({"solve", "--config", config.path(), "--input", static_trc, "--orientations",
                    late.path(), "--output", joints.path(), "--quiet"});
    CHECK(code == 2);
    CHECK_THAT(err, Catch::StartsWith("fabrik solve: " + late.path() +
                                      ": no marker frame falls within its time span: the "
                                      "markers (" +
                                      static_trc +
                                      ") span 0 to 4.98333333 s, "
                                      "the orientations 10 to 10.99 s. Fix: "));
    CHECK_FALSE(fs::exists(joints.path()));
    // 0 to 0.99 s (0.995 s with half a sample): frames 1 to 60 of 300 at 60 Hz.
    const auto [part_code, part_err] =
        run_fabrik({"solve", "--config", config.path(), "--input", static_trc, "--orientations",
                    walk.path(), "--output", joints.path(), "--report", report.path(), "--quiet"});
    CAPTURE(part_err);
    CHECK(part_code == 0);
    // In the report too, for a batch that reads no stderr.
    const json r = json::parse(slurp(report.path()));
    REQUIRE(r["warnings"].size() == 1);
    CHECK_THAT(r["warnings"][0].get<std::string>(),
               Catch::StartsWith(walk.path() + ": 240 of 300 marker frames fall outside"));
    CHECK_THAT(part_err, Catch::Contains("fabrik solve: warning: " + walk.path() +
                                         ": 240 of 300 marker frames fall outside its time "
                                         "span") &&
                             Catch::Contains("they are tracked without orientations"));
    // fabrik replay joins them the same way: refused before it streams anything.
    const auto [replay_code, replay_err] =
        run_fabrik({"replay", static_trc, "--orientations", late.path(), "--to",
                    "ipc://" + (fs::temp_directory_path() / "fabrik-late-replay").string()});
    CHECK(replay_code == 2);
    CHECK_THAT(replay_err, Catch::Contains(late.path() + ": no marker frame falls within its "
                                                         "time span"));
  }
}
