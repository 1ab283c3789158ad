#include "eval.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>

#include "calib/calibrate.hpp"
#include "common/quantile.hpp"
#include "offline/solve_trial.hpp"
#include "synth/synthetic_motion.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::eval {

namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}
std::string mm2(double metres) {
  return fmt("%.2f", metres * 1e3);
}
std::string pad(std::string s, std::size_t width, bool right = false) {
  if (s.size() >= width) return s + " ";
  const std::string fill(width - s.size(), ' ');
  return right ? fill + s + " " : s + fill + " ";
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Running RMS and max of distances.
struct Acc {
  double sq = 0.0, max = 0.0;
  int n = 0;
  std::string max_name;
  void add(double d, const std::string& name = {}) {
    sq += d * d;
    ++n;
    if (d > max || n == 1) max = d, max_name = name;
  }
  double rms() const { return n ? std::sqrt(sq / n) : 0.0; }
};

// Trial column of each tracked marker, -1 if the trial lacks it.
std::vector<int> columns(const DaemonConfig& config, const io::MarkerTrial& trial) {
  std::vector<int> c;
  for (const MarkerTarget& m : config.tracker.markers) c.push_back(trial.find(m.marker));
  return c;
}

// One tracking pass over frames [0, frames) with some samples withheld.
struct Run {
  std::size_t refs = 0, n = 0;
  std::vector<Eigen::Vector3d> ref_m;      // [frame * refs + r]
  std::vector<Eigen::Vector3d> markers_m;  // [frame * n + i]: the model's position
  std::vector<double> rms_m;               // residual over the markers it saw
};

// hide(frame, marker) -> true withholds that sample from the tracker.
template <class Hide>
Run track(const DaemonConfig& config, const io::MarkerTrial& trial, const std::vector<int>& col,
          const ReferencePoints& refs, std::size_t frames, Hide hide) {
  Tracker tracker(config.tracker);
  const Model& model = tracker.model();
  const int n = tracker.marker_count();
  Run run;
  run.refs = refs.points.size();
  run.n = static_cast<std::size_t>(n);
  run.ref_m.reserve(frames * run.refs);
  run.markers_m.reserve(frames * run.n);
  std::vector<Eigen::Vector3d> measured(n);
  std::vector<std::uint8_t> visible(n);
  for (std::size_t f = 0; f < frames; ++f) {
    for (int i = 0; i < n; ++i) {
      measured[i] = col[i] >= 0 ? trial.at(f, col[i]) : Eigen::Vector3d::Constant(NAN);
      visible[i] = measured[i].allFinite() && !hide(f, i) ? 1 : 0;
    }
    const TrackResult& r = tracker.track(trial.time_s(f), measured, visible);
    for (int p : refs.points) run.ref_m.push_back(tracker.posture().point_world_m(model, p));
    run.markers_m.insert(run.markers_m.end(), r.markers_world_m.begin(), r.markers_world_m.end());
    run.rms_m.push_back(r.residual_rms_m);
  }
  return run;
}

// Worst residual of the least-squares rigid fit (Kabsch) of local points onto measured ones.
// Returns {residual, index}; fewer than two points fit exactly.
std::pair<double, int> rigid_fit_worst(const std::vector<Eigen::Vector3d>& local,
                                       const std::vector<Eigen::Vector3d>& world) {
  const std::size_t k = local.size();
  if (k < 2) return {0.0, k ? 0 : -1};
  Eigen::Vector3d cl = Eigen::Vector3d::Zero(), cw = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < k; ++i) cl += local[i], cw += world[i];
  cl /= static_cast<double>(k);
  cw /= static_cast<double>(k);
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < k; ++i) h += (local[i] - cl) * (world[i] - cw).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d rot = svd.matrixV() * d * svd.matrixU().transpose();
  double worst = -1.0;
  int at = -1;
  for (std::size_t i = 0; i < k; ++i) {
    const double e = (rot * (local[i] - cl) + cw - world[i]).norm();
    if (e > worst) worst = e, at = static_cast<int>(i);
  }
  return {worst, at};
}

}  // namespace

