// Proves that solve() and the daemon's per-frame path perform no heap
// allocation: this test binary counts every allocation, through operator new
// or straight through malloc (Eigen allocates with malloc).
//   - Normal builds: the binary defines glibc's allocation functions, which
//     forward to glibc's own (__libc_malloc, ...); libstdc++'s operator new
//     allocates through them, so one counter sees both.
//   - AddressSanitizer builds: ASan owns malloc, so a defined malloc would
//     break it; the sanitizer's malloc hook counts instead (it sees every
//     allocation of ASan's allocator, operator new included).
#include <atomic>
#include <cerrno>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <limits>
#include <new>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "config/daemon_config.hpp"
#include "solver/fabrik_plan.hpp"
#include "solver/fabrik_solver.hpp"
#include "solver/solver.hpp"
#include "solver/jacobian_solver.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/mirror_swap.hpp"
#include "test_models.hpp"
#include "transport/marker_codec.hpp"
#include "transport/pose_codec.hpp"
#include "transport/daemon.hpp"
#include "socket_client.hpp"
#include "subjects_fixture.hpp"

#include "sanitized.hpp"

namespace {
std::atomic<long> g_allocations{0};
void count_allocation() {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

#ifdef FABRIK_TEST_SANITIZED
#include <sanitizer/allocator_interface.h>

namespace {
void on_malloc(const volatile void*, std::size_t) {
  count_allocation();
}
void on_free(const volatile void*) {}
const bool g_hooks_installed = __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free) != 0;
}  // namespace

#else
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
void __libc_free(void*);

void* malloc(std::size_t n) {
  count_allocation();
  return __libc_malloc(n);
}
void* calloc(std::size_t count, std::size_t n) {
  count_allocation();
  return __libc_calloc(count, n);
}
void* realloc(void* p, std::size_t n) {
  count_allocation();
  return __libc_realloc(p, n);
}
void* memalign(std::size_t alignment, std::size_t n) {
  count_allocation();
  return __libc_memalign(alignment, n);
}
void* aligned_alloc(std::size_t alignment, std::size_t n) {
  count_allocation();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) {
  count_allocation();
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t n) {
  count_allocation();
  return __libc_valloc(n);
}
void* pvalloc(std::size_t n) {
  count_allocation();
  return __libc_pvalloc(n);
}
void free(void* p) {
  __libc_free(p);
}
}  // extern "C"
#endif

using namespace fabrik;

namespace {
struct Scene {
  Model model = test::fullbody_model();
  std::vector<Target> targets;
  std::vector<int> points;
  std::vector<Eigen::Vector3d> pos;
  std::vector<std::uint8_t> visible;
  Scene() {
    points = model.marker_points();
    for (int p : points) targets.push_back({p, p % 3, 1.0});  // three priority levels
    pos.resize(points.size());
    visible.assign(points.size(), 1);
    visible[5] = 0;  // one occluded marker
  }
};
}  // namespace

namespace {
// Keeps the optimiser from removing an allocation whose result is unused.
template <class T>
T* escape(T* p) {
  asm volatile("" : : "g"(p) : "memory");
  return p;
}
}  // namespace

TEST_CASE("The counter sees operator new, malloc and Eigen's heap (the test can fail)",
          "[alloc]") {
#ifdef FABRIK_TEST_SANITIZED
  REQUIRE(g_hooks_installed);
#endif
  struct alignas(64) Line {
    double x[8];
  };
  long before = g_allocations.load();
  delete escape(new std::vector<int>(100));
  delete escape(new Line{});                  // aligned operator new
  delete escape(new (std::nothrow) int(3));  // as Catch allocates
  const long by_new = g_allocations.load() - before;

  before = g_allocations.load();
  void* raw = escape(std::malloc(24));
  raw = escape(std::realloc(raw, 4096));
  std::free(raw);
  std::free(escape(std::calloc(3, 8)));
  std::free(escape(std::aligned_alloc(64, 128)));
  const long by_malloc = g_allocations.load() - before;

  before = g_allocations.load();
  double sum = 0.0;
  {
    Eigen::MatrixXd m = Eigen::MatrixXd::Identity(12, 12);
    Eigen::VectorXd x = m * Eigen::VectorXd::Ones(12);
    sum = x.sum();
  }
  const long by_eigen = g_allocations.load() - before;

  CHECK(by_new == 4);  // the vector object, its elements, the Line, the int
  CHECK(by_malloc == 4);
  CHECK(by_eigen >= 2);
  CHECK(sum == 12.0);
}

