// The `fabrik replay|watch|synth` cores: synthetic trials with gaps, replay onto a SUB socket
// (inproc and tcp, JSON and MessagePack), --drop parsing, and the watch decoder and tally.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <thread>
#include <zmq_addon.hpp>

#include "io/marker_trial.hpp"
#include "temp_file.hpp"
#include "tools/replay.hpp"
#include "tools/synth.hpp"
#include "tools/watch.hpp"
#include "tools/wire.hpp"

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

TEST_CASE("replay rejects a drop of a marker that is not in the recording") {
  zmq::context_t context;
  ReplayOptions o = fast_options("inproc://nobody");
  o.drops = {parse_drop_spec("RASI:0:1")};
  CHECK_THROWS_WITH(replay_trial(context, small_trial(), o),
                    Catch::Contains("'RASI' is not in the recording"));
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