DaemonConfig calibrate_config(const std::string& template_path, const std::string& static_path) {
  const calib::CalibTemplate tmpl = calib::load_template_file(template_path);
  const io::MarkerTrial trial = io::read_trial(static_path);
  const calib::CalibrationResult r = calib::calibrate(tmpl, trial, static_path);
  return load_daemon_config(r.config.dump(), "<calibrated from " + static_path + ">");
}

ReferencePoints reference_points(const Model& model) {
  ReferencePoints refs;
  auto add = [&](int p) {
    const std::string& name = model.points[p].name;
    refs.points.push_back(p);
    refs.names.push_back(name);
    const bool sided = name.size() > 2 && (name[0] == 'r' || name[0] == 'l') && name[1] == '_';
    refs.groups.push_back(sided ? name.substr(2) : name);
  };
  for (const Joint& j : model.joints) add(j.point);
  for (std::size_t p = 0; p < model.points.size(); ++p)
    if (model.points[p].kind == PointKind::end_site) add(static_cast<int>(p));
  return refs;
}

// ---------------------------------------------------------------- walk

WalkReport eval_walk(const DaemonConfig& config, const io::MarkerTrial& trial) {
  const TrialSolution s = solve_trial(config, trial);
  const Model& model = *config.tracker.model;
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = columns(config, trial);
  WalkReport r;
  r.rate_hz = trial.rate_hz;
  r.rms_m = s.rms_m;
  r.max_m = s.max_m;
  const std::size_t frames = trial.frames();
  std::vector<Acc> acc(markers.size());
  double it_sum = 0.0;
  for (std::size_t f = 0; f < frames; ++f) {
    r.worst.push_back(s.worst[f] >= 0 ? markers[s.worst[f]].marker : "");
    r.rms_mean_m += s.rms_m[f] / static_cast<double>(frames);
    r.rms_worst_m = std::max(r.rms_worst_m, s.rms_m[f]);
    if (s.max_m[f] > r.max_m_over_frames)
      r.max_m_over_frames = s.max_m[f], r.max_frame = f, r.max_marker = r.worst.back();
    it_sum += s.iterations[f];
    for (std::size_t i = 0; i < markers.size(); ++i) {
      if (col[i] < 0 || !trial.at(f, col[i]).allFinite()) continue;
      acc[i].add((s.markers.at(f, i) - trial.at(f, col[i])).norm());
    }
    // The rigid-cluster bound: each segment's measured markers fitted alone.
    double worst = 0.0;
    std::string worst_name;
    for (std::size_t seg = 0; seg < model.segments.size(); ++seg) {
      std::vector<Eigen::Vector3d> local, world;
      std::vector<std::string> names;
      for (std::size_t i = 0; i < markers.size(); ++i) {
        const Point& p = model.points[markers[i].point];
        if (p.segment != static_cast<int>(seg) || col[i] < 0) continue;
        if (!trial.at(f, col[i]).allFinite()) continue;
        local.push_back(p.p_local_m);
        world.push_back(trial.at(f, col[i]));
        names.push_back(markers[i].marker);
      }
      const auto [e, at] = rigid_fit_worst(local, world);
      if (at >= 0 && e > worst) worst = e, worst_name = names[at];
    }
    r.cluster_max_m.push_back(worst);
    r.cluster_worst.push_back(worst_name);
    if (worst > r.cluster_max_over_frames_m)
      r.cluster_max_over_frames_m = worst, r.cluster_max_frame = f,
      r.cluster_max_marker = worst_name;
  }
  r.iterations_mean = frames ? it_sum / static_cast<double>(frames) : 0.0;
  for (std::size_t i = 0; i < markers.size(); ++i) {
    const std::string& seg = model.segments[model.points[markers[i].point].segment].name;
    r.markers.push_back({markers[i].marker, seg, acc[i].rms(), acc[i].max, acc[i].n});
  }
  return r;
}

