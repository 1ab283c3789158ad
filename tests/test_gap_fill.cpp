// Gap filling: the live prediction (GapPredictor through the Tracker) and the
// offline two-sided fill, on noise-free synthetic motion of the full-body
// model, where the truth is known; and the must-show on subject01_walk1
// when ../shared/data is there.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <optional>
#include <random>
#include <memory>

#include "eval/eval.hpp"
#include "synth/synthetic_motion.hpp"
#include "test_models.hpp"
#include "tracking/gap_predictor.hpp"
#include "tracking/tracker.hpp"
#include "tracking/two_sided_fill.hpp"

using namespace fabrik;

namespace {

constexpr double kRateHz = 100.0;

struct Recording {
  std::shared_ptr<const Model> model;
  TrackerSetup setup;
  std::size_t frames = 0, n = 0;
  std::vector<double> times_s;
  std::vector<Eigen::Vector3d> measured_m;  // [frame * n + i]
  std::vector<int> segment;                 // per marker
};

Recording recording(double seconds, bool prediction) {
  Recording r;
  r.model = std::make_shared<const Model>(test::fullbody_model());
  r.setup.model = r.model;
  std::vector<int> points;
  for (int p : r.model->marker_points()) {
    r.setup.markers.push_back({r.model->points[p].name, p, 0, 1.0});
    points.push_back(p);
    r.segment.push_back(r.model->points[p].segment);
  }
  r.setup.solver.root = RootMode::free;
  r.setup.solver.segment_fit = SegmentFit::rigid;
  r.setup.solver.tolerance_m = 1e-4;
  r.setup.prediction.enabled = prediction;
  r.setup.prediction.level = -1;
  r.n = points.size();
  r.frames = static_cast<std::size_t>(seconds * kRateHz);
  SyntheticMotion motion(*r.model, MotionSettings{});
  Posture truth = Posture::rest(*r.model);
  std::vector<Eigen::Vector3d> frame(r.n);
  for (std::size_t f = 0; f < r.frames; ++f) {
    r.times_s.push_back(static_cast<double>(f) / kRateHz);
    motion.posture_at(r.times_s.back(), truth);
    motion.sample(truth, points, 0.0, frame);
    r.measured_m.insert(r.measured_m.end(), frame.begin(), frame.end());
  }
  return r;
}

int segment_named(const Model& model, const std::string& name) {
  for (std::size_t s = 0; s < model.segments.size(); ++s)
    if (model.segments[s].name == name) return static_cast<int>(s);
  FAIL("no segment " << name);
  return -1;
}

// Visibility with every marker of `segment` hidden in frames [first, end).
std::vector<std::uint8_t> hide_segment(const Recording& r, int segment, std::size_t first,
                                       std::size_t end) {
  std::vector<std::uint8_t> visible(r.frames * r.n, 1);
  for (std::size_t f = first; f < end; ++f)
    for (std::size_t i = 0; i < r.n; ++i)
      if (r.segment[i] == segment) visible[f * r.n + i] = 0;
  return visible;
}

}  // namespace

TEST_CASE("gap_s counts the time since a marker was last measured, 0 while measured",
          "[gaps]") {
  Recording r = recording(0.5, true);
  Tracker tracker(r.setup);
  std::vector<std::uint8_t> visible(r.n, 1);
  for (std::size_t f = 0; f < 30; ++f) {
    visible[2] = f >= 10 && f < 20 ? 0 : 1;
    const TrackResult& t = tracker.track(r.times_s[f], std::span(r.measured_m).subspan(f * r.n, r.n), visible);
    const double expected_s = visible[2] ? 0.0 : r.times_s[f] - r.times_s[9];
    CHECK(t.gap_s[2] == Approx(expected_s).margin(1e-12));
    CHECK(t.gap_s[3] == 0.0);
  }
}

