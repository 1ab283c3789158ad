// What every reader of a markers payload (the full reader and the fast paths
// of marker_json_fast.hpp and marker_msgpack_fast.hpp) does the same way when
// it fills a MarkerFrame, so the readers cannot drift apart on it.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "marker_codec.hpp"
#include "marker_name_index.hpp"
#include "tracking/confidence.hpp"

namespace fabrik::wire {

// What the decoder needs from a fast path besides the frame: as the full
// reader's SAX handler gives it.
struct FastFrameTop {
  bool has_frame = false;
  double m_per_unit = 0.0;  // 0: not given
};

// Lists a name not in the config, cut to the list entry's reserved capacity,
// so listing never allocates (up to the list's length, then only counted).
inline void list_unknown_name(std::vector<std::string>& list, int& listed, std::string_view name) {
  if (listed >= static_cast<int>(list.size())) return;
  std::string& entry = list[listed++];
  entry.assign(name.data(), std::min(name.size(), entry.capacity()));
}

// Whether a listed name starts with `prefix` ("X:").
inline bool listed_prefix(const std::vector<std::string>& list, int listed,
                          std::string_view prefix) {
  for (int k = 0; k < listed; ++k)
    if (std::string_view(list[k]).starts_with(prefix)) return true;
  return false;
}

// Marker i's 4th value, as every reader takes it (clamped_confidence); one that is not
// finite occludes the marker.
inline void set_confidence(MarkerFrame& out, int i, double confidence) {
  ++out.confidence_count;
  const std::optional<float> clamped = clamped_confidence(confidence);
  if (!clamped) out.visible[i] = 0;
  out.confidence[i] = clamped.value_or(0.0f);
}

// A frame's "units": metres per unit, 0 for anything but "mm" and "m".
inline double metres_per_unit(std::string_view units) {
  return units == "mm" ? 1e-3 : units == "m" ? 1.0 : 0.0;
}

// A fast path's "units" or "subject" member, whose string value it has read,
// as the full reader takes it. False: units the full reader refuses.
inline bool set_units_or_subject(std::string_view key, std::string_view value, MarkerFrame& out,
                                 FastFrameTop& top) {
  if (key == "units") {
    top.m_per_unit = metres_per_unit(value);
    return top.m_per_unit > 0.0;
  }
  set_frame_subject(out, value);
  return true;
}

// The config's index of the frame's marker at `position` (0, 1, ...) named
// `name`, or -1, counted as known or unknown (and listed) in `out`.
inline int count_marker(MarkerNameIndex& names, std::size_t position, std::string_view name,
                        MarkerFrame& out) {
  const int i = names.find_at(position, name);
  if (i >= 0) {
    ++out.known_count;
  } else {
    ++out.unknown_count;
    const bool foreign = names.foreign(name);
    out.unknown_foreign += foreign ? 1 : 0;
    // Beside a multi-subject config's subjects, another subject's names are listed once per
    // subject, so that one subject's many markers cannot take every slot of the list.
    if (out.unknown_count > out.unknown_skip &&
        (!foreign || !names.of_subjects() ||
         !listed_prefix(out.unknown_names, out.unknown_listed, name.substr(0, name.find(':') + 1))))
      list_unknown_name(out.unknown_names, out.unknown_listed, name);
  }
  return i;
}

// Known marker i measured at p (payload units), with its confidence if one
// was given: a position that is not finite is an occlusion.
inline void set_marker(MarkerFrame& out, int i, const Eigen::Vector3d& p, const double* confidence) {
  out.p_world_m[i] = p;
  out.visible[i] = p.allFinite() ? 1 : 0;
  if (confidence) set_confidence(out, i, *confidence);
}

}  // namespace fabrik::wire