std::string walk_table(const WalkReport& r) {
  std::string out;
  const std::size_t frames = r.rms_m.size();
  out += "frames                      " + std::to_string(frames) + " at " + fmt("%g", r.rate_hz) +
         " Hz, " + fmt("%.1f", r.iterations_mean) + " solver iterations on average\n";
  out += "marker residual RMS         " + mm2(r.rms_mean_m) + " mm mean over frames (worst frame " +
         mm2(r.rms_worst_m) + " mm)\n";
  out += "per-frame max residual      " + mm2(r.max_m_over_frames) + " mm at most (" +
         r.max_marker + ", frame index " + std::to_string(r.max_frame) + ")\n";
  out += "rigid-cluster bound         " + mm2(r.cluster_max_over_frames_m) + " mm at most (" +
         r.cluster_max_marker + ", frame index " + std::to_string(r.cluster_max_frame) +
         "): each segment's markers fitted alone, no joints\n\n";
  out += pad("marker", 16) + pad("segment", 12) + pad("RMS mm", 8, true) + pad("max mm", 8, true) +
         "\n";
  std::vector<MarkerStats> sorted = r.markers;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const MarkerStats& a, const MarkerStats& b) { return a.rms_m > b.rms_m; });
  for (const MarkerStats& m : sorted)
    out += pad(m.marker, 16) + pad(m.segment, 12) + pad(mm2(m.rms_m), 8, true) +
           pad(mm2(m.max_m), 8, true) + "\n";
  return out;
}

nlohmann::json walk_json(const WalkReport& r) {
  nlohmann::json markers = nlohmann::json::array();
  for (const MarkerStats& m : r.markers)
    markers.push_back({{"marker", m.marker},
                       {"segment", m.segment},
                       {"rms_mm", m.rms_m * 1e3},
                       {"max_mm", m.max_m * 1e3},
                       {"samples", m.samples}});
  return {{"frames", r.rms_m.size()},
          {"rate_hz", r.rate_hz},
          {"rms_mean_mm", r.rms_mean_m * 1e3},
          {"rms_worst_frame_mm", r.rms_worst_m * 1e3},
          {"max_mm", r.max_m_over_frames * 1e3},
          {"max_frame_index", r.max_frame},
          {"max_marker", r.max_marker},
          {"cluster_bound_max_mm", r.cluster_max_over_frames_m * 1e3},
          {"cluster_bound_frame_index", r.cluster_max_frame},
          {"cluster_bound_marker", r.cluster_max_marker},
          {"iterations_mean", r.iterations_mean},
          {"markers", markers}};
}

void write_walk_csv(const std::string& path, const WalkReport& r) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << "frame,time_s,rms_mm,max_mm,worst_marker,cluster_max_mm,cluster_worst_marker\n";
  for (std::size_t f = 0; f < r.rms_m.size(); ++f)
    out << f << ',' << fmt("%.4f", static_cast<double>(f) / r.rate_hz) << ','
        << fmt("%.3f", r.rms_m[f] * 1e3) << ',' << fmt("%.3f", r.max_m[f] * 1e3) << ','
        << r.worst[f] << ',' << fmt("%.3f", r.cluster_max_m[f] * 1e3) << ',' << r.cluster_worst[f]
        << '\n';
}

// ---------------------------------------------------------------- gaps