TEST_CASE("A lost marker's prediction starts where its last velocity carries it: no jump",
          "[gaps]") {
  Recording r = recording(1.0, true);
  Tracker tracker(r.setup);
  const int hand = segment_named(*r.model, "r_hand");
  const std::vector<std::uint8_t> visible = hide_segment(r, hand, 50, 80);
  for (std::size_t f = 0; f <= 50; ++f) {
    const TrackResult& t = tracker.track(r.times_s[f], std::span(r.measured_m).subspan(f * r.n, r.n),
                                         std::span(visible).subspan(f * r.n, r.n));
    if (f < 50) continue;
    for (std::size_t i = 0; i < r.n; ++i) {
      if (r.segment[i] != hand) continue;
      // The skeleton's fill starts at the linear extrapolation; donors carry
      // the marker on rigidly from its last measurement: both within a small
      // part of the marker's own step per frame.
      const Eigen::Vector3d expected =
          2.0 * r.measured_m[49 * r.n + i] - r.measured_m[48 * r.n + i];
      const double step_m = (r.measured_m[49 * r.n + i] - r.measured_m[48 * r.n + i]).norm();
      const double off_m = (t.markers_world_m[i] - expected).norm();
      INFO("first fill " << off_m * 1e3 << " mm from the extrapolation; step " << step_m * 1e3
                         << " mm");
      CHECK(off_m < 0.1 * step_m);
    }
  }
}

TEST_CASE("A hidden hand keeps turning relative to the forearm at its last velocity, then holds",
          "[gaps]") {
  // Without markers the warm start alone keeps the hand's rotation relative
  // to the forearm; the weak orientation target continues its last relative
  // angular velocity, decaying to a hold after about velocity_decay_s.
  Recording r = recording(1.5, true);
  Tracker tracker(r.setup);
  const int hand = segment_named(*r.model, "r_hand");
  const int forearm = r.model->segments[hand].parent;
  const std::vector<std::uint8_t> visible = hide_segment(r, hand, 50, 150);
  std::vector<Eigen::Quaterniond> rel;
  for (std::size_t f = 0; f < 150; ++f) {
    tracker.track(r.times_s[f], std::span(r.measured_m).subspan(f * r.n, r.n),
                  std::span(visible).subspan(f * r.n, r.n));
    const Posture& p = tracker.posture();
    rel.push_back(p.segments[forearm].q_world.conjugate() * p.segments[hand].q_world);
  }
  const PredictionSettings& ps = r.setup.prediction;
  const auto window = static_cast<std::size_t>(std::round(ps.velocity_window_s * kRateHz));
  const Eigen::AngleAxisd step(rel[49 - window].conjugate() * rel[49]);
  const double turn_rad = step.angle() * ps.velocity_decay_s / ps.velocity_window_s;
  const Eigen::Quaterniond predicted =
      rel[49] * Eigen::Quaterniond(Eigen::AngleAxisd(turn_rad, step.axis()));
  INFO("predicted turn " << turn_rad << " rad; reached " << rel[149].angularDistance(rel[49])
                         << " rad, " << rel[149].angularDistance(predicted) << " rad from the prediction");
  REQUIRE(turn_rad > 0.05);  // the motion turns the hand: a hold and a continuation differ
  CHECK(rel[149].angularDistance(predicted) < 0.2 * turn_rad);
  CHECK(rel[149].angularDistance(rel[140]) < 0.02 * turn_rad);  // held by now
}

TEST_CASE("A returning marker hands over without a jump in the joint centres", "[gaps]") {
  Recording r = recording(2.0, true);
  Tracker tracker(r.setup);
  const int hand = segment_named(*r.model, "r_hand");
  const std::size_t back = 150;
  const std::vector<std::uint8_t> visible = hide_segment(r, hand, 50, back);
  std::vector<std::vector<Eigen::Vector3d>> model_m;  // every marker's model position per frame
  for (std::size_t f = 0; f < back + 10; ++f) {
    const TrackResult& t = tracker.track(r.times_s[f], std::span(r.measured_m).subspan(f * r.n, r.n),
                                         std::span(visible).subspan(f * r.n, r.n));
    std::vector<Eigen::Vector3d> now;
    for (std::size_t i = 0; i < r.n; ++i)
      now.push_back(tracker.posture().point_world_m(tracker.model(), r.setup.markers[i].point));
    now.insert(now.end(), t.joints_world_m.begin(), t.joints_world_m.end());
    model_m.push_back(now);
  }
  double worst_m = 0.0;
  for (std::size_t f = back; f < back + 5; ++f)
    for (std::size_t k = 0; k < model_m[f].size(); ++k) {
      const auto step = [&](std::size_t g) { return (model_m[g][k] - model_m[g - 1][k]).norm(); };
      worst_m = std::max(worst_m, step(f) - std::max(step(back - 1), step(back + 9)));
    }
  INFO("largest step on return beyond the neighbouring motion: " << worst_m * 1e3 << " mm");
  CHECK(worst_m <= 5e-3);
}

