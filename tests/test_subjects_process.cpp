// The split (docs/multi-subject.md): subjects spread across fabrikd
// processes that subscribe to the same stream. The test binds the source's
// PUB; two fabrikd processes, each with a subset of the subjects, connect to
// it; each publishes only its own subjects' poses, and every frame is
// answered once per subject. Every wait is bounded.
#include <catch2/catch.hpp>
#include <chrono>
#include <map>
#include <set>

#include "process.hpp"
#include "socket_client.hpp"
#include "subjects_fixture.hpp"

using namespace fabrik;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kFabrikd =
    std::getenv("FABRIKD_UNDER_TEST") ? std::getenv("FABRIKD_UNDER_TEST") : FABRIKD_PATH;

// (topic, frame) of every pose that arrives on `sub` within `timeout`.
void collect(zmq::socket_t& sub, std::chrono::milliseconds timeout,
             std::set<std::pair<std::string, std::uint64_t>>& out) {
  zmq::pollitem_t items[] = {{sub.handle(), 0, ZMQ_POLLIN, 0}};
  zmq::poll(items, 1, timeout);
  zmq::message_t t, p;
  while (sub.recv(t, zmq::recv_flags::dontwait)) {
    if (!t.more() || !sub.recv(p, zmq::recv_flags::dontwait)) continue;
    const json pose = test::decode_payload(p);
    out.insert({std::string(t.to_string_view()), pose["frame"].get<std::uint64_t>()});
  }
}

}  // namespace

