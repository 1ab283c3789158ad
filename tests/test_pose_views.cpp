// Pose views (output.views): a subscriber chooses what its poses carry by
// subscribing to a view's topic; the daemon encodes a view only while a
// subscription selects it, and stops when its last subscriber goes.
#include <catch2/catch.hpp>
#include <chrono>
#include <optional>
#include <spdlog/spdlog.h>
#include <string>

#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/resources.hpp"
#include "daemon_thread.hpp"
#include "socket_client.hpp"
#include "subjects_fixture.hpp"
#include "synth/synthetic_motion.hpp"
#include "transport/subscription_book.hpp"

using namespace fabrik;
using namespace std::chrono_literals;
using json = nlohmann::json;

using test::subscriber;

namespace {

DaemonConfig config_with_views(const json& output) {
  json root{{"format", "fabrikd-config/1"}, {"model", "models/fullbody.json"}, {"output", output}};
  return load_daemon_config(root.dump(), "views.json");
}

// The message ConfigError gives for `output`, or "" when it loads.
std::string config_error(const json& output) {
  try {
    (void)config_with_views(output);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

DaemonConfig on_free_ports(DaemonConfig c) {
  c.input = {"tcp://127.0.0.1:*", SocketMode::bind};
  c.output = {"tcp://127.0.0.1:*", SocketMode::bind};
  c.stats_interval_s = 0.02;
  spdlog::set_level(spdlog::level::err);
  return c;
}

// The view of frame `frame` on `sub` (views of earlier frames may still be queued), or
// nothing after 5 s.
std::optional<json> view_of(zmq::socket_t& sub, const std::string& topic, std::uint64_t frame) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < deadline) {
    auto m = test::receive_topic(sub, topic, 100ms);
    if (m && test::decode_payload(*m)["frame"] == frame) return test::decode_payload(*m);
  }
  return std::nullopt;
}

// stats.views[topic][key] of the first stats for which `done` holds while
// frames keep coming (so the loop keeps serving), or nothing after 5 s.
template <class Done>
std::optional<json> view_stats_until(test::SocketClient& client, std::uint64_t& frame,
                                     Done done) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < deadline) {
    client.send_frame(++frame);
    auto stats = client.receive("stats", 100ms);
    if (stats && stats->contains("views") && done((*stats)["views"])) return (*stats)["views"];
  }
  return std::nullopt;
}

}  // namespace

TEST_CASE("output.views reads each view's topic, parts, measured switch, encoding and units",
          "[views][config]") {
  const DaemonConfig c = config_with_views(
      {{"encoding", "msgpack"},
       {"units", "mm"},
       {"views", json::array({{{"topic", "joints"}, {"pose_content", {"angles"}}},
                              {{"topic", "lab.full"},
                               {"pose_content", {"segments", "gap_s"}},
                               {"measured_markers", true},
                               {"encoding", "json"},
                               {"units", "m"}}})}});
  REQUIRE(c.output_views.size() == 2);
  CHECK(c.output_views[0].topic == "joints");
  CHECK(c.output_views[0].content == PoseContent::none().with(PosePart::angles));
  CHECK_FALSE(c.output_views[0].measured_markers);
  CHECK(c.output_views[0].encoding == Encoding::msgpack);  // output.encoding's
  CHECK(c.output_views[1].content ==
        PoseContent::none().with(PosePart::segments).with(PosePart::gap_s));
  CHECK(c.output_views[1].measured_markers);
  CHECK(c.output_views[1].encoding == Encoding::json);
  CHECK(c.output_views[0].units == "mm");  // output.units
  CHECK(c.output_views[1].units == "m");
  CHECK(config_with_views({{"units", "m"}, {"views", json::array({{{"topic", "j"}}})}})
            .output_views[0]
            .units == "m");
  CHECK(config_with_views(json::object()).output_views.empty());  // none by default
}

