#include "walk.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <utility>

#include "distance_stats.hpp"
#include "offline/solve_trial.hpp"

namespace fabrik::eval {

namespace {

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

WalkReport eval_walk(const DaemonConfig& config, const io::MarkerTrial& trial) {
  const TrialSolution s = solve_trial(config, trial);
  const Model& model = *config.tracker.model;
  const auto& markers = config.tracker.markers;
  const std::vector<int> col = trial_columns(config, trial);
  WalkReport r;
  r.rate_hz = trial.rate_hz;
  r.clock = trial.clock();
  r.rms_m = s.rms_m;
  r.max_m = s.max_m;
  const std::size_t frames = trial.frames();
  std::vector<DistanceStats> acc(markers.size());
  double it_sum = 0.0;
  for (std::size_t f = 0; f < frames; ++f) {
    r.worst.push_back(s.worst[f] >= 0 ? markers[s.worst[f]].marker : "");
    r.rms_mean_m += s.rms_m[f] / static_cast<double>(frames);
    r.rms_worst_m = std::max(r.rms_worst_m, s.rms_m[f]);
    if (s.max_m[f] > r.max_m_over_frames)
      r.max_m_over_frames = s.max_m[f], r.max_frame = trial.clock().number(f), r.max_marker = r.worst.back();
    it_sum += s.iterations[f];
    for (std::size_t i = 0; i < markers.size(); ++i) {
      if (col[i] < 0 || !trial.at(f, col[i]).allFinite()) continue;
      acc[i].add((s.model_markers.at(f, i) - trial.at(f, col[i])).norm());
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
      r.cluster_max_over_frames_m = worst, r.cluster_max_frame = trial.clock().number(f),
      r.cluster_max_marker = worst_name;
  }
  r.iterations_mean = frames ? it_sum / static_cast<double>(frames) : 0.0;
  for (std::size_t i = 0; i < markers.size(); ++i) {
    const std::string& seg = model.segments[model.points[markers[i].point].segment].name;
    r.markers.push_back({markers[i].marker, seg, acc[i].rms(), acc[i].max, acc[i].n});
  }
  return r;
}

}  // namespace fabrik::eval