GapReport eval_gaps(const DaemonConfig& config, const io::MarkerTrial& trial,
                    const GapOptions& options) {
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = columns(config, trial);
  const ReferencePoints refs = reference_points(*config.tracker.model);
  const std::size_t frames = trial.frames();
  const Run full = track(config, trial, col, refs, frames, [](std::size_t, int) { return false; });

  std::vector<int> withheld;
  if (options.markers.empty()) {
    for (std::size_t i = 0; i < markers.size(); ++i)
      if (col[i] >= 0) withheld.push_back(static_cast<int>(i));
  } else {
    for (const std::string& name : options.markers) {
      int found = -1;
      for (std::size_t i = 0; i < markers.size(); ++i)
        if (markers[i].marker == name && col[i] >= 0) found = static_cast<int>(i);
      if (found < 0)
        throw std::invalid_argument("gaps: '" + name + "' is not a tracked marker of the trial");
      withheld.push_back(found);
    }
  }

  GapReport report;
  report.rate_hz = trial.rate_hz;
  const auto stride =
      static_cast<std::size_t>(std::max(1.0, std::round(options.stride_s * trial.rate_hz)));
  for (double window_s : options.windows_s) {
    const auto len = static_cast<std::size_t>(std::round(window_s * trial.rate_hz));
    if (len < 1 || len > frames) continue;
    GapSummary sum;
    sum.window_s = window_s;
    Acc all_joints;
    std::vector<double> rms, maxes;
    for (int i : withheld) {
      GapStats row;
      row.marker = markers[i].marker;
      row.window_s = window_s;
      Acc err, joints;
      for (std::size_t start = 0; start + len <= frames; start += stride) {
        const std::size_t end = start + len;
        // Frames after the gap cannot change what was predicted inside it.
        const Run run = track(config, trial, col, refs, end, [&](std::size_t f, int m) {
          return m == i && f >= start && f < end;
        });
        GapTrace trace{row.marker, window_s, static_cast<int>(start), {}, {}};
        for (std::size_t f = start; f < end; ++f) {
          const Eigen::Vector3d& real = trial.at(f, col[i]);
          if (!real.allFinite()) continue;  // a real gap: nothing to compare with
          const Eigen::Vector3d& pred = run.markers_m[f * run.n + i];
          err.add((pred - real).norm());
          trace.real_m.push_back(real);
          trace.predicted_m.push_back(pred);
          for (std::size_t p = 0; p < run.refs; ++p) {
            const double d = (run.ref_m[f * run.refs + p] - full.ref_m[f * full.refs + p]).norm();
            joints.add(d);
            all_joints.add(d);
          }
        }
        ++row.windows;
        report.traces.push_back(std::move(trace));
      }
      row.samples = err.n;
      row.rms_m = err.rms();
      row.max_m = err.max;
      row.joint_rms_m = joints.rms();
      row.joint_max_m = joints.max;
      if (row.samples == 0) continue;
      rms.push_back(row.rms_m);
      maxes.push_back(row.max_m);
      if (row.rms_m > sum.worst_rms_m) sum.worst_rms_m = row.rms_m, sum.worst_marker = row.marker;
      sum.windows += row.windows;
      report.rows.push_back(row);
    }
    sum.markers = static_cast<int>(rms.size());
    sum.median_rms_m = median(rms);
    sum.median_max_m = median(maxes);
    sum.joint_rms_m = all_joints.rms();
    sum.joint_max_m = all_joints.max;
    report.summary.push_back(sum);
  }
  return report;
}

std::string gaps_table(const GapReport& r) {
  std::string out;
  std::vector<double> windows;
  for (const GapSummary& s : r.summary) windows.push_back(s.window_s);
  out +=
      "Withheld marker vs the model's gap-filled position (RMS / max mm); joint centres and end\n"
      "sites vs the all-markers solution during the gap (RMS / max mm)\n\n";
  out += pad("marker", 16);
  for (double w : windows) {
    const std::string t = fmt("%gs", w);
    out += pad(t + " RMS", 9, true) + pad(t + " max", 9, true) + pad("joint RMS", 10, true) +
           pad("joint max", 10, true);
  }
  out += "\n";
  std::vector<std::string> names;
  for (const GapStats& g : r.rows)
    if (std::find(names.begin(), names.end(), g.marker) == names.end()) names.push_back(g.marker);
  for (const std::string& name : names) {
    out += pad(name, 16);
    for (double w : windows) {
      const auto it = std::find_if(r.rows.begin(), r.rows.end(), [&](const GapStats& g) {
        return g.marker == name && g.window_s == w;
      });
      if (it == r.rows.end()) {
        out += pad("-", 9, true) + pad("-", 9, true) + pad("-", 10, true) + pad("-", 10, true);
        continue;
      }
      out += pad(mm2(it->rms_m), 9, true) + pad(mm2(it->max_m), 9, true) +
             pad(mm2(it->joint_rms_m), 10, true) + pad(mm2(it->joint_max_m), 10, true);
    }
    out += "\n";
  }
  out += "\n";
  for (const GapSummary& s : r.summary)
    out += fmt("%g s gaps: ", s.window_s) + std::to_string(s.markers) + " markers, " +
           std::to_string(s.windows) + " windows; median over markers RMS " + mm2(s.median_rms_m) +
           " mm, max " + mm2(s.median_max_m) + " mm; worst marker " + s.worst_marker + " " +
           mm2(s.worst_rms_m) + " mm RMS; joints " + mm2(s.joint_rms_m) + " mm RMS, " +
           mm2(s.joint_max_m) + " mm max\n";
  return out;
}