TEST_CASE("FabrikSolver::solve performs no heap allocation", "[alloc]") {
  Scene scene;
  SyntheticMotion motion(scene.model, MotionSettings{});
  Posture truth = Posture::rest(scene.model);
  for (SegmentFit fit : {SegmentFit::paper, SegmentFit::rigid})
    for (bool prio : {false, true}) {
      SolverOptions o;
      o.segment_fit = fit;
      o.root = RootMode::free;
      o.use_priorities = prio;
      FabrikSolver solver(scene.model, scene.targets, o);
      Posture posture = Posture::rest(scene.model);
      long allocations = 0;
      for (int frame = 0; frame < 50; ++frame) {
        motion.posture_at(frame / 100.0, truth);
        motion.sample(truth, scene.points, 0.001, scene.pos);
        const long before = g_allocations.load();
        const SolveResult r = solver.solve(scene.pos, scene.visible, posture);
        allocations += g_allocations.load() - before;
        REQUIRE(r.visible_targets == static_cast<int>(scene.points.size()) - 1);
      }
      CAPTURE(static_cast<int>(fit), prio);
      CHECK(allocations == 0);
    }
}

TEST_CASE("A workspace shares its plan's tables: making one allocates only its scratch",
          "[alloc]") {
  // Counted, not timed: a plan solved by N threads holds its tables once. A workspace that
  // copied them would allocate what a plan does on top of its scratch.
  Scene scene;
  const auto model = std::make_shared<const Model>(scene.model);
  SolverOptions o;
  o.root = RootMode::free;
  const SolverPlan plan(model, scene.targets, o);
  const auto count = [](const auto& make) {
    const long before = g_allocations.load();
    make();
    return g_allocations.load() - before;
  };
  std::vector<Target> copy_a = scene.targets, copy_b = scene.targets;
  const long tables = count([&] {
    escape(std::make_shared<const FabrikPlan>(model, std::move(copy_a),
                                              std::vector<OrientationTarget>{})
               .get());
  });
  const long standalone =
      count([&] { FabrikSolver solver(model, std::move(copy_b), o); escape(&solver); });
  const long workspace = count([&] { SolverWorkspace ws(plan); escape(&ws); });
  CAPTURE(tables, standalone, workspace);
  REQUIRE(tables > 10);  // the plan's tables are many vectors
  // standalone = the plan (tables) + the scratch; a workspace = the scratch and its own
  // FabrikSolver object: one allocation more than the scratch alone.
  CHECK(workspace + tables <= standalone + 1);
}

TEST_CASE("JacobianSolver::solve performs no heap allocation", "[alloc]") {
  Scene scene;
  SyntheticMotion motion(scene.model, MotionSettings{});
  Posture truth = Posture::rest(scene.model);
  motion.posture_at(0.3, truth);
  motion.sample(truth, scene.points, 0.0, scene.pos);
  for (JacobianMethod method : {JacobianMethod::transpose, JacobianMethod::damped_least_squares}) {
    SolverOptions o;
    o.root = RootMode::free;
    o.max_iterations = 20;
    JacobianSolver solver(scene.model, scene.targets, o, {method, 0.01, 0.2});
    Posture posture = Posture::rest(scene.model);
    const long before = g_allocations.load();
    const SolveResult r = solver.solve(scene.pos, scene.visible, posture);
    const long allocations = g_allocations.load() - before;  // read before Catch allocates
    CAPTURE(static_cast<int>(method));
    CHECK(allocations == 0);
    CHECK(r.iterations > 0);
  }
}

