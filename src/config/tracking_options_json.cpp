#include "tracking_options_json.hpp"

namespace fabrik {

void read_tracking_options(const JsonReader& root, TrackerSetup& setup) {
  if (root.has("outliers")) {
    const JsonReader o = root.at("outliers");
    o.only_keys({"enabled", "floor_mm", "median_factor", "moved_mm", "max_per_frame", "min_markers",
                 "relabel_swaps"});
    OutlierSettings& s = setup.outliers;
    s.enabled = o.get("enabled", s.enabled);
    s.floor_m = o.get("floor_mm", s.floor_m * 1e3, 1.0, 1e6) * 1e-3;
    s.median_factor = o.get("median_factor", s.median_factor, 1.0, 1e6);
    s.moved_m = o.get("moved_mm", s.moved_m * 1e3, 0.0, 1e6) * 1e-3;
    s.max_per_frame =
        static_cast<int>(o.get("max_per_frame", static_cast<long long>(s.max_per_frame), 0LL, 64LL));
    s.min_markers =
        static_cast<int>(o.get("min_markers", static_cast<long long>(s.min_markers), 3LL, 10000LL));
    s.relabel_swaps = o.get("relabel_swaps", s.relabel_swaps);
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
        c.get("max_iterations", static_cast<long long>(s.max_iterations), 1LL, 100000LL));
    s.after_gap_s = c.get("after_gap_s", s.after_gap_s, 0.0, 1e9);
    s.align = c.get("align", s.align);
  }
}

}  // namespace fabrik