nlohmann::json gaps_json(const GapReport& r) {
  nlohmann::json rows = nlohmann::json::array(), summary = nlohmann::json::array();
  for (const GapStats& g : r.rows)
    rows.push_back({{"marker", g.marker},
                    {"window_s", g.window_s},
                    {"windows", g.windows},
                    {"samples", g.samples},
                    {"rms_mm", g.rms_m * 1e3},
                    {"max_mm", g.max_m * 1e3},
                    {"joint_rms_mm", g.joint_rms_m * 1e3},
                    {"joint_max_mm", g.joint_max_m * 1e3}});
  for (const GapSummary& s : r.summary)
    summary.push_back({{"window_s", s.window_s},
                       {"markers", s.markers},
                       {"windows", s.windows},
                       {"median_rms_mm", s.median_rms_m * 1e3},
                       {"median_max_mm", s.median_max_m * 1e3},
                       {"worst_marker", s.worst_marker},
                       {"worst_rms_mm", s.worst_rms_m * 1e3},
                       {"joint_rms_mm", s.joint_rms_m * 1e3},
                       {"joint_max_mm", s.joint_max_m * 1e3}});
  return {{"summary", summary}, {"markers", rows}};
}

void write_gaps_csv(const std::string& path, const GapReport& r) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << "marker,window_s,start_frame,frame,time_s,real_x_mm,real_y_mm,real_z_mm,pred_x_mm,"
         "pred_y_mm,pred_z_mm,error_mm\n";
  for (const GapTrace& t : r.traces)
    for (std::size_t k = 0; k < t.real_m.size(); ++k) {
      const std::size_t f = static_cast<std::size_t>(t.first_frame) + k;
      out << t.marker << ',' << t.window_s << ',' << t.first_frame << ',' << f << ','
          << fmt("%.4f", static_cast<double>(f) / r.rate_hz);
      for (const Eigen::Vector3d* v : {&t.real_m[k], &t.predicted_m[k]})
        for (int a = 0; a < 3; ++a) out << ',' << fmt("%.3f", (*v)[a] * 1e3);
      out << ',' << fmt("%.3f", (t.predicted_m[k] - t.real_m[k]).norm() * 1e3) << '\n';
    }
}

// ---------------------------------------------------------------- reduction

std::vector<DropSet> gait2354_drop_sets() {
  return {
      {"none (full set)", {}},
      {"one per thigh/shank cluster",
       {"R.Thigh.Rear", "L.Thigh.Rear", "R.Shank.Rear", "L.Shank.Rear"}},
      {"arms: wrists only", {"R.Bicep", "R.Elbow", "L.Bicep", "L.Elbow"}},
      {"no thigh clusters",
       {"R.Thigh.Upper", "R.Thigh.Front", "R.Thigh.Rear", "L.Thigh.Upper", "L.Thigh.Front",
        "L.Thigh.Rear"}},
      {"no head", {"R.Temple", "L.Temple", "Top.Head"}},
      {"one foot marker fewer", {"R.Midfoot.Lat", "L.Midfoot.Lat"}},
      // Two markers per limb segment (three on the pelvis and feet), one per wrist, no head.
      {"minimal (26 of 41)",
       {"R.Temple", "L.Temple", "Top.Head", "R.Bicep", "L.Bicep", "R.Wrist.Med", "L.Wrist.Med",
        "R.Thigh.Rear", "L.Thigh.Rear", "R.Shank.Rear", "L.Shank.Rear", "R.Midfoot.Lat",
        "L.Midfoot.Lat", "R.Toe.Med", "L.Toe.Med"}},
  };
}

