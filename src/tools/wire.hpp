// Payloads of the wire contract (../shared/wire-contract.md, proto/) as the tools see them:
// any payload decoded by its first byte into a JSON document (watch shows every field). Marker
// frames are written with transport's encode_marker_frame, as the daemon's own tests do.
#pragma once

#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include <zmq.hpp>

#include "config/daemon_config.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::tools {

enum class WireEncoding { json, msgpack };

WireEncoding parse_wire_encoding(
    const std::string& name);  // "json"/"msgpack", else invalid_argument
const char* wire_encoding_name(WireEncoding encoding);

// The encoding of a payload from its first byte: '{' or JSON whitespace is JSON, a MessagePack
// map header (fixmap 0x80-0x8f, map16 0xde, map32 0xdf) is MessagePack. Throws
// std::runtime_error for anything else (including an empty payload).
WireEncoding detect_encoding(std::string_view payload);
// Decodes a JSON or MessagePack payload (detected as above). Throws std::runtime_error with the
// reason when it is neither.
nlohmann::json decode_payload(std::string_view payload);
std::string encode_payload(const nlohmann::json& doc, WireEncoding encoding);

// A tool's endpoint option (--to, --from) with its --bind flag: "bind:" and "connect:" prefixes
// as fabrikd's --input/--output take them, the daemon's own endpoint check
// (config/endpoint_check.hpp: no port ZeroMQ would wrap modulo 65536); std::invalid_argument
// naming `option` otherwise.
Endpoint tool_endpoint(const std::string& spec, bool bind, const char* option);
// Binds or connects `socket` to the tool_endpoint of `spec`.
void open_endpoint(zmq::socket_t& socket, const std::string& spec, bool bind, const char* option);

// The tools' waits and non-blocking reads, where Ctrl-C must stop a loop with its summary:
// a signal makes ZeroMQ's calls fail with EINTR (zmq_poll whatever SA_RESTART says), and
// cppzmq throws that. Here it is "nothing yet": the caller's loop then reads its stop flag.
// Other errors still throw.
// Whether a message waits on `socket` within `timeout`.
bool wait_readable(zmq::socket_t& socket, std::chrono::milliseconds timeout);
// A message if one waits (without blocking): false when none does, or on a signal.
bool receive_waiting(zmq::socket_t& socket, zmq::message_t& message);
// The next part of a message whose first part was read (it is there: a signal is retried).
void receive_part(zmq::socket_t& socket, zmq::message_t& part);
// One part sent, a signal retried: once a message's first part is out, its others must follow.
void send_part(zmq::socket_t& socket, zmq::const_buffer part, zmq::send_flags flags);

}  // namespace fabrik::tools