TEST_CASE("The daemon's per-frame path (decode, track, encode) performs no heap allocation",
          "[alloc]") {
  const DaemonConfig config = default_daemon_config();
  Tracker tracker(config.tracker);
  const wire::PoseEncoder encoder(tracker, "mm", wire::PayloadEncoding::json);
  const wire::PoseEncoder msgpack(tracker, "mm", wire::PayloadEncoding::msgpack);
  // With output.measured_markers: the frame's measurements too.
  const wire::PoseEncoder measured_json(tracker, "mm", wire::PayloadEncoding::json, true);
  const wire::PoseEncoder measured_msgpack(tracker, "m", wire::PayloadEncoding::msgpack, true);
  // With output.pose_content: joints and angles (and the required fields).
  const wire::PoseEncoder angles_json(tracker, "mm", wire::PayloadEncoding::json, false,
                                      PoseContent::none().with(PosePart::angles));
  std::vector<std::string> names;
  std::vector<int> points;
  for (const MarkerTarget& m : config.tracker.markers)
    names.push_back(m.marker), points.push_back(m.point);
  const wire::MarkerDecoder decoder(names, 1e-3, 1 << 20);
  wire::MarkerFrame frame = decoder.make_frame();
  SyntheticMotion motion(tracker.model(), MotionSettings{});
  Posture truth = Posture::rest(tracker.model());
  std::vector<Eigen::Vector3d> measured(names.size());
  std::vector<std::uint8_t> visible(names.size(), 1);
  // The stream also carries a marker the model does not know, with a name
  // longer than the short-string buffer (as Vicon's "Subject:NAME" labels).
  std::vector<std::string> sent = names;
  sent.push_back("boite:gauche_exterieur");
  std::vector<Eigen::Vector3d> sent_m(sent.size(), Eigen::Vector3d(0.1, 0.2, 0.3));
  std::vector<std::uint8_t> sent_visible(sent.size(), 1);
  std::string payload, out, error;
  payload.reserve(1 << 16);
  out.reserve(1 << 16);
  long track_allocations = 0, encode_allocations = 0, json_decode_allocations = 0,
       msgpack_decode_allocations = 0;
  int outlier_frames = 0, cold_frames = 0;
  for (int f = 0; f < 60; ++f) {
    motion.posture_at(f / 100.0, truth);
    motion.sample(truth, points, 0.001, measured);
    visible[f % names.size()] = 0;  // a moving occlusion
    visible[(f + 7) % names.size()] = 1;
    // Outliers (a label swap, then a ghost) and a cold start after a gap cost no allocation.
    if (f >= 20 && f < 30) std::swap(measured[10], measured[30]);
    if (f >= 40 && f < 45) measured[22] += Eigen::Vector3d(0.4, 0.0, 0.0);
    const double t = f / 100.0 + (f >= 50 ? 5.0 : 0.0);
    std::copy(measured.begin(), measured.end(), sent_m.begin());
    std::copy(visible.begin(), visible.end(), sent_visible.begin());
    bool ok = true;
    for (auto enc : {wire::PayloadEncoding::json, wire::PayloadEncoding::msgpack}) {
      wire::encode_marker_frame(static_cast<std::uint64_t>(f), &t, sent, sent_m, sent_visible, "mm",
                                enc, payload);
      const long before = g_allocations.load();
      ok = ok &&
           decoder.decode({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()},
                          frame, error);
      if (f >= 2)  // after the buffers have grown
        (enc == wire::PayloadEncoding::json ? json_decode_allocations
                                            : msgpack_decode_allocations) +=
            g_allocations.load() - before;
    }
    long before = g_allocations.load();
    const TrackResult& r = tracker.track(t, frame.p_world_m, frame.visible);
    track_allocations += g_allocations.load() - before;
    outlier_frames += r.outlier_count > 0;
    cold_frames += r.cold_start;
    before = g_allocations.load();
    encoder.encode({frame.frame, true, t, false, 0.0}, r, out);
    msgpack.encode({frame.frame, true, t, false, 0.0}, r, out);
    measured_json.encode({frame.frame, true, t, false, 0.0}, r, out,
                         {frame.p_world_m, frame.visible});
    measured_msgpack.encode({frame.frame, true, t, false, 0.0}, r, out,
                            {frame.p_world_m, frame.visible});
    angles_json.encode({frame.frame, true, t, false, 0.0}, r, out);
    encode_allocations += g_allocations.load() - before;
    REQUIRE(ok);
  }
  CHECK(track_allocations == 0);
  CHECK(encode_allocations == 0);
  CHECK(outlier_frames >= 5);  // the filter's extra solves ran (the ghost at least)
  CHECK(cold_frames == 2);      // the first frame and the one after the gap
  // The readers' and the frame's buffers are reused from frame to frame; both
  // encodings' common shape takes a fast path, which reads names in place.
  CHECK(frame.unknown_count == 1);
  CHECK(json_decode_allocations == 0);
  CHECK(msgpack_decode_allocations == 0);
  CHECK(decoder.fast_path_frames() == 2 * 60);
}

