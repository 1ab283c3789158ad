#include "tracking_options_json.hpp"

#include <algorithm>

#include "tracking/mirror_swap.hpp"
#include "tracking/settings_bounds.hpp"

namespace fabrik {

namespace {

// `outliers.mirror_pairs`: [["RHip", "LHip"], ...], names of the targets' markers.
std::vector<std::array<int, 2>> read_mirror_pairs(const JsonReader& r,
                                                  const std::vector<MarkerTarget>& markers) {
  r.expect_array();
  std::vector<std::array<int, 2>> pairs;
  for (std::size_t k = 0; k < r.value().size(); ++k) {
    const JsonReader pair = r.at(k);
    pair.expect_array();
    if (pair.value().size() != 2) pair.fail("a mirror pair has two names", "[\"RHip\", \"LHip\"]");
    std::array<int, 2> idx{};
    for (std::size_t j = 0; j < 2; ++j) {
      const std::string name = pair.at(j).as_string();
      const auto it = std::find_if(markers.begin(), markers.end(),
                                   [&](const MarkerTarget& m) { return m.marker == name; });
      if (it == markers.end())
        pair.at(j).fail("'" + name + "' is no tracked marker", "name a marker of the targets");
      idx[j] = static_cast<int>(it - markers.begin());
    }
    if (idx[0] == idx[1]) pair.fail("a mirror pair names one marker twice", "name two markers");
    pairs.push_back(idx);
    // The earlier pairs had no marker twice: one found now is in this pair.
    if (const int m = marker_in_two_pairs(pairs); m >= 0)
      pair.fail("'" + markers[static_cast<std::size_t>(m)].marker + "' is in an earlier pair too",
                "give each marker one mirror pair");
  }
  return pairs;
}

}  // namespace

void read_tracking_options(const JsonReader& root, TrackerSetup& setup) {
  if (root.has("outliers")) {
    const JsonReader o = root.at("outliers");
    o.only_keys({"enabled", "floor_mm", "median_factor", "moved_mm", "max_per_frame", "min_markers",
                 "relabel_swaps", "relabel_mirrored", "mirror_ratio", "mirror_floor_mm", "mirror_max_s",
                 "mirror_pairs"});
    OutlierSettings& s = setup.outliers;
    s.enabled = o.get("enabled", s.enabled);
    s.floor_m =
        o.get("floor_mm", s.floor_m * 1e3, settings_bounds::kLeastOutlierFloorM * 1e3, 1e6) * 1e-3;
    s.median_factor =
        o.get("median_factor", s.median_factor, settings_bounds::kLeastMedianFactor, 1e6);
    s.moved_m = o.get("moved_mm", s.moved_m * 1e3, 0.0, 1e6) * 1e-3;
    s.max_per_frame =
        static_cast<int>(o.get("max_per_frame", static_cast<long long>(s.max_per_frame), 0LL, 64LL));
    s.min_markers = static_cast<int>(
        o.get("min_markers", static_cast<long long>(s.min_markers),
              static_cast<long long>(settings_bounds::kLeastOutlierMarkers), 10000LL));
    s.relabel_swaps = o.get("relabel_swaps", s.relabel_swaps);
    s.relabel_mirrored = o.get("relabel_mirrored", s.relabel_mirrored);
    s.mirror_ratio = o.get("mirror_ratio", s.mirror_ratio, 0.0, settings_bounds::kMostFraction);
    s.mirror_floor_m = o.get("mirror_floor_mm", s.mirror_floor_m * 1e3, 0.0, 1e6) * 1e-3;
    s.mirror_max_s = o.get("mirror_max_s", s.mirror_max_s, 0.0, 3600.0);
    if (o.has("mirror_pairs")) setup.mirror_pairs = read_mirror_pairs(o.at("mirror_pairs"), setup.markers);
  }
  if (root.has("confidence")) {
    const JsonReader c = root.at("confidence");
    c.only_keys({"threshold", "scale_weight"});
    setup.confidence.threshold =
        c.get("threshold", setup.confidence.threshold, 0.0, settings_bounds::kMostFraction);
    setup.confidence.scale_weight = c.get("scale_weight", setup.confidence.scale_weight);
  }
  if (root.has("smoothing")) {
    const JsonReader f = root.at("smoothing");
    f.only_keys({"enabled", "min_cutoff_hz", "beta_per_m", "d_cutoff_hz"});
    SmoothingSettings& s = setup.smoothing;
    s.enabled = f.get("enabled", s.enabled);
    s.min_cutoff_hz = f.get("min_cutoff_hz", s.min_cutoff_hz, settings_bounds::kLeastCutoffHz, 1e4);
    s.beta_per_m = f.get("beta_per_m", s.beta_per_m, 0.0, 1e6);
    s.d_cutoff_hz = f.get("d_cutoff_hz", s.d_cutoff_hz, settings_bounds::kLeastCutoffHz, 1e4);
  }
  if (root.has("quality")) {
    const JsonReader q = root.at("quality");
    q.only_keys({"rms_mm", "max_mm"});
    setup.quality.rms_m = q.get("rms_mm", setup.quality.rms_m * 1e3, 0.0, 1e6) * 1e-3;
    setup.quality.max_m = q.get("max_mm", setup.quality.max_m * 1e3, 0.0, 1e6) * 1e-3;
  }
  if (root.has("cold_start")) {
    const JsonReader c = root.at("cold_start");
    c.only_keys({"max_iterations", "after_gap_s", "align"});
    ColdStartSettings& s = setup.cold_start;
    s.max_iterations = static_cast<int>(
        c.get("max_iterations", static_cast<long long>(s.max_iterations),
              static_cast<long long>(settings_bounds::kLeastColdIterations), 100000LL));
    s.after_gap_s = c.get("after_gap_s", s.after_gap_s, 0.0, 1e9);
    s.align = c.get("align", s.align);
  }
}

}  // namespace fabrik