TEST_CASE("A view topic that a subscriber of pose, stats, model or another view would also "
          "receive is refused with the reason",
          "[views][config]") {
  const auto view = [](const std::string& topic) {
    return json{{"views", json::array({{{"topic", topic}}})}};
  };
  CHECK(config_error(view("joints")).empty());
  for (const char* topic : {"pose", "pose2", "p", "posed", "stats.lean", "model", "mark", ""}) {
    CAPTURE(topic);
    CHECK_THAT(config_error(view(topic)), Catch::Contains("cannot be used"));
  }
  CHECK_THAT(config_error(view("has space")), Catch::Contains("letters, digits"));
  CHECK_THAT(config_error(view(std::string(33, 'j'))), Catch::Contains("1 to 32"));
  CHECK_THAT(config_error({{"views", json::array({{{"topic", "joints"}},
                                                   {{"topic", "joints.fast"}}})}}),
             Catch::Contains("start alike"));
  CHECK_THAT(config_error({{"views", json::array({{{"topic", "j"}, {"units", "cm"}}})}}),
             Catch::Contains("unknown unit 'cm'"));
  CHECK_THAT(config_error({{"views", json::array({{{"topic", "j"}, {"axes", "y_up"}}})}}),
             Catch::Contains("axes"));
  const auto with_axes = [](const json& axes) {
    return json{{"views", json::array({{{"topic", "j"}, {"axes", axes}}})}};
  };
  CHECK(config_error(with_axes({{"up", "+z"}, {"forward", "-y"}})).empty());
  CHECK(config_error(with_axes({{"up", "z"}})).empty());  // forward +x
  CHECK_THAT(config_error(with_axes({{"up", "x"}})), Catch::Contains("no forward axis"));
  CHECK_THAT(config_error(with_axes({{"up", "+w"}})), Catch::Contains("not an axis"));
  CHECK_THAT(config_error(with_axes({{"up", "z"}, {"forward", "-z"}})),
             Catch::Contains("forward is along the up axis"));
  CHECK_THAT(config_error({{"views", json::array({{{"topic", "j"}, {"pose_content", {"wings"}}}})}}),
             Catch::Contains("unknown pose part 'wings'"));
  json many = json::array();
  for (int i = 0; i < 17; ++i) many.push_back({{"topic", "v" + std::to_string(i) + "x"}});
  CHECK_THAT(config_error({{"views", many}}), Catch::Contains("at most 16"));
}

// ZeroMQ's own unsubscription (no descriptor), as for a subscriber gone.
static void zeromq_unsubscribes(wire::SubscriptionBook& book, std::string_view prefix) {
  book.unsubscribed(prefix, {}, [](const wire::SubscriptionSender&) { return true; });
}

TEST_CASE("A subscription selects a view when it starts the view's topic and is no start of "
          "the daemon's own topics",
          "[views]") {
  wire::SubscriptionBook book;
  book.subscribed("");
  book.subscribed("p");
  book.subscribed("pose");
  CHECK(book.selecting("joints") == 0);  // every topic, or every pose: not a view's choice
  book.subscribed("jo");
  book.subscribed("joints");
  book.subscribed("joints");
  CHECK(book.selecting("joints") == 3);
  CHECK(book.selecting("joints/alice") == 3);
  CHECK(book.selecting("lean") == 0);
  zeromq_unsubscribes(book, "joints");
  zeromq_unsubscribes(book, "never-counted");
  CHECK(book.selecting("joints") == 2);
  zeromq_unsubscribes(book, "joints");
  zeromq_unsubscribes(book, "joints");  // one more than was made: stays at none
  zeromq_unsubscribes(book, "jo");
  CHECK(book.selecting("joints") == 0);
  book.subscribed("joints/alice");
  CHECK(book.selecting("joints/alice") == 1);
  CHECK(book.selecting("joints/bob") == 0);
}