std::vector<ReductionRow> eval_reduction(const DaemonConfig& config, const io::MarkerTrial& trial,
                                         const std::vector<DropSet>& sets) {
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = columns(config, trial);
  const ReferencePoints refs = reference_points(*config.tracker.model);
  const std::size_t frames = trial.frames();
  const Run full = track(config, trial, col, refs, frames, [](std::size_t, int) { return false; });
  int present = 0;
  for (int c : col) present += c >= 0 ? 1 : 0;
  std::vector<ReductionRow> rows;
  for (const DropSet& set : sets) {
    std::vector<std::uint8_t> drop(markers.size(), 0);
    for (const std::string& name : set.markers) {
      const auto it = std::find_if(markers.begin(), markers.end(),
                                   [&](const MarkerTarget& m) { return m.marker == name; });
      if (it == markers.end())
        throw std::invalid_argument("reduction '" + set.name + "': '" + name +
                                    "' is not a tracked marker");
      drop[it - markers.begin()] = 1;
    }
    const Run run =
        track(config, trial, col, refs, frames, [&](std::size_t, int m) { return drop[m] != 0; });
    ReductionRow row;
    row.name = set.name;
    row.dropped = static_cast<int>(set.markers.size());
    row.kept = present - row.dropped;
    Acc all;
    std::map<std::string, Acc> groups;
    std::vector<std::string> order;
    for (std::size_t f = 0; f < frames; ++f) {
      row.marker_rms_mean_m += run.rms_m[f] / static_cast<double>(frames);
      for (std::size_t p = 0; p < run.refs; ++p) {
        const double d = (run.ref_m[f * run.refs + p] - full.ref_m[f * full.refs + p]).norm();
        all.add(d, refs.names[p]);
        if (!groups.count(refs.groups[p])) order.push_back(refs.groups[p]);
        groups[refs.groups[p]].add(d);
      }
    }
    row.rms_m = all.rms();
    row.max_m = all.max;
    row.max_point = all.max_name;
    for (const std::string& g : order) row.groups.push_back({g, groups[g].rms(), groups[g].max});
    rows.push_back(row);
  }
  return rows;
}

std::string reduction_table(const std::vector<ReductionRow>& rows) {
  if (rows.empty()) return "no drop sets\n";
  std::string out =
      "Joint centres and end sites with markers left out, vs the full set (mm: RMS/max over\n"
      "frames and both sides)\n\n";
  out += pad("drop set", 28) + pad("kept", 5, true) + pad("all RMS", 8, true) +
         pad("all max", 8, true);
  for (const GroupDeviation& g : rows.front().groups) out += pad(g.group, 10, true);
  out += pad("marker RMS", 11, true) + "\n";
  for (const ReductionRow& r : rows) {
    out += pad(r.name, 28) + pad(std::to_string(r.kept), 5, true) + pad(mm2(r.rms_m), 8, true) +
           pad(mm2(r.max_m), 8, true);
    for (const GroupDeviation& g : r.groups)
      out += pad(fmt("%.1f", g.rms_m * 1e3) + "/" + fmt("%.0f", g.max_m * 1e3), 10, true);
    out += pad(mm2(r.marker_rms_mean_m), 11, true) + "\n";
  }
  return out;
}