TEST_CASE("Tracking with confidence, smoothing and the mirror rule performs no heap allocation",
          "[alloc]") {
  DaemonConfig config = default_daemon_config();
  config.tracker.smoothing.enabled = true;
  Tracker tracker(config.tracker);
  std::vector<int> points;
  for (const MarkerTarget& m : config.tracker.markers) points.push_back(m.point);
  SyntheticMotion motion(tracker.model(), MotionSettings{});
  Posture truth = Posture::rest(tracker.model());
  std::vector<Eigen::Vector3d> measured(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  std::vector<float> confidence(points.size(), 0.9f);
  std::vector<std::string> names;
  for (const MarkerTarget& m : config.tracker.markers) names.push_back(m.marker);
  const auto pairs = mirror_pairs_from_names(names);
  REQUIRE(pairs.size() >= 2);
  long allocations = 0;
  int mirrored = 0;
  for (int f = 0; f < 60; ++f) {
    motion.posture_at(f / 100.0, truth);
    motion.sample(truth, points, 0.002, measured);
    std::fill(confidence.begin(), confidence.end(), 0.9f);
    confidence[f % points.size()] = 0.1f;  // a moving low-confidence marker
    confidence[(f + 5) % points.size()] = 0.6f;
    visible[(f + 11) % points.size()] = 0;  // gaps reset the filter
    visible[(f + 10) % points.size()] = 1;
    // Every left/right pair swapped (the mirror rule's relabelling).
    if (f >= 20 && f < 25)
      for (const auto& [r, l] : pairs) std::swap(measured[r], measured[l]);
    const long before = g_allocations.load();
    const TrackResult& r = tracker.track(f / 100.0, measured, visible, confidence);
    allocations += g_allocations.load() - before;
    mirrored += r.mirrored_count;
  }
  CHECK(allocations == 0);
  CHECK(mirrored > 0);  // the relabelling ran
}

TEST_CASE("The per-frame path with orientation sensors performs no heap allocation",
          "[alloc][sensors]") {
  DaemonConfig config = default_daemon_config();
  const Model& model = *config.tracker.model;
  std::vector<std::string> sensor_names;
  for (int s = 0; s < static_cast<int>(model.segments.size()); ++s) {
    sensor_names.push_back(model.segments[s].name + "_imu");
    config.tracker.sensors.sensors.push_back({sensor_names.back(), s, 0, 1.0});
  }
  Tracker tracker(config.tracker);
  const wire::PoseEncoder encoder(tracker, "mm", wire::PayloadEncoding::json);
  std::vector<std::string> names;
  std::vector<int> points;
  for (const MarkerTarget& m : config.tracker.markers)
    names.push_back(m.marker), points.push_back(m.point);
  const wire::MarkerDecoder decoder(names, 1e-3, 1 << 20, {}, sensor_names);
  wire::MarkerFrame frame = decoder.make_frame();
  SyntheticMotion motion(model, MotionSettings{});
  Posture truth = Posture::rest(model);
  std::vector<Eigen::Vector3d> measured(names.size());
  std::vector<std::uint8_t> visible(names.size(), 1);
  std::vector<Eigen::Quaterniond> q(sensor_names.size());
  std::vector<std::uint8_t> q_visible(q.size(), 1);
  std::string payload, out, error;
  payload.reserve(1 << 16);
  out.reserve(1 << 16);
  long allocations = 0;
  for (int f = 0; f < 40; ++f) {
    const double t = f / 100.0;
    motion.posture_at(t, truth);
    motion.sample(truth, points, 0.001, measured);
    for (std::size_t k = 0; k < q.size(); ++k) q[k] = truth.segments[k].q_world;
    q_visible[f % q.size()] = 0;  // a moving dropout; markers gone in every other frame
    q_visible[(f + 5) % q.size()] = 1;
    std::fill(visible.begin(), visible.end(), f % 2);
    const wire::SensorSamples samples{sensor_names, q, q_visible};
    for (auto enc : {wire::PayloadEncoding::json, wire::PayloadEncoding::msgpack}) {
      wire::encode_marker_frame(static_cast<std::uint64_t>(f), &t, names, measured, visible, "mm",
                                enc, payload, nullptr, &samples);
      const long before = g_allocations.load();
      REQUIRE(decoder.decode(
          {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, frame, error));
      const TrackResult& r =
          tracker.track(t, frame.p_world_m, frame.visible, frame.q_sensor, frame.sensor_visible);
      encoder.encode({frame.frame, true, t, false, 0.0}, r, out);
      if (f >= 2) allocations += g_allocations.load() - before;
    }
  }
  CHECK(frame.sensor_visible[(39 + 5) % q.size()] == 1);
  CHECK(allocations == 0);
}

TEST_CASE("FabrikSolver::solve with joint limits, subtree carry and orientation targets performs "
          "no heap allocation",
          "[alloc]") {
  // The embedded default's model has hinge, universal and limited ball joints.
  const DaemonConfig config = load_daemon_config_file("default.json");
  const Model& model = *config.tracker.model;
  REQUIRE(model.has_joint_limits());
  const std::vector<int> points = model.marker_points();
  std::vector<OrientationTarget> orientations;
  for (int s = 0; s < static_cast<int>(model.segments.size()); s += 3)
    orientations.push_back({s, 0, 1.0});
  std::vector<Eigen::Vector3d> pos(points.size());
  std::vector<std::uint8_t> visible(points.size(), 1);
  visible[3] = 0;
  std::vector<Eigen::Quaterniond> q(orientations.size());
  const std::vector<std::uint8_t> q_visible(orientations.size(), 1);
  SyntheticMotion motion(model, MotionSettings{});
  Posture truth = Posture::rest(model);
  // Two levels (the priority loop), and one (the extrapolation of the convergence loop).
  for (const bool two_levels : {true, false})
    for (double carry : {0.0, 0.5}) {
      std::vector<Target> targets;
      for (int p : points) targets.push_back({p, two_levels ? p % 2 : 0, 1.0});
      SolverOptions o;
      o.segment_fit = SegmentFit::rigid;
      o.root = RootMode::free;
      o.subtree_carry = carry;
      FabrikSolver solver(model, targets, o, orientations);
      Posture posture = Posture::rest(model);
      long allocations = 0;
      int jumps = 0;
      for (int frame = 0; frame < 50; ++frame) {
        motion.posture_at(frame / 100.0, truth);
        motion.sample(truth, points, 0.001, pos);
        for (std::size_t k = 0; k < orientations.size(); ++k)
          q[k] = truth.segments[orientations[k].segment].q_world;
        const long before = g_allocations.load();
        const SolveResult r = solver.solve(pos, visible, q, q_visible, posture);
        allocations += g_allocations.load() - before;
        REQUIRE(r.status != SolveStatus::size_mismatch);
        jumps += r.jumps;
      }
      CAPTURE(carry, two_levels, jumps);
      CHECK(allocations == 0);
      if (!two_levels) CHECK(jumps > 0);
    }
}

TEST_CASE("The QTM stream path (split, decode data, encode data) allocates nothing after warm-up",
          "[alloc][qtm]") {
  using namespace fabrik::qtm;
  DataFrame sent, decoded;
  sent.has_3d = sent.has_3d_no_labels = true;
  sent.labelled_p_qtm_mm.assign(60, Eigen::Vector3f(100.0f, 200.0f, 300.0f));
  sent.unlabelled.assign(3, UnlabelledMarker{Eigen::Vector3f(1.0f, 2.0f, 3.0f), 1});
  PacketSplitter splitter(ByteOrder::little, 1 << 16);
  std::vector<std::uint8_t> packet, two_packets;
  packet.reserve(1 << 12);
  two_packets.reserve(1 << 13);
  long split_allocations = 0, decode_allocations = 0, encode_allocations = 0;
  int frames = 0;
  for (std::uint32_t f = 0; f < 60; ++f) {
    sent.frame_number = f;
    sent.labelled_p_qtm_mm[f % 60].x() = std::numeric_limits<float>::quiet_NaN();  // occlusions
    long before = g_allocations.load();
    write_data_packet(sent, ByteOrder::little, packet);
    if (f >= 2) encode_allocations += g_allocations.load() - before;
    // Two packets per read, cut off-centre: the splitter carries a partial packet over.
    two_packets.assign(packet.begin(), packet.end());
    two_packets.insert(two_packets.end(), packet.begin(), packet.end());
    const std::size_t cut = packet.size() + 13;
    for (const auto& chunk : {std::span<const std::uint8_t>(two_packets).first(cut),
                              std::span<const std::uint8_t>(two_packets).subspan(cut)}) {
      before = g_allocations.load();
      splitter.feed(chunk);
      PacketView view;
      Status status;
      while (true) {
        status = splitter.next(view);
        if (status != Status::ok) break;
        const long before_decode = g_allocations.load();
        const Status decoded_status = read_data(view, ByteOrder::little, 1000, decoded);
        if (f >= 2) decode_allocations += g_allocations.load() - before_decode;
        frames += decoded_status == Status::ok && decoded.frame_number == f;
      }
      if (f >= 2) split_allocations += g_allocations.load() - before;
      REQUIRE(status == Status::need_more);
    }
  }
  CHECK(frames == 120);
  CHECK(split_allocations == 0);
  CHECK(decode_allocations == 0);
  CHECK(encode_allocations == 0);
}

// The whole frame path of a multi-subject daemon (Daemon::serve_payload:
// decode, route, track and encode each subject, publish) against a
// single-subject one: the only allocation is ZeroMQ's copy of each pose it
// sends (a message over 33 bytes), so a frame of two subjects (and another
// process's third) costs exactly what two single-subject frames cost, and
// one with "subject" one.
namespace {
// `c` on in-process endpoints of its own, named after `name`.
DaemonConfig on_inproc(DaemonConfig c, const std::string& name) {
  c.input = {"inproc://alloc-" + name + "-in", SocketMode::bind};
  c.output = {"inproc://alloc-" + name + "-out", SocketMode::bind};
  return c;
}
// Whether `allocations` are ZeroMQ's copies of `messages` sent (one each,
// over 33 bytes) and nothing else: its queue to an in-process subscriber
// also takes a block of 256 messages now and then.
bool zmq_copies(long allocations, int messages) {
  return allocations >= messages && allocations <= messages + 2;
}
}  // namespace

TEST_CASE("A multi-subject frame allocates nothing beyond ZeroMQ's copy of each pose sent",
          "[alloc][subjects]") {
  zmq::context_t context;
  test::SubjectsDir dir;
  const DaemonConfig single = on_inproc(default_daemon_config(), "single");
  const DaemonConfig multi = on_inproc(load_daemon_config_file(dir.write({"Alice", "Bob"})), "multi");
  wire::Daemon one(context, single), two(context, multi);
  // Poses are made only for subscribers (each receives pose, or pose/NAME by prefix).
  zmq::socket_t one_sub = test::subscriber(context, single.output.address, "pose");
  zmq::socket_t two_sub = test::subscriber(context, multi.output.address, "pose");
  SyntheticMotion motion(*single.tracker.model, MotionSettings{});
  const auto bytes = [](const std::string& s) {
    return std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(s.data()), s.size());
  };
  long single_allocations = 0, prefix_allocations = 0, field_allocations = 0;
  const int frames = 40, warm_up = 5;
  for (int f = 0; f < frames + warm_up; ++f) {
    const double t = f / 100.0;
    const nlohmann::json bare = test::subject_markers(single.tracker, motion, t, Eigen::Vector3d::Zero(), "");
    nlohmann::json both = test::subject_markers(single.tracker, motion, t, test::subject_offset_m(0), "Alice:");
    both = test::subject_markers(single.tracker, motion, t, test::subject_offset_m(1), "Bob:", both);
    // And another process's subject (a split), whose name is longer than a
    // short-string buffer: reported once, then skipped without allocating.
    both = test::subject_markers(single.tracker, motion, t, test::subject_offset_m(2),
                                 "Another_process_subject:", both);
    const std::string p_single = nlohmann::json{{"frame", f}, {"time", t}, {"markers", bare}}.dump();
    const std::string p_prefix = nlohmann::json{{"frame", f}, {"time", t}, {"markers", both}}.dump();
    const std::string p_field =
        nlohmann::json{{"frame", f}, {"time", t}, {"subject", "Bob"}, {"markers", bare}}.dump();
    long before = g_allocations.load();
    one.serve_payload(bytes(p_single));
    const long a_single = g_allocations.load() - before;
    before = g_allocations.load();
    two.serve_payload(bytes(p_prefix));
    const long a_prefix = g_allocations.load() - before;
    before = g_allocations.load();
    two.serve_payload(bytes(p_field));
    const long a_field = g_allocations.load() - before;
    test::drain(one_sub);
    test::drain(two_sub);
    if (f < warm_up) continue;
    REQUIRE(one.counters().pose_subscribers == 1);
    REQUIRE(two.counters().pose_subscribers == 1);
    single_allocations += a_single;
    prefix_allocations += a_prefix;
    field_allocations += a_field;
  }
  CHECK(two.counters().frames_out == 3u * static_cast<std::uint64_t>(frames + warm_up));
  CHECK(two.counters().decode_errors == 0);
  CHECK(zmq_copies(single_allocations, frames));  // one pose a frame
  CHECK(zmq_copies(prefix_allocations, 2 * frames));
  CHECK(zmq_copies(field_allocations, frames));
}

// Views (output.views) that no subscription selects are not encoded: a daemon
// configured with some allocates on its frame path what one without does.
TEST_CASE("Pose views nobody subscribes to add no allocation to the frame path", "[alloc][views]") {
  zmq::context_t context;
  const DaemonConfig plain = on_inproc(default_daemon_config(), "plain");
  DaemonConfig viewed = on_inproc(default_daemon_config(), "viewed");
  viewed.output_views = {{"joints", PoseContent::none().with(PosePart::angles), false, Encoding::json, "mm", {}},
                         {"lean", PoseContent::none(), true, Encoding::msgpack, "mm", {}}};
  wire::Daemon a(context, plain), b(context, viewed);
  zmq::socket_t a_sub = test::subscriber(context, plain.output.address, "pose");
  zmq::socket_t b_sub = test::subscriber(context, viewed.output.address, "pose");
  SyntheticMotion motion(*plain.tracker.model, MotionSettings{});
  long plain_allocations = 0, viewed_allocations = 0;
  const int frames = 30, warm_up = 5;
  for (int f = 0; f < frames + warm_up; ++f) {
    const double t = f / 100.0;
    const std::string payload =
        nlohmann::json{{"frame", f},
                       {"time", t},
                       {"markers", test::subject_markers(plain.tracker, motion, t,
                                                         Eigen::Vector3d::Zero(), "")}}
            .dump();
    const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(payload.data()),
                                              payload.size());
    long before = g_allocations.load();
    a.serve_payload(bytes);
    const long a_plain = g_allocations.load() - before;
    before = g_allocations.load();
    b.serve_payload(bytes);
    const long a_viewed = g_allocations.load() - before;
    test::drain(a_sub);
    test::drain(b_sub);
    if (f < warm_up) continue;
    REQUIRE(a.counters().pose_subscribers == 1);
    REQUIRE(b.counters().pose_subscribers == 1);
    plain_allocations += a_plain;
    viewed_allocations += a_viewed;
  }
  CHECK(b.counters().frames_out == static_cast<std::uint64_t>(frames + warm_up));
  CHECK(zmq_copies(plain_allocations, frames));  // one pose a frame
  CHECK(zmq_copies(viewed_allocations, frames));
}

