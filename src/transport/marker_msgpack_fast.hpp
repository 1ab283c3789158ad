// The fast path of MarkerDecoder for MessagePack: the common shape of a
// markers payload read in one pass without the general reader:
//   {"frame": N, "time": T, "stamp_us": S, "units": "mm" | "m", "subject": NAME,
//    "markers": {"NAME": [x, y, z] | [x, y, z, confidence] | nil, ...}}
// keys in any order (any of them absent or repeated), any MessagePack
// encoding of each value (fixstr or str8/16/32, fixmap or map16/32, every
// integer and float width). Anything else (other keys, "orientations", a
// signed or float frame number, a non-finite time, a truncated payload,
// bytes after the frame) is declined, and the caller runs the full reader
// (nlohmann's SAX reader + the decoder's SAX handler) on the payload from the
// start: so every error message and validation rule is the full reader's.
// tests/test_marker_fast_path.cpp checks that the two agree on many varied
// payloads; the marker-decoder fuzz target does on any bytes.
#pragma once

#include <cstdint>
#include <span>

#include "marker_codec.hpp"
#include "marker_frame_fill.hpp"
#include "marker_name_index.hpp"

namespace fabrik::wire {

// True: `out` and `top` hold what the full reader would have given for
// `payload` (`out` reset by the caller beforehand). False: declined, `out` is
// partly written and must be reset before the full reader runs.
bool read_common_marker_msgpack(std::span<const std::uint8_t> payload, MarkerNameIndex& names,
                                MarkerFrame& out, FastFrameTop& top);

}  // namespace fabrik::wire