TEST_CASE("A connection's unsubscription counts only against what it subscribed to",
          "[views][subscriptions]") {
  using Kind = wire::SubscriptionSender::Kind;
  wire::SubscriptionBook book;
  const wire::SubscriptionSender b{Kind::connection, 7, 1001}, raw{Kind::connection, 8, 1002},
      raw_closed{Kind::gone, 8, 0}, c{Kind::connection, 9, 1003}, on_c_fd{Kind::connection, 9, 1004};
  bool c_open = true;
  const auto still_open = [&](const wire::SubscriptionSender& s) { return s != c || c_open; };
  book.subscribed("pose", b);
  // A raw peer's unsubscriptions of what another connection holds change nothing,
  // nor do they once its connection is closed.
  for (int k = 0; k < 3; ++k) {
    CHECK_FALSE(book.unsubscribed("pose", raw, still_open));
    CHECK_FALSE(book.unsubscribed("", raw, still_open));
    CHECK_FALSE(book.unsubscribed("pose", raw_closed, still_open));
  }
  CHECK(book.receiving("pose") == 1);
  // Its own subscription it can give up.
  book.subscribed("pose", raw);
  CHECK(book.receiving("pose") == 2);
  CHECK(book.unsubscribed("pose", raw, still_open));
  CHECK_FALSE(book.unsubscribed("pose", raw, still_open));
  CHECK(book.receiving("pose") == 1);
  // A connection gone: ZeroMQ's unsubscription, no descriptor, counts; a later socket on
  // the same descriptor holds nothing of the last one's.
  book.subscribed("joints", c);
  c_open = false;
  CHECK(book.unsubscribed("joints", {}, still_open));
  book.subscribed("joints", b);
  CHECK_FALSE(book.unsubscribed("joints", on_c_fd, still_open));
  CHECK(book.selecting("joints") == 1);
  CHECK(book.unsubscribed("joints", b, still_open));
  CHECK(book.selecting("joints") == 0);
  CHECK(book.receiving("pose") == 1);
}

TEST_CASE("A connected output's peer holds a prefix or not: sent again, it counts once",
          "[views][subscriptions]") {
  wire::SubscriptionBook book;
  const wire::SubscriptionSender peer{wire::SubscriptionSender::Kind::peer};
  const auto never_open = [](const wire::SubscriptionSender&) { return false; };
  for (int k = 0; k < 3; ++k) book.subscribed("", peer);  // each reconnection sends it again
  book.subscribed("joints", peer);
  CHECK(book.receiving("pose") == 1);
  CHECK(book.selecting("joints") == 1);
  CHECK_FALSE(book.unsubscribed("pose", peer, never_open));  // never held
  CHECK(book.unsubscribed("", peer, never_open));
  CHECK(book.receiving("pose") == 0);
  CHECK_FALSE(book.unsubscribed("", peer, never_open));
  CHECK(book.selecting("joints") == 1);
  book.subscribed("", peer);
  CHECK(book.receiving("pose") == 1);
  book.clear();
  CHECK(book.receiving("pose") == 0);
  book.subscribed("", peer);  // a new output socket's peer starts afresh
  CHECK(book.receiving("pose") == 1);
  // What the daemon refused from it counts once a reload makes it a topic (and once only);
  // one it gave up does not, nor one longer than any topic.
  book.refused("joints", peer);
  book.refused("lean", peer);
  CHECK_FALSE(book.unsubscribed("lean", peer, never_open));
  book.refused(std::string(200, 'j'), peer);
  const auto any = [](std::string_view) { return true; };
  const auto total = [&] { return book.count_if([](std::string_view) { return true; }); };
  CHECK(total() == 1);
  book.revalidate([](std::string_view p) { return p == "joints"; });
  CHECK(book.selecting("joints") == 1);
  book.revalidate(any);
  CHECK(book.selecting("joints") == 1);
  CHECK(book.selecting("lean") == 0);
  CHECK(total() == 2);
  // The longest topic is a view's (32 bytes), '/' and a subject's name (32): one that
  // long is kept, one byte more is not.
  CHECK(kLongestTopicBytes == 65);
  book.refused(std::string(kLongestTopicBytes, 'k'), peer);
  book.refused(std::string(kLongestTopicBytes + 1, 'm'), peer);
  book.revalidate(any);
  CHECK(total() == 3);
  CHECK(book.selecting(std::string(kLongestTopicBytes, 'k')) == 1);
}

