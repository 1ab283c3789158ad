#include "synth.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

#include <fstream>
#include "common/ascii_case.hpp"
#include "config/daemon_config.hpp"
#include "io/opensim_table.hpp"
#include "io/output_file.hpp"
#include "solver/joint_angles.hpp"
#include "solver/posture.hpp"
#include "solver/units.hpp"
#include "synth/synthetic_motion.hpp"

namespace fabrik::tools {

SynthSetup load_synth_setup(const std::string& config_path) {
  return synth_setup(load_daemon_config_file(config_path));
}

SynthSetup synth_setup(const DaemonConfig& config) {
  SynthSetup setup;
  setup.model = config.tracker.model;
  for (const MarkerTarget& t : config.tracker.markers) {
    setup.marker_names.push_back(t.marker);
    setup.marker_points.push_back(t.point);
  }
  return setup;
}

SynthTrial make_synth_trial(const SynthSetup& setup, const SynthOptions& o) {
  if (!(o.rate_hz > 0.0) || !(o.seconds > 0.0))
    throw std::invalid_argument("--seconds and --rate must be positive");
  if (!(o.noise_mm >= 0.0)) throw std::invalid_argument("--noise-mm must be >= 0");
  if (o.gaps < 0) throw std::invalid_argument("--gaps must be >= 0");
  const Model& m = *setup.model;
  const int n = std::max(1, static_cast<int>(std::lround(o.seconds * o.rate_hz)));
  const std::size_t markers = setup.marker_names.size();
  if (markers == 0) throw std::invalid_argument("the config tracks no markers");

  SynthTrial out;
  out.markers.labels = setup.marker_names;
  out.markers.rate_hz = o.rate_hz;
  out.markers.positions_m.resize(static_cast<std::size_t>(n) * markers);
  for (const Joint& j : m.joints) out.joints.labels.push_back(j.name);
  out.joints.rate_hz = o.rate_hz;
  out.joints.positions_m.resize(static_cast<std::size_t>(n) * m.joints.size());

  MotionSettings ms;
  ms.seed = o.seed;
  SyntheticMotion motion(m, ms);
  Posture posture = Posture::rest(m);
  const std::size_t nc = m.coordinates.size();
  for (const Coordinate& c : m.coordinates) {
    out.coordinate_names.push_back(c.name);
    out.coordinate_is_rotation.push_back(c.kind == CoordinateKind::rotation);
  }
  out.coordinates.resize(static_cast<std::size_t>(n) * nc);
  for (int f = 0; f < n; ++f) {
    motion.posture_at(f / o.rate_hz, posture);
    motion.sample(posture, setup.marker_points, o.noise_mm * 1e-3,
                  std::span(out.markers.positions_m).subspan(f * markers, markers));
    for (std::size_t j = 0; j < m.joints.size(); ++j)
      out.joints.at(f, j) = posture.point_world_m(m, m.joints[j].point);
    const std::span<double> c(out.coordinates.data() + f * nc, nc);
    coordinate_values(m, posture, c);
    if (f > 0) unwrap_coordinates(m, std::span<const double>(c.data() - nc, nc), c);
  }

  // Gap windows: never overlapping or touching on one marker, so each is one run of NaN.
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 17);
  std::uniform_real_distribution<double> length_s(0.2, 1.0);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(markers) - 1);
  for (int g = 0; g < o.gaps; ++g) {
    bool placed = false;
    for (int attempt = 0; attempt < 1000 && !placed; ++attempt) {
      GapWindow w;
      w.marker = pick(rng);
      w.frames = std::clamp(static_cast<int>(std::lround(length_s(rng) * o.rate_hz)), 1, n);
      w.first_frame = std::uniform_int_distribution<int>(0, n - w.frames)(rng);
      placed = true;
      for (const GapWindow& other : out.gaps)
        if (other.marker == w.marker && w.first_frame <= other.first_frame + other.frames &&
            other.first_frame <= w.first_frame + w.frames)
          placed = false;
      if (placed) out.gaps.push_back(w);
    }
    if (!placed)
      throw std::invalid_argument(
          "cannot fit " + std::to_string(o.gaps) + " non-overlapping gaps of 0.2-1 s into " +
          std::to_string(o.seconds) + " s of " + std::to_string(markers) + " markers");
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const GapWindow& w : out.gaps)
    for (int f = w.first_frame; f < w.first_frame + w.frames; ++f)
      out.markers.at(f, w.marker) = Eigen::Vector3d::Constant(nan);
  return out;
}

KeypointTrial make_keypoint_trial(const SynthSetup& setup, const SynthOptions& o,
                                  const KeypointCorruption& corruption) {
  SynthOptions exact = o;
  exact.noise_mm = 0.0;  // the keypoints' noise is the corruption's jitter
  exact.gaps = 0;
  KeypointTrial out;
  out.truth = make_synth_trial(setup, exact);
  out.keypoints = out.truth.markers;
  const std::vector<std::pair<int, int>> pairs = mirrored_pairs(setup.marker_names);
  const std::vector<int> limb = limbs_of_pairs(*setup.model, setup.marker_points, pairs);
  out.injected = corrupt_keypoints(out.keypoints.positions_m, setup.marker_names.size(),
                                   o.rate_hz, pairs, limb, corruption);
  return out;
}

void write_injected_csv(const std::string& path, const KeypointTrial& t) {
  std::ofstream out = io::open_output_file(path);
  out << "frame,time_s,kind,keypoints\n";
  const auto& labels = t.keypoints.labels;
  for (const InjectedRun& r : t.injected) {
    std::string names;
    for (std::size_t i = 0; i < r.keypoints.size(); ++i)
      names += (i ? ";" : "") + labels[static_cast<std::size_t>(r.keypoints[i])];
    for (int f = r.first_frame; f < r.first_frame + r.frames; ++f)
      out << t.keypoints.first_frame + f << ',' << t.keypoints.time_s(static_cast<std::size_t>(f))
          << ',' << injected_kind_name(r.kind) << ',' << names << '\n';
  }
  io::finish_output_file(out, path);
}

void write_truth_mot(const std::string& path, const SynthTrial& t) {
  io::OpenSimTable table = io::coordinates_table(t.coordinate_names, true);
  const std::size_t n = t.coordinate_names.size();
  std::vector<double> row(n);
  for (std::size_t f = 0; f < t.joints.frames(); ++f) {
    for (std::size_t c = 0; c < n; ++c)
      row[c] = t.coordinates[f * n + c] * (t.coordinate_is_rotation[c] ? kDegPerRad : 1.0);
    table.add_row(t.joints.time_s(f), row);
  }
  io::write_opensim_table(path, table);
}

std::string sidecar_stem(const std::string& trc_path) {
  const std::size_t n = trc_path.size();
  if (n >= 4 && iequals(std::string_view(trc_path).substr(n - 4), ".trc"))
    return trc_path.substr(0, n - 4);
  return trc_path;
}

std::string joints_sidecar_path(const std::string& trc_path) {
  return sidecar_stem(trc_path) + ".joints.trc";
}

}  // namespace fabrik::tools