// A pose that went wrong while markers were gone (here: every other marker 0.15 m off in
// the one frame the pelvis markers are hidden) must not be held by their return: the
// hand-over lasts no longer than the gap. Holding it at the return speed kept the pelvis
// markers' targets 0.15-0.3 m off for a second.
TEST_CASE("Markers back after a short gap hand over within the gap's length", "[gaps]") {
  Recording r = recording(1.0, true);
  const int pelvis = segment_named(*r.model, "pelvis");
  const std::size_t gap = 40;
  std::vector<std::uint8_t> visible = hide_segment(r, pelvis, gap, gap + 1);
  std::vector<Eigen::Vector3d> displaced = r.measured_m;
  for (std::size_t i = 0; i < r.n; ++i) displaced[gap * r.n + i].x() += 0.15;
  Tracker tracker(r.setup), clean(r.setup);
  const std::vector<std::uint8_t> all(r.n, 1);
  double worst_m = 0.0;
  for (std::size_t f = 0; f < 80; ++f) {
    const TrackResult& t = tracker.track(r.times_s[f], std::span(displaced).subspan(f * r.n, r.n),
                                         std::span(visible).subspan(f * r.n, r.n));
    const TrackResult& c =
        clean.track(r.times_s[f], std::span(r.measured_m).subspan(f * r.n, r.n), all);
    if (f < gap + 3) continue;  // the return frame and the next finish the hand-over
    for (std::size_t j = 0; j < t.joints_world_m.size(); ++j)
      worst_m = std::max(worst_m, (t.joints_world_m[j] - c.joints_world_m[j]).norm());
  }
  INFO("joint centres off the undisturbed tracker from the third frame after the gap: "
       << worst_m * 1e3 << " mm");
  CHECK(worst_m <= 2e-3);
}

TEST_CASE("The offline fill blends both sides: continuous at both ends of the gap", "[gaps]") {
  Recording r = recording(2.0, true);
  const int hand = segment_named(*r.model, "r_hand");
  const std::size_t first = 50, end = 150;
  std::vector<std::uint8_t> visible = hide_segment(r, hand, first, end);
  int never = -1;  // a marker never measured stays unfilled
  for (std::size_t i = 0; i < r.n && never < 0; ++i)
    if (r.segment[i] != hand) never = static_cast<int>(i);
  for (std::size_t f = 0; f < r.frames; ++f) visible[f * r.n + never] = 0;
  const TwoSidedFill fill = fill_two_sided(r.setup, r.times_s, r.measured_m, visible);
  for (std::size_t k = 0; k < r.frames * r.n; ++k) {
    const bool hidden = !visible[k] && static_cast<int>(k % r.n) != never;
    CHECK(fill.filled[k] == (hidden ? 1 : 0));
    if (visible[k]) CHECK(fill.markers_m[k] == r.measured_m[k]);
  }
  CHECK_FALSE(fill.markers_m[never].allFinite());
  double edge_m = 0.0, middle_m = 0.0;
  for (std::size_t i = 0; i < r.n; ++i) {
    if (r.segment[i] != hand) continue;
    const auto error = [&](std::size_t f) {
      return (fill.markers_m[f * r.n + i] - r.measured_m[f * r.n + i]).norm();
    };
    edge_m = std::max({edge_m, error(first), error(end - 1)});
    middle_m = std::max(middle_m, error((first + end) / 2));
  }
  INFO("fill error: next to the edges " << edge_m * 1e3 << " mm, mid-gap " << middle_m * 1e3 << " mm");
  CHECK(edge_m < 2e-3);
  std::size_t hand_markers = 0;
  for (int seg : r.segment) hand_markers += seg == hand ? 1 : 0;
  CHECK(fill.gaps.size() == hand_markers);  // a never-measured marker has no gap to fill
}

TEST_CASE(
    "The offline fill fills one marker's edge gap from the others, not frames where no "
    "marker is measured",
    "[gaps]") {
  Recording r = recording(2.0, true);
  const int hand = segment_named(*r.model, "r_hand");
  // The hand's markers hidden for the first 30 frames (the others seen: a one-sided fill), and
  // every marker hidden in the first 10 and the last 10 frames (nothing to fill from).
  std::vector<std::uint8_t> visible = hide_segment(r, hand, 0, 30);
  for (std::size_t f = 0; f < r.frames; ++f)
    if (f < 10 || f + 10 >= r.frames)
      for (std::size_t i = 0; i < r.n; ++i) visible[f * r.n + i] = 0;
  const TwoSidedFill fill = fill_two_sided(r.setup, r.times_s, r.measured_m, visible);
  for (std::size_t f = 0; f < r.frames; ++f)
    for (std::size_t i = 0; i < r.n; ++i) {
      const std::size_t k = f * r.n + i;
      const bool empty_edge = f < 10 || f + 10 >= r.frames;
      INFO("frame " << f << ", marker " << i);
      CHECK(fill.filled[k] == (!empty_edge && !visible[k] ? 1 : 0));
      CHECK(fill.markers_m[k].allFinite() == !empty_edge);
    }
}

