// The fast path of MarkerDecoder for JSON: the common shape of a markers
// payload read in one pass without the general reader:
//   {"frame": N, "time": T, "stamp_us": S, "units": "mm" | "m",
//    "markers": {"NAME": [x, y, z] | [x, y, z, confidence] | null, ...}}
// keys in any order (any of them absent or repeated), any JSON whitespace,
// names of printable ASCII without escapes. Anything else (other keys,
// "orientations", escapes, non-ASCII names, a malformed or out-of-range
// token, a byte order mark) is declined, and the caller runs the full reader
// (JsonSaxReader + the decoder's SAX handler) on the payload from the start:
// so every error message and validation rule is the full reader's.
// tests/test_codec.cpp checks that the two agree on many varied payloads.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "marker_codec.hpp"
#include "marker_name_index.hpp"

namespace fabrik::wire {

// What the decoder needs besides `out`: as the SAX handler's fields.
struct FastFrameTop {
  bool has_frame = false;
  double m_per_unit = 0.0;  // 0: not given
};

// True: `out` and `top` hold what the full reader would have given for
// `text` (`out` reset by the caller beforehand). False: declined, `out` is
// partly written and must be reset before the full reader runs.
bool read_common_marker_json(std::string_view text, MarkerNameIndex& names, MarkerFrame& out,
                             FastFrameTop& top);

// Lists a name not in the config, cut to the list entry's reserved capacity,
// so listing never allocates (up to the list's length, then only counted).
inline void list_unknown_name(std::vector<std::string>& list, int& listed, std::string_view name) {
  if (listed >= static_cast<int>(list.size())) return;
  std::string& entry = list[listed++];
  entry.assign(name.data(), std::min(name.size(), entry.capacity()));
}

// Marker i's 4th value, as both readers take it: clamped to [0, 1] (detectors'
// scores may stray a little past 1); one that is not finite says nothing about
// the marker, so the marker is occluded.
inline void set_confidence(MarkerFrame& out, int i, double confidence) {
  ++out.confidence_count;
  if (!std::isfinite(confidence)) {
    out.visible[i] = 0;
    out.confidence[i] = 0.0f;
    return;
  }
  out.confidence[i] = static_cast<float>(std::clamp(confidence, 0.0, 1.0));
}

}  // namespace fabrik::wire