TEST_CASE("A refused subscription to a topic a reload dropped is counted until ZeroMQ drops it",
          "[views][subscriptions]") {
  using Kind = wire::SubscriptionSender::Kind;
  wire::SubscriptionBook book;
  const wire::SubscriptionSender earlier{Kind::connection, 7, 1001}, refused{Kind::connection, 8, 1002},
      another{Kind::connection, 8, 1003};
  const auto open = [](const wire::SubscriptionSender&) { return true; };
  book.subscribed("joints", earlier);
  // A reload dropped the view: a new subscriber of it is refused and dropped, and ZeroMQ
  // then unsubscribes it as its own (no descriptor). The earlier subscriber stays counted.
  book.refused("joints", refused);
  CHECK(book.selecting("joints") == 2);
  CHECK(book.unsubscribed("joints", {}, open));
  CHECK(book.selecting("joints") == 1);
  // Or another one unsubscribes itself before it is dropped.
  book.refused("joints", another);
  CHECK(book.unsubscribed("joints", another, open));
  CHECK_FALSE(book.unsubscribed("joints", another, open));
  CHECK(book.selecting("joints") == 1);
  // One that sends it twice (as a SUB subscribing twice does) counts once: ZeroMQ
  // unsubscribes its pipe once.
  const wire::SubscriptionSender twice{Kind::connection, 9, 1004};
  book.refused("joints", twice);
  book.refused("joints", twice);
  CHECK(book.selecting("joints") == 2);
  CHECK(book.unsubscribed("joints", {}, open));
  CHECK(book.selecting("joints") == 1);
  // A prefix nobody holds is not counted (the book does not grow with what senders choose),
  // and its unsubscription changes nothing.
  book.refused("lean", another);
  CHECK(book.count_if([](std::string_view) { return true; }) == 1);
  CHECK_FALSE(book.unsubscribed("lean", {}, open));
  CHECK(book.unsubscribed("joints", earlier, open));
  CHECK(book.selecting("joints") == 0);
}

TEST_CASE("What the subscription book keeps of connections gone stays bounded", "[subscriptions]") {
  using Kind = wire::SubscriptionSender::Kind;
  wire::SubscriptionBook book;
  const wire::SubscriptionSender stays{Kind::connection, 3, 1};
  book.subscribed("pose", stays);
  const auto only_stays = [&](const wire::SubscriptionSender& s) { return s == stays; };
  // Connections that come, subscribe and go, on the same descriptor number, 10000 times.
  std::size_t most_kept = 0;
  for (std::uint64_t k = 0; k < 10000; ++k) {
    book.subscribed("pose", {Kind::connection, 4, 100 + k});
    book.unsubscribed("pose", {}, only_stays);
    most_kept = std::max(most_kept, book.connection_records());
  }
  CHECK(most_kept <= 16);  // the one that stays, and those gone since the last look
  CHECK(book.receiving("pose") == 1);
  book.unsubscribed("pose", stays, only_stays);
  CHECK(book.receiving("pose") == 0);
}

