// Any payload of the wire contract (pose, stats, model, markers) decoded into a JSON document,
// JSON or MessagePack told apart by the first byte: what the tools and the view show.
#pragma once

#include <nlohmann/json.hpp>
#include <string_view>

#include "marker_codec.hpp"

namespace fabrik::wire {

// The encoding of a payload from its first byte: '{' or JSON whitespace is JSON, a MessagePack
// map header (fixmap 0x80-0x8f, map16 0xde, map32 0xdf) is MessagePack. Throws
// std::runtime_error for anything else (including an empty payload).
PayloadEncoding document_encoding(std::string_view payload);
// Decodes a JSON or MessagePack payload (detected as above). Throws std::runtime_error with the
// reason when it is neither.
nlohmann::json decode_document(std::string_view payload);

}  // namespace fabrik::wire