TEST_CASE("The offline fill lets the skeleton compete only where two more markers of the "
          "segment hold it through the gap",
          "[gaps][donors]") {
  Recording r = recording(0.6, true);
  const int head = segment_named(*r.model, "head");
  std::vector<std::size_t> markers;  // the head's four
  for (std::size_t i = 0; i < r.n; ++i)
    if (r.segment[i] == head) markers.push_back(i);
  REQUIRE(markers.size() == 4);
  const std::size_t first = 20, end = 35;
  // The first head marker is lost, and with it `lost_too` more of the head's.
  const auto method = [&](std::size_t lost_too) {
    std::vector<std::uint8_t> visible(r.frames * r.n, 1);
    for (std::size_t f = first; f < end; ++f)
      for (std::size_t k = 0; k <= lost_too; ++k) visible[f * r.n + markers[k]] = 0;
    const TwoSidedFill fill = fill_two_sided(r.setup, r.times_s, r.measured_m, visible);
    for (const FilledGap& g : fill.gaps)
      if (g.marker == static_cast<int>(markers[0])) return g.method;
    FAIL("no gap filled");
    return FillMethod::skeleton;
  };
  // One holder: the segment's frame is not scored (the lost marker placed it
  // in the past, which would flatter it), so the donors fill alone. (With
  // three, the skeleton competes, but on noise-free motion it ties with exact
  // donor triples, so whether it is among the best three is down to rounding:
  // clang and gcc disagree.)
  CHECK(method(2) == FillMethod::donors);
}

namespace {
// `fabrik eval gaps` on subject01_walk1 calibrated with the shipped gait2354;
// nothing (and a warning) without ../shared/data.
std::optional<eval::GapReport> walk1_gaps(const eval::GapOptions& options) {
  const std::string dir = FABRIK_SHARED_DATA_DIR;
  const std::string static_path = dir + "/subject01_static.trc", walk_path = dir + "/subject01_walk1.trc";
  if (!std::filesystem::exists(static_path) || !std::filesystem::exists(walk_path)) {
    WARN("SKIPPED: " << static_path << " or " << walk_path << " not found");
    return std::nullopt;
  }
  const DaemonConfig config = eval::calibrate_config(
      std::string(FABRIK_SOURCE_DIR) + "/config/templates/gait2354.json", static_path);
  return eval::eval_gaps(config, io::read_trial(walk_path), options);
}
}  // namespace

// The must-show on the one trial we have (docs/gap-filling.md).
// Without donor markers (prediction.donors false) the live median is 9.84 mm
// and the offline one 8.67 mm (2026-12-02): both fail. A returning marker's hand-over
// started at the model point plus the marker's old offset fails the return
// jump (11.4 mm): it must start at the model's own point of the marker.
// The forearms pronate since issue 19: a withheld wrist marker leaves its
// forearm's axial rotation to the other wrist marker, 25 mm off the axis, and
// the live 1 s median rose from 7.1 to 8.3 mm (wrist and elbow gaps 4-12 ->
// 7-16 mm); the bound moved from 8 to 8.5 mm for it (a known cost, in the note).
TEST_CASE("walk1 must-show: 1 s gaps live median <= 8.5 mm and every marker <= 30 mm, offline "
          "<= 5 and 20 mm, 2 s live median <= 15 mm, return jumps <= 5 mm",
          "[gaps][data]") {
  eval::GapOptions options;
  options.windows_s = {1.0, 2.0};
  const std::optional<eval::GapReport> report = walk1_gaps(options);
  if (!report) return;
  const eval::GapReport& g = *report;
  REQUIRE(g.summary.size() == 4);
  for (const eval::GapSummary& s : g.summary) {
    INFO(eval::to_string(s.mode) << " " << s.window_s << " s: median " << s.median_rms_m * 1e3
                                 << " mm, worst " << s.worst_marker << " " << s.worst_rms_m * 1e3
                                 << " mm, return jump " << s.return_jump_m * 1e3 << " mm");
    const bool live = s.mode == eval::GapMode::live;
    if (s.window_s == 1.0) {
      CHECK(s.median_rms_m <= (live ? 8.5e-3 : 5e-3));
      CHECK(s.worst_rms_m <= (live ? 30e-3 : 20e-3));
    } else if (live) {
      CHECK(s.median_rms_m <= 15e-3);
    }
    if (live) CHECK(s.return_jump_m <= 5e-3);
  }
}