TEST_CASE("A view is encoded only while someone subscribes to it, carries the parts it names, "
          "and stops when its subscriber goes",
          "[views][daemon]") {
  zmq::context_t context;
  test::DaemonThread d(
      context, on_free_ports(config_with_views(
                   {{"views", json::array({{{"topic", "joints"},
                                            {"pose_content", {"angles"}},
                                            {"units", "m"}},
                                           {{"topic", "lean"}, {"encoding", "msgpack"}}})}})));
  // Subscribed to everything (""): that asks for no view.
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  std::uint64_t frame = client.handshake();
  const auto none_sent = view_stats_until(client, frame, [](const json& views) {
    return views["joints"]["frames_out"] == 0 && views["lean"]["frames_out"] == 0;
  });
  REQUIRE(none_sent);
  CHECK((*none_sent)["joints"]["subscribers"] == 0);
  const std::uint64_t poses_before = d.daemon.counters().frames_out;
  CHECK(poses_before > 0);

  {
    zmq::socket_t joints = subscriber(context, d.daemon.output_endpoint(), "joints");
    const auto counted = view_stats_until(
        client, frame, [](const json& views) { return views["joints"]["subscribers"] == 1; });
    REQUIRE(counted);
    CHECK((*counted)["lean"]["subscribers"] == 0);
    client.send_frame(++frame);
    const std::optional<json> view = view_of(joints, "joints", frame);
    REQUIRE(view);
    const json& lean = *view;
    // The pose's required fields and the angles, nothing else it could carry.
    for (const char* key : {"frame", "units", "joints", "markers", "occluded", "residual", "solver",
                            "angles"})
      CHECK(lean.contains(key));
    for (const char* key : {"segments", "translations", "gap_s", "held", "outliers", "measured"})
      CHECK_FALSE(lean.contains(key));
    // The pose of the same frame is as the config says (every part).
    const auto pose = client.pose_of(frame);
    REQUIRE(pose);
    CHECK(pose->contains("segments"));
    CHECK(pose->contains("gap_s"));
    CHECK((*pose)["angles"] == lean["angles"]);
    // In the view's units (metres; the pose's are output.units, mm).
    CHECK((*pose)["units"] == "mm");
    CHECK(lean["units"] == "m");
    REQUIRE(lean["joints"].size() == (*pose)["joints"].size());
    for (const auto& [name, p_mm] : (*pose)["joints"].items())
      for (int k = 0; k < 3; ++k)
        CHECK(lean["joints"][name][k].get<double>() ==
              Approx(p_mm[k].get<double>() * 1e-3).margin(1e-7));
  }  // the subscriber goes: ZeroMQ unsubscribes it

  const auto gone = view_stats_until(
      client, frame, [](const json& views) { return views["joints"]["subscribers"] == 0; });
  REQUIRE(gone);
  const std::uint64_t sent = (*gone)["joints"]["frames_out"].get<std::uint64_t>();
  CHECK(sent > 0);
  // Poses go on; the view does not.
  const auto later = view_stats_until(client, frame, [&](const json&) {
    return d.daemon.counters().frames_out > poses_before + 50;
  });
  REQUIRE(later);
  CHECK((*later)["joints"]["frames_out"] == sent);
  CHECK((*later)["lean"]["frames_out"] == 0);
  CHECK(d.daemon.counters().subscriptions_refused == 0);
}