nlohmann::json reduction_json(const std::vector<ReductionRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  for (const ReductionRow& r : rows) {
    nlohmann::json groups = nlohmann::json::object();
    for (const GroupDeviation& g : r.groups)
      groups[g.group] = {{"rms_mm", g.rms_m * 1e3}, {"max_mm", g.max_m * 1e3}};
    out.push_back({{"name", r.name},
                   {"dropped", r.dropped},
                   {"kept", r.kept},
                   {"rms_mm", r.rms_m * 1e3},
                   {"max_mm", r.max_m * 1e3},
                   {"max_point", r.max_point},
                   {"marker_rms_mean_mm", r.marker_rms_mean_m * 1e3},
                   {"groups", groups}});
  }
  return out;
}

// ---------------------------------------------------------------- synthetic

std::vector<SyntheticRow> eval_synthetic(const DaemonConfig& config,
                                         const SyntheticOptions& options) {
  const Model& model = *config.tracker.model;
  const auto& markers = config.tracker.markers;
  std::vector<int> points;
  for (const MarkerTarget& m : markers) points.push_back(m.point);
  const auto frames = static_cast<std::size_t>(options.seconds * options.rate_hz);
  std::vector<SyntheticRow> rows;
  for (double noise_mm : options.noise_mm) {
    // Same seed for every noise level: the same motion, only the noise differs.
    MotionSettings settings;
    settings.seed = options.seed;
    SyntheticMotion motion(model, settings);
    Tracker tracker(config.tracker);
    Posture truth = Posture::rest(model);
    std::vector<Eigen::Vector3d> measured(points.size());
    const std::vector<std::uint8_t> visible(points.size(), 1);
    std::vector<double> errors;
    SyntheticRow row;
    row.noise_mm = noise_mm;
    row.frames = frames;
    Acc acc;
    for (std::size_t f = 0; f < frames; ++f) {
      const double t = static_cast<double>(f) / options.rate_hz;
      motion.posture_at(t, truth);
      motion.sample(truth, points, noise_mm * 1e-3, measured);
      const TrackResult& r = tracker.track(t, measured, visible);
      row.marker_rms_mean_m += r.residual_rms_m / static_cast<double>(frames);
      for (std::size_t j = 0; j < model.joints.size(); ++j) {
        const double e =
            (r.joints_world_m[j] - truth.point_world_m(model, model.joints[j].point)).norm();
        errors.push_back(e);
        acc.add(e);
      }
    }
    row.joint_rms_m = acc.rms();
    row.joint_max_m = acc.max;
    row.joint_p99_m = quantile(errors, 0.99);
    rows.push_back(row);
  }
  return rows;
}

std::string synthetic_table(const std::vector<SyntheticRow>& rows) {
  std::string out = "Joint centres vs the synthetic truth (every joint, every frame)\n\n";
  out += pad("noise mm", 9, true) + pad("frames", 7, true) + pad("RMS mm", 8, true) +
         pad("p99 mm", 8, true) + pad("max mm", 8, true) + pad("marker RMS", 11, true) + "\n";
  for (const SyntheticRow& r : rows)
    out += pad(fmt("%g", r.noise_mm), 9, true) + pad(std::to_string(r.frames), 7, true) +
           pad(mm2(r.joint_rms_m), 8, true) + pad(mm2(r.joint_p99_m), 8, true) +
           pad(mm2(r.joint_max_m), 8, true) + pad(mm2(r.marker_rms_mean_m), 11, true) + "\n";
  return out;
}

nlohmann::json synthetic_json(const std::vector<SyntheticRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  for (const SyntheticRow& r : rows)
    out.push_back({{"noise_mm", r.noise_mm},
                   {"frames", r.frames},
                   {"joint_rms_mm", r.joint_rms_m * 1e3},
                   {"joint_p99_mm", r.joint_p99_m * 1e3},
                   {"joint_max_mm", r.joint_max_m * 1e3},
                   {"marker_rms_mean_mm", r.marker_rms_mean_m * 1e3}});
  return out;
}

}  // namespace fabrik::eval
