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
// tests/test_marker_fast_path.cpp checks that the two agree on many varied
// payloads; the marker-decoder fuzz target does on any bytes.
#pragma once

#include <string_view>

#include "marker_codec.hpp"
#include "marker_frame_fill.hpp"
#include "marker_name_index.hpp"

namespace fabrik::wire {

// True: `out` and `top` hold what the full reader would have given for
// `text` (`out` reset by the caller beforehand). False: declined, `out` is
// partly written and must be reset before the full reader runs.
bool read_common_marker_json(std::string_view text, MarkerNameIndex& names, MarkerFrame& out,
                             FastFrameTop& top);

}  // namespace fabrik::wire
