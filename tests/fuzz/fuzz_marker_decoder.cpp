// The daemon's marker-frame decoder on any payload, JSON or MessagePack:
// it answers true or false (with a reason), never throws or crashes, and
// reuses one frame across calls as the daemon does. An accepted frame has
// finite positions for every visible marker, and an accepted JSON payload is
// valid JSON to nlohmann too (our reader is the stricter one, docs/fuzzing.md). The
// fast paths (JSON and MessagePack) and the full reader give the same verdict,
// message and frame.
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "fuzz_check.hpp"
#include "transport/marker_codec.hpp"

namespace {

struct Decoding {
  std::vector<std::string> names;
  fabrik::wire::MarkerDecoder decoder;
  fabrik::wire::MarkerFrame frame;
  std::string error;

  explicit Decoding(bool fast_path) : names(model_marker_names()), decoder(names, 1e-3, 1 << 20) {
    decoder.set_fast_path(fast_path);
    frame = decoder.make_frame();
  }
  static std::vector<std::string> model_marker_names() {
    std::vector<std::string> names;
    for (const fabrik::MarkerTarget& m : fabrik::default_daemon_config().tracker.markers)
      names.push_back(m.marker);
    return names;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using fabrik::fuzz::require;
  static Decoding d(true), full(false);
  const std::span<const std::uint8_t> payload(data, size);
  d.decoder.set_fast_path(true);  // no pause after a declined payload: try every one
  const bool ok = d.decoder.decode(payload, d.frame, d.error);
  require(full.decoder.decode(payload, full.frame, full.error) == ok && full.error == d.error,
          "a fast path and the full reader disagree on the verdict or the message");
  if (ok) {
    const fabrik::wire::MarkerFrame &a = d.frame, &b = full.frame;
    require(a.frame == b.frame && a.has_time == b.has_time && a.time_s == b.time_s &&
                a.visible == b.visible && a.known_count == b.known_count &&
                a.unknown_count == b.unknown_count && a.zero_count == b.zero_count &&
                a.rejected_count == b.rejected_count && a.confidence == b.confidence &&
                a.confidence_count == b.confidence_count && a.has_stamp == b.has_stamp &&
                a.has_subject == b.has_subject && a.subject == b.subject,
            "a fast path and the full reader give different frames");
    for (std::size_t i = 0; i < a.visible.size(); ++i)
      if (a.visible[i])
        require(a.p_world_m[i] == b.p_world_m[i],
                "a fast path and the full reader give different positions");
  }
  if (!ok) {
    require(!d.error.empty(), "decode returned false without a reason");
    return 0;
  }
  require(d.frame.visible.size() == d.names.size() && d.frame.p_world_m.size() == d.names.size(),
          "the frame's arrays lost their size");
  for (std::size_t i = 0; i < d.names.size(); ++i)
    if (d.frame.visible[i]) require(d.frame.p_world_m[i].allFinite(), "visible marker not finite");
  require(d.frame.unknown_count >= 0, "negative unknown_count");
  if (fabrik::wire::detect_encoding(payload) == fabrik::wire::PayloadEncoding::json)
    require(nlohmann::json::accept(data, data + size),
            "the decoder accepted a JSON payload that nlohmann rejects");
  return 0;
}