TEST_CASE("A view with axes carries positions and segment rotations turned into them, and "
          "says which",
          "[views][daemon]") {
  // The model's lab: z up, y forward (as a Z-up lab's). The view's: y up, x forward, so a
  // lab vector (x, y, z) is (y, z, x) in it. The view is MessagePack in metres, with the
  // measured markers; the full pose JSON in millimetres.
  json model = json::parse(*embedded_config("models/fullbody.json"));
  model["lab_axes"] = {{"up", "+z"}, {"forward", "+y"}};
  const json output{{"views", json::array({{{"topic", "yup"},
                                            {"pose_content", {"segments", "angles"}},
                                            {"measured_markers", true},
                                            {"encoding", "msgpack"},
                                            {"units", "m"},
                                            {"axes", {{"up", "+y"}, {"forward", "+x"}}}}})},
                    {"measured_markers", true}};
  const json root{{"format", "fabrikd-config/1"}, {"model", model}, {"output", output}};
  zmq::context_t context;
  test::DaemonThread d(context, on_free_ports(load_daemon_config(root.dump(), "axes.json")));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  std::uint64_t frame = client.handshake();
  zmq::socket_t yup = subscriber(context, d.daemon.output_endpoint(), "yup");
  REQUIRE(view_stats_until(client, frame,
                           [](const json& views) { return views["yup"]["subscribers"] == 1; }));
  // Segments away from their rest rotations, and measured markers to turn.
  SyntheticMotion motion(*d.daemon.config().tracker.model, MotionSettings{});
  client.send_frame(++frame, test::subject_markers(d.daemon.config().tracker, motion, 0.3,
                                                   Eigen::Vector3d::Zero(), ""));
  const std::optional<json> view = view_of(yup, "yup", frame);
  REQUIRE(view);
  const auto pose = client.pose_of(frame);
  REQUIRE(pose);
  CHECK_FALSE(pose->contains("axes"));
  CHECK((*view)["axes"] == json{{"up", "+y"}, {"forward", "+x"}});
  const Eigen::Matrix3d r_view_lab = (Eigen::Matrix3d() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished();
  // Each position of `part` in the view, in metres, against the pose's (mm) turned.
  const auto turned_alike = [&](const json& view_points, const json& pose_points) {
    REQUIRE(view_points.size() == pose_points.size());
    REQUIRE(pose_points.size() > 0);
    for (const auto& [name, p_mm] : pose_points.items()) {
      CAPTURE(name);
      const Eigen::Vector3d expected_m =
          r_view_lab * Eigen::Vector3d(p_mm[0].get<double>(), p_mm[1].get<double>(),
                                       p_mm[2].get<double>()) * 1e-3;
      for (int k = 0; k < 3; ++k)
        CHECK(view_points[name][k].get<double>() == Approx(expected_m[k]).margin(2e-7));
    }
  };
  turned_alike((*view)["joints"], (*pose)["joints"]);
  turned_alike((*view)["markers"], (*pose)["markers"]);
  turned_alike((*view)["measured"], (*pose)["measured"]);
  const auto q_of = [](const json& q) {
    return Eigen::Quaterniond(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
                              q[3].get<double>());
  };
  int turned_segments = 0;
  json origins_pose = json::object(), origins_view = json::object();
  for (const auto& [name, seg] : (*pose)["segments"].items()) {
    CAPTURE(name);
    const Eigen::Matrix3d r_lab = q_of(seg["q"]).toRotationMatrix();
    turned_segments += r_lab.isIdentity(1e-3) ? 0 : 1;
    const Eigen::Matrix3d expected = r_view_lab * r_lab;
    CHECK((q_of((*view)["segments"][name]["q"]).toRotationMatrix() - expected).norm() < 1e-5);
    origins_pose[name] = seg["origin"];
    origins_view[name] = (*view)["segments"][name]["origin"];
  }
  CHECK(turned_segments > 0);  // the order of the two rotations shows
  turned_alike(origins_view, origins_pose);
  // Angles are the lab's own, whatever the axes (and not all zero here).
  REQUIRE((*view)["angles"].size() == (*pose)["angles"].size());
  double largest_deg = 0.0;
  for (const auto& [name, a] : (*pose)["angles"].items()) {
    CHECK((*view)["angles"][name].get<double>() == Approx(a.get<double>()).margin(1e-3));
    largest_deg = std::max(largest_deg, std::abs(a.get<double>()));
  }
  CHECK(largest_deg > 1.0);
}

TEST_CASE("A multi-subject daemon publishes each subject's view on TOPIC/NAME, selected apart",
          "[views][daemon][subjects]") {
  test::SubjectsDir dir;
  DaemonConfig c = load_daemon_config_file(dir.write(
      {"alice", "bob"}, {{"output", {{"views", json::array({{{"topic", "joints"}}})}}}}));
  zmq::context_t context;
  test::DaemonThread d(context, on_free_ports(std::move(c)));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  zmq::socket_t alice = subscriber(context, d.daemon.output_endpoint(), "joints/alice");
  std::uint64_t frame = 0;
  const auto counted = view_stats_until(client, frame, [](const json& views) {
    return views.contains("joints/alice") && views["joints/alice"]["subscribers"] == 1;
  });
  REQUIRE(counted);
  CHECK((*counted)["joints/bob"]["subscribers"] == 0);
  CHECK_FALSE(counted->contains("joints"));
  CHECK(d.daemon.counters().subscriptions_refused == 0);
}

// The longest topic the daemon publishes (a 32-byte view topic, '/', a 32-byte subject name):
// libzmq 4.3 sends a subscription as ZMTP 3.1's SUBSCRIBE command, 10 bytes more than the
// prefix, and a bound output's ZMQ_MAXMSGSIZE once dropped any prefix over 54 bytes, silently.
TEST_CASE("A subscriber to the longest topic the daemon publishes is kept and served",
          "[views][daemon][subjects][subscriptions]") {
  const std::string name(kMaxSubjectNameBytes, 'a'), view(kMaxViewTopicBytes, 'v');
  const std::string topic = view + "/" + name;
  REQUIRE(topic.size() == kLongestTopicBytes);
  test::SubjectsDir dir;
  DaemonConfig c = load_daemon_config_file(
      dir.write({name, "bob"}, {{"output", {{"views", json::array({{{"topic", view}}})}}}}));
  zmq::context_t context;
  test::DaemonThread d(context, on_free_ports(std::move(c)));
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  zmq::socket_t sub = subscriber(context, d.daemon.output_endpoint(), topic.c_str());
  std::uint64_t frame = 0;
  const auto counted = view_stats_until(client, frame, [&](const json& views) {
    return views.contains(topic) && views[topic]["subscribers"] == 1;
  });
  REQUIRE(counted);
  CHECK(d.daemon.counters().subscriptions_refused == 0);
}

TEST_CASE("A reload that keeps the output keeps its subscribers' views selected, and starts new "
          "views",
          "[views][daemon][reload]") {
  const json joints{{"topic", "joints"}, {"pose_content", {"angles"}}};
  const DaemonConfig before = on_free_ports(config_with_views({{"views", json::array({joints})}}));
  const DaemonConfig after = on_free_ports(
      config_with_views({{"views", json::array({joints, {{"topic", "lean"}}})}}));
  zmq::context_t context;
  test::DaemonThread d(context, before, {}, [&] { return after; });
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  zmq::socket_t viewer = subscriber(context, d.daemon.output_endpoint(), "joints");
  std::uint64_t frame = 0;
  REQUIRE(view_stats_until(client, frame,
                           [](const json& views) { return views["joints"]["subscribers"] == 1; }));
  d.control.reload = true;
  const auto reloaded =
      view_stats_until(client, frame, [](const json& views) { return views.contains("lean"); });
  REQUIRE(reloaded);
  CHECK(d.daemon.counters().reloads == 1);
  CHECK((*reloaded)["joints"]["subscribers"] == 1);  // the subscriber did not resubscribe
  CHECK((*reloaded)["lean"]["subscribers"] == 0);
  // And its view still comes.
  client.send_frame(++frame);
  CHECK(test::receive_topic(viewer, "joints", 5000ms));
}

// A connected output's peer (the operator's proxy) is not dropped for a subscription the
// daemon refuses, and ZeroMQ keeps it: a reload that makes it one of the daemon's topics
// must count it, or the view would not be made until the proxy reconnects.
TEST_CASE("A connected output's refused subscription that a reload makes a view's topic selects it",
          "[views][daemon][reload][subscriptions]") {
  zmq::context_t context;
  zmq::socket_t proxy(context, zmq::socket_type::sub);
  proxy.set(zmq::sockopt::linger, 0);
  for (const char* topic : {"stats", "joints"}) proxy.set(zmq::sockopt::subscribe, topic);
  proxy.bind("tcp://127.0.0.1:*");
  const auto connected = [&](DaemonConfig c) {
    c = on_free_ports(std::move(c));
    c.output = {proxy.get(zmq::sockopt::last_endpoint), SocketMode::connect};
    return c;
  };
  const DaemonConfig before = connected(config_with_views(json::object()));
  const DaemonConfig after = connected(config_with_views(
      {{"views", json::array({{{"topic", "joints"}, {"pose_content", {"angles"}}}})}}));
  test::DaemonThread d(context, before, {}, [&] { return after; });
  zmq::socket_t source(context, zmq::socket_type::pub);
  source.set(zmq::sockopt::linger, 0);
  source.connect(d.daemon.input_endpoint());
  // The first stats for which done(stats) holds, within 5 s.
  const auto stats_until = [&](auto done) -> std::optional<json> {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (std::chrono::steady_clock::now() < deadline) {
      auto m = test::receive_topic(proxy, "stats", 100ms);
      if (m && done(test::decode_payload(*m))) return test::decode_payload(*m);
    }
    return std::nullopt;
  };
  REQUIRE(stats_until([](const json& s) { return s["subscriptions_refused"] == 1; }));
  d.control.reload = true;
  const auto reloaded = stats_until([](const json& s) { return s.contains("views"); });
  REQUIRE(reloaded);
  CHECK((*reloaded)["views"]["joints"]["subscribers"] == 1);  // the proxy did not resubscribe
  // And the view comes to it.
  std::optional<zmq::message_t> view;
  std::uint64_t frame = 0;
  for (const auto deadline = std::chrono::steady_clock::now() + 5s;
       !view && std::chrono::steady_clock::now() < deadline;) {
    source.send(zmq::str_buffer("markers"), zmq::send_flags::sndmore);
    source.send(zmq::buffer(json{{"frame", ++frame}, {"units", "mm"}, {"markers", json::object()}}.dump()));
    view = test::receive_topic(proxy, "joints", 50ms);
  }
  CHECK(view);
}

// On a bound output a subscriber the daemon refuses is dropped, and ZeroMQ's unsubscription for
// it (its own, naming no connection) counts. A reload that dropped a view keeps its earlier
// subscribers counted; a refused subscription to that topic must not take one of their counts,
// or a later reload that brings the view back would not make it for them.
TEST_CASE("A refused subscription to a view a reload dropped leaves its earlier subscriber "
          "counted when a later reload brings the view back",
          "[views][daemon][reload][subscriptions]") {
  const json joints{{"topic", "joints"}, {"pose_content", {"angles"}}};
  const DaemonConfig with_view = on_free_ports(config_with_views({{"views", json::array({joints})}}));
  const DaemonConfig without_view = on_free_ports(config_with_views(json::object()));
  int reloads = 0;
  zmq::context_t context;
  test::DaemonThread d(context, with_view, {},
                       [&] { return ++reloads == 1 ? without_view : with_view; });
  test::SocketClient client(context, d.daemon.input_endpoint(), d.daemon.output_endpoint());
  zmq::socket_t viewer = subscriber(context, d.daemon.output_endpoint(), "joints");
  std::uint64_t frame = 0;
  // The first stats for which done(stats) holds while frames keep coming, within 5 s.
  const auto stats_until = [&](auto done) -> std::optional<json> {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (std::chrono::steady_clock::now() < deadline) {
      client.send_frame(++frame);
      auto stats = client.receive("stats", 100ms);
      if (stats && done(*stats)) return stats;
    }
    return std::nullopt;
  };
  REQUIRE(stats_until([](const json& s) {
    return s.contains("views") && s["views"]["joints"]["subscribers"] == 1;
  }));
  d.control.reload = true;
  REQUIRE(stats_until([](const json& s) { return !s.contains("views"); }));
  // A new subscriber: first `pose` (counted: the client's "" and this one), then `joints`,
  // refused now, for which it is dropped. ZeroMQ unsubscribes both prefixes at once when
  // it drops the connection, so `pose_subscribers` back at 1 says both were read.
  // (It must not reconnect once dropped: it would send its subscriptions again.)
  zmq::socket_t late(context, zmq::socket_type::sub);
  late.set(zmq::sockopt::linger, 0);
  late.set(zmq::sockopt::reconnect_ivl, -1);
  late.set(zmq::sockopt::subscribe, "pose");
  late.connect(d.daemon.output_endpoint());
  REQUIRE(stats_until([](const json& s) { return s["pose_subscribers"] == 2; }));
  late.set(zmq::sockopt::subscribe, "joints");
  REQUIRE(stats_until([](const json& s) {
    return s["subscriptions_refused"] == 1 && s["pose_subscribers"] == 1;
  }));
  d.control.reload = true;
  const auto reloaded = stats_until([](const json& s) { return s.contains("views"); });
  REQUIRE(reloaded);
  CHECK(reloads == 2);
  CHECK((*reloaded)["views"]["joints"]["subscribers"] == 1);  // the viewer, who never left
  client.send_frame(++frame);
  CHECK(view_of(viewer, "joints", frame));
}