TEST_CASE("Donor candidates are the markers on segments at most donor_max_joints joints away",
          "[gap][donors]") {
  // Against the definition: joints between two segments of a tree are their
  // depths' sum less twice their common ancestor's.
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Model model = fabrik::test::random_tree_model(rng, 2 + trial);
    std::vector<int> segments;
    for (const Point& p : model.points)
      if (p.kind == PointKind::marker) segments.push_back(p.segment);
    const auto depth = [&](int s) {
      int d = 0;
      for (; model.segments[s].parent >= 0; s = model.segments[s].parent) ++d;
      return d;
    };
    const auto joints_between = [&](int a, int b) {
      int da = depth(a), db = depth(b), steps = 0;
      for (; da > db; --da, ++steps) a = model.segments[a].parent;
      for (; db > da; --db, ++steps) b = model.segments[b].parent;
      for (; a != b; steps += 2) a = model.segments[a].parent, b = model.segments[b].parent;
      return steps;
    };
    const std::size_t n = segments.size();
    for (int max_joints : {-1, 0, 1, 2, 3}) {
      const std::vector<std::uint8_t> nearby = nearby_markers(model, segments, max_joints);
      REQUIRE(nearby.size() == n * n);
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t m = 0; m < n; ++m) {
          CAPTURE(trial, max_joints, i, m);
          const bool expected = i != m && joints_between(segments[i], segments[m]) <= max_joints;
          CHECK(static_cast<bool>(nearby[i * n + m]) == expected);
        }
    }
  }
}

// The hand-over's length, known answers on a still subject (the model's point of a returning
// marker is where it was): a marker back 10 mm off its model point after a one-frame gap
// (last seen two frames before) moves its target at 0.01 m / 0.02 s = 0.5 m/s, half the way
// in the frame it returns and the rest in the next; after a 1 s gap, at the 0.2 m/s floor,
// 2 mm a frame.
TEST_CASE(
    "A returning marker's target moves at the larger of 0.2 m/s and its offset over "
    "its gap",
    "[gaps]") {
  const Model model = test::fullbody_model();
  const std::vector<int> points = model.marker_points();
  const std::size_t n = points.size();
  PredictionSettings settings;
  settings.enabled = true;
  settings.level = -1;
  const Posture still = Posture::rest(model);
  std::vector<Eigen::Vector3d> at_model(n);
  for (std::size_t i = 0; i < n; ++i) at_model[i] = still.point_world_m(model, points[i]);
  const Eigen::Vector3d offset_m(0.010, 0.0, 0.0);
  // Marker 0's target's distance from its measurement in the frames from its return on.
  auto handover_mm = [&](int hidden_frames) {
    GapPredictor predictor(model, points, settings);
    std::vector<Eigen::Quaterniond> q(predictor.orientation_targets().size());
    std::vector<std::uint8_t> q_visible(q.size());
    std::vector<Eigen::Vector3d> markers(n);
    std::vector<double> gap_s(n);
    std::vector<double> out;
    const int back = 6 + hidden_frames;
    for (int f = 0; f < back + 4; ++f) {
      const double t_s = f * 0.01;
      std::vector<std::uint8_t> seen(n, 1);
      if (f >= 6 && f < back) seen[0] = 0;
      std::vector<Eigen::Vector3d> measured = at_model;
      if (f >= back) measured[0] += offset_m;
      std::vector<Eigen::Vector3d> target = measured;
      predictor.before_solve(t_s, seen, target, q, q_visible);
      if (f >= back) out.push_back((target[0] - measured[0]).norm() * 1e3);
      predictor.after_solve(t_s, still, seen, measured, markers, gap_s);
    }
    return out;
  };
  const std::vector<double> short_gap = handover_mm(1), long_gap = handover_mm(100);
  CAPTURE(short_gap, long_gap);
  CHECK(short_gap[0] == Approx(5.0).margin(1e-6));
  CHECK(short_gap[1] == Approx(0.0).margin(1e-6));
  CHECK(long_gap[0] == Approx(8.0).margin(1e-6));
  CHECK(long_gap[1] == Approx(6.0).margin(1e-6));
  CHECK(long_gap[3] == Approx(2.0).margin(1e-6));
}
