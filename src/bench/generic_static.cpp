#include "generic_static.hpp"
#include "synth/random_draws.hpp"

#include <random>
#include <string>
#include <utility>
#include <vector>

namespace fabrik::bench {

namespace {

// Right-side and midline landmarks of a generic 1.75 m adult, millimetres, x anterior, y up,
// z right; the left side mirrors z. Heights follow the usual segment proportions of stature
// (Drillis & Contini 1966, as tabulated by Winter 2009: hip 0.53 H, knee 0.285 H, ankle
// 0.039 H, shoulder 0.818 H, upper arm 0.186 H, forearm 0.146 H, foot 0.152 H); marker
// offsets from the bones are typical skin-marker placements, not one subject's.
struct Landmark {
  const char* name;  // without the "R."/"L." prefix for sided markers
  bool sided;
  double x, y, z;
};

constexpr Landmark kLandmarks[] = {
    // Pelvis: ASIS 250 mm apart, sacral marker 190 mm behind them.
    {"ASIS", true, 120, 1000, 125},
    {"V.Sacral", false, -70, 1020, 0},
    // Thigh (hip centre near (40, 930, 85), knee centre (45, 500, 90)).
    {"Thigh.Upper", true, 40, 780, 150},
    {"Thigh.Front", true, 100, 700, 105},
    {"Thigh.Rear", true, -10, 650, 140},
    {"Knee.Lat", true, 45, 500, 140},
    {"Knee.Med", true, 45, 500, 40},
    // Shank (ankle centre (30, 75, 100)).
    {"Shank.Upper", true, 40, 420, 140},
    {"Shank.Front", true, 90, 360, 95},
    {"Shank.Rear", true, 0, 300, 145},
    {"Ankle.Lat", true, 25, 75, 135},
    {"Ankle.Med", true, 35, 85, 65},
    // Foot: 265 mm from heel to toe tip.
    {"Heel", true, -40, 45, 100},
    {"Midfoot.Sup", true, 90, 60, 85},
    {"Midfoot.Lat", true, 90, 35, 140},
    {"Toe.Lat", true, 160, 25, 140},
    {"Toe.Med", true, 170, 30, 70},
    {"Toe.Tip", true, 225, 25, 95},
    // Trunk and head.
    {"Sternum", false, 110, 1300, 0},
    {"Acromium", true, 0, 1440, 180},
    {"Temple", true, 80, 1620, 65},
    {"Top.Head", false, 10, 1750, 0},
    // Arms out sideways, elbows slightly bent forward (the arm's plane defines its frame).
    {"Bicep", true, 25, 1400, 330},
    {"Elbow", true, 0, 1390, 480},
    {"Wrist.Med", true, 90, 1372, 718},
    {"Wrist.Lat", true, 35, 1382, 740},
};

}  // namespace

io::MarkerTrial generic_gait2354_static(int frames, double noise_m, unsigned seed) {
  std::vector<std::pair<std::string, Eigen::Vector3d>> markers;
  for (const Landmark& l : kLandmarks) {
    const Eigen::Vector3d p_m = Eigen::Vector3d(l.x, l.y, l.z) * 1e-3;
    if (!l.sided) {
      markers.emplace_back(l.name, p_m);
      continue;
    }
    markers.emplace_back(std::string("R.") + l.name, p_m);
    markers.emplace_back(std::string("L.") + l.name, Eigen::Vector3d(p_m.x(), p_m.y(), -p_m.z()));
  }
  io::MarkerTrial trial;
  trial.rate_hz = 60.0;
  for (const auto& m : markers) trial.labels.push_back(m.first);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_m);
  for (int f = 0; f < frames; ++f)
    for (const auto& m : markers) trial.positions_m.push_back(m.second + draw_vector3(noise, rng));
  return trial;
}

}  // namespace fabrik::bench