TEST_CASE("Subjects split across two fabrikd processes on one stream: each publishes its own, "
          "every frame answered",
          "[subjects][fabrikd][split]") {
  test::SubjectsDir dir;
  const std::string base = dir.write_file("x", json::object());  // a path in the scratch folder
  const std::string source = "ipc://" + base + "-source";
  const std::vector<std::string> all{"A", "B", "C", "D"};
  const std::vector<std::vector<std::string>> split{{"A", "B"}, {"C", "D"}};
  // Each process: its subjects, input connected to the test's source, its own output.
  std::vector<std::string> outputs, configs;
  for (std::size_t p = 0; p < split.size(); ++p) {
    outputs.push_back("ipc://" + base + "-out" + std::to_string(p));
    configs.push_back(dir.write(split[p], {{"input", {{"endpoint", source}, {"mode", "connect"}}},
                                           {"output", {{"endpoint", outputs[p]}}},
                                           {"stats_interval_s", 0.1}}));
  }
  zmq::context_t context;
  zmq::socket_t pub(context, zmq::socket_type::pub);
  pub.set(zmq::sockopt::linger, 0);
  pub.bind(source);
  std::vector<std::unique_ptr<test::Process>> daemons;
  std::vector<zmq::socket_t> subs;
  for (std::size_t p = 0; p < split.size(); ++p) {
    daemons.push_back(std::make_unique<test::Process>(
        std::vector<std::string>{kFabrikd, "--config", configs[p]}));
    REQUIRE(daemons.back()->wait_for_output("markers in on", 5s));
    subs.emplace_back(context, zmq::socket_type::sub);
    subs.back().set(zmq::sockopt::linger, 0);
    subs.back().set(zmq::sockopt::subscribe, "pose");
    subs.back().connect(outputs[p]);
  }
  // Every subject's markers, subject k at subject_offset_m(k).
  const DaemonConfig one = load_daemon_config_file(configs[0]);
  const TrackerSetup& setup = one.subjects[0].tracker;
  SyntheticMotion motion(*setup.model, MotionSettings{});
  const auto send = [&](std::uint64_t frame, double t_s, std::size_t first_subject = 0) {
    json markers = json::object();
    for (std::size_t k = first_subject; k < all.size(); ++k)
      markers = test::subject_markers(setup, motion, t_s, test::subject_offset_m(static_cast<int>(k)),
                                      all[k] + ":", markers);
    const std::string payload = json{{"frame", frame}, {"time", t_s}, {"markers", markers}}.dump();
    pub.send(zmq::buffer(std::string_view("markers")), zmq::send_flags::sndmore);
    pub.send(zmq::buffer(payload));
  };
  // Handshake: probes until both processes answer (connections are asynchronous).
  std::vector<std::set<std::pair<std::string, std::uint64_t>>> seen(split.size());
  bool joined = false;
  const std::uint64_t first_probe = 1000000;
  int probes = 0;
  for (; probes < 600 && !joined; ++probes) {
    send(first_probe + static_cast<std::uint64_t>(probes), probes * 0.001);
    for (std::size_t p = 0; p < split.size(); ++p) collect(subs[p], 25ms, seen[p]);
    joined = !seen[0].empty() && !seen[1].empty();
  }
  REQUIRE(joined);
  for (std::size_t p = 0; p < split.size(); ++p) {
    collect(subs[p], 300ms, seen[p]);  // answers to probes still in flight
    seen[p].clear();
  }
  // The frames: each answered by its subjects' poses, from their process only.
  const std::uint64_t first = 2000000;
  const int n = 100;
  for (int i = 0; i < n; ++i) {
    const std::uint64_t frame = first + static_cast<std::uint64_t>(i);
    send(frame, 1.0 + i / 240.0);
    // Paced: wait (bounded) for this frame's four poses before the next.
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    const auto answered = [&] {
      for (std::size_t p = 0; p < split.size(); ++p)
        for (const std::string& name : split[p])
          if (!seen[p].count({"pose/" + name, frame})) return false;
      return true;
    };
    while (!answered() && std::chrono::steady_clock::now() < deadline)
      for (std::size_t p = 0; p < split.size(); ++p) collect(subs[p], 5ms, seen[p]);
    REQUIRE(answered());
  }
  for (std::size_t p = 0; p < split.size(); ++p) collect(subs[p], 200ms, seen[p]);
  for (std::size_t p = 0; p < split.size(); ++p) {
    std::set<std::pair<std::string, std::uint64_t>> expected, answered;
    for (const std::string& name : split[p])
      for (int i = 0; i < n; ++i) expected.insert({"pose/" + name, first + static_cast<std::uint64_t>(i)});
    // A probe's answer may still come in late on a loaded host: its subjects are checked, its
    // frame is not one of these.
    CAPTURE(p);
    std::set<std::string> own;
    for (const std::string& name : split[p]) own.insert("pose/" + name);
    for (const auto& [topic, frame] : seen[p]) {
      CAPTURE(topic, frame);
      CHECK(own.count(topic) == 1);
      const bool probe = frame >= first_probe && frame < first_probe + probes;
      if (!probe) answered.insert({topic, frame});
    }
    CHECK(answered == expected);  // its own subjects, every measured frame, nothing else
  }
  // While A and B are out of the volume, frames of C and D alone: the second
  // process answers them; to the first they are another process's frames,
  // not a stream whose names do not fit its config (no mismatch warning).
  const std::uint64_t later = first + 1000;
  for (int i = 0; i < 30; ++i) {
    send(later + static_cast<std::uint64_t>(i), 2.0 + i / 240.0, 2);
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (!seen[1].count({"pose/D", later + static_cast<std::uint64_t>(i)}) &&
           std::chrono::steady_clock::now() < deadline)
      collect(subs[1], 5ms, seen[1]);
    REQUIRE(seen[1].count({"pose/D", later + static_cast<std::uint64_t>(i)}));
  }
  collect(subs[0], 200ms, seen[0]);
  CHECK_FALSE(daemons[0]->wait_for_output("share none", 500ms));  // reads its log so far
  // The other process's subjects are reported once each, not per marker.
  for (std::size_t p = 0; p < split.size(); ++p) {
    const std::string other = split[1 - p][0];
    CHECK(daemons[p]->wait_for_output("subject '" + other + "' is not in the config", 2s));
    CHECK(daemons[p]->count("not in the model") == 0);
  }
  for (auto& d : daemons) {
    d->signal(SIGTERM);
    CHECK(d->wait(5s) == 0);
  }
}