// What no subscription receives is not made: a frame with no subscriber
// allocates nothing, and each pose or view someone receives costs ZeroMQ's
// one copy (poses and views are encoded without allocating, tests above).
TEST_CASE("A frame's pose and views are made only while a subscription receives them",
          "[alloc][views]") {
  zmq::context_t context;
  DaemonConfig c = on_inproc(default_daemon_config(), "receivers");
  // In axes of its own (z up): turning positions allocates nothing either.
  c.output_views = {{"joints", PoseContent::all(), false, Encoding::json, "mm",
                     LabAxes{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX()}}};
  wire::Daemon d(context, c);
  SyntheticMotion motion(*c.tracker.model, MotionSettings{});
  int f = 0;
  std::string payload;
  std::vector<zmq::socket_t*> subscribers;  // drained after each frame
  std::vector<int> received;                // messages each has received, in all
  // One frame: its allocations and stages; then every subscriber drained.
  const auto serve = [&] {
    const double t = f / 100.0;
    payload = nlohmann::json{{"frame", f++},
                             {"time", t},
                             {"markers", test::subject_markers(c.tracker, motion, t,
                                                               Eigen::Vector3d::Zero(), "")}}
                  .dump();
    const long before = g_allocations.load();
    const wire::FrameStages stages = d.serve_payload(
        {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()});
    const long allocations = g_allocations.load() - before;
    received.resize(subscribers.size());
    for (std::size_t k = 0; k < subscribers.size(); ++k) received[k] += test::drain(*subscribers[k]);
    return std::pair(allocations, stages);
  };
  // Frames until `ready()` (over inproc a subscription reaches the daemon
  // within a frame or two: 200 at most), then 5 more.
  const auto settle = [&](auto ready) {
    for (int i = 0; i < 200 && !ready(); ++i) (void)serve();
    REQUIRE(ready());
    for (int i = 0; i < 5; ++i) (void)serve();
  };
  const int frames = 20;
  // Allocations over `frames` frames, each frame's stages checked by check(stages).
  const auto count = [&](auto check) {
    long total = 0;
    std::fill(received.begin(), received.end(), 0);
    for (int i = 0; i < frames; ++i) {
      const auto [allocations, stages] = serve();
      check(stages);
      total += allocations;
    }
    return total;
  };
  const std::uint64_t out_before = d.counters().frames_out;
  // No subscriber: tracked and counted, nothing encoded or sent.
  for (int i = 0; i < 5; ++i) (void)serve();
  CHECK(count([](const wire::FrameStages& s) {
          CHECK(s[wire::Stage::solve] > 0.0);
          CHECK(s[wire::Stage::encode] == 0.0);
        }) == 0);
  CHECK(d.counters().frames_out - out_before == static_cast<std::uint64_t>(frames + 5));
  // A subscriber of stats and one of the view: the view only.
  zmq::socket_t stats_sub = test::subscriber(context, c.output.address, "stats");
  zmq::socket_t view_sub = test::subscriber(context, c.output.address, "joints");
  subscribers = {&stats_sub, &view_sub};
  settle([&] { return !received.empty() && received[1] > 0; });
  CHECK(d.counters().pose_subscribers == 0);
  CHECK(zmq_copies(count([](const wire::FrameStages& s) {
                     CHECK(s[wire::Stage::encode] > 0.0);  // the view's
                   }),
                   frames));
  CHECK(received == std::vector<int>{0, frames});
  // And one of every topic: the pose too.
  zmq::socket_t all_sub = test::subscriber(context, c.output.address, "");
  subscribers.push_back(&all_sub);
  settle([&] { return d.counters().pose_subscribers == 1; });
  CHECK(zmq_copies(count([](const wire::FrameStages&) {}), 2 * frames));
  CHECK(received == std::vector<int>{0, frames, 2 * frames});  // everything's: the pose and the view
  // It goes: the view only again.
  subscribers.pop_back();
  all_sub.close();
  settle([&] { return d.counters().pose_subscribers == 0; });
  CHECK(zmq_copies(count([](const wire::FrameStages&) {}), frames));
  CHECK(received == std::vector<int>{0, frames});
}
