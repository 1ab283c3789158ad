// The command strings a client sends and the replies it reads (doc,
// "Commands"): ASCII, space separated, case insensitive, in command packets.
// Only what fabrikd needs: Version, ByteOrder, GetParameters 3D, StreamFrames.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bridges/qtm/byte_io.hpp"

namespace fabrik::qtm {

struct ProtocolVersion {
  int major = 1;
  int minor = 0;
  friend bool operator==(const ProtocolVersion&, const ProtocolVersion&) = default;
};

// The 3D components fabrikd streams (doc, "Data component types").
enum class Components { labelled_3d, labelled_and_unlabelled_3d };

// Which frames QTM sends: every processed real-time frame, or every n-th.
struct StreamRate {
  std::uint32_t frequency_divisor = 1;  // 1 = AllFrames
};

std::string version_command(ProtocolVersion v);        // "Version 1.19"
std::string byte_order_command();                      // "ByteOrder"
std::string get_parameters_3d_command();               // "GetParameters 3D"
std::string stream_frames_command(StreamRate rate, Components components);
                                                       // "StreamFrames AllFrames 3D"
std::string stream_stop_command();                     // "StreamFrames Stop"

// A command packet (type 1) holding `command` and a NUL, into `out`.
void write_command_packet(std::string_view command, ByteOrder order, std::vector<std::uint8_t>& out);

// Server replies. The welcome string is "QTM RT Interface connected." (the doc's
// text; SDKs also accept it without the full stop).
bool is_welcome(std::string_view reply);
// "Version set to 1.19" or "Version is 1.19": the version; else nullopt
// (e.g. "Version NOT supported", which QTM sends as an error packet).
std::optional<ProtocolVersion> parse_version_reply(std::string_view reply);
// "Byte order is little endian" / "Byte order is big endian".
std::optional<ByteOrder> parse_byte_order_reply(std::string_view reply);

// What a server (the simulator) reads from a client's command string.
struct ParsedCommand {
  enum class Kind { version, byte_order, get_parameters, stream_frames, stream_stop, other };
  Kind kind = Kind::other;
  std::optional<ProtocolVersion> version;  // Version with an argument
  std::vector<std::string> arguments;      // the words after the command name, as sent
  StreamRate rate;                         // StreamFrames
  bool wants_3d = false;                   // GetParameters/StreamFrames asked for 3D (or All)
  bool wants_3d_no_labels = false;         // StreamFrames asked for 3DNoLabels (or All)
  bool rate_valid = true;                  // false: a rate other than AllFrames/FrequencyDivisor:n>=1
};
ParsedCommand parse_command(std::string_view command);

}  // namespace fabrik::qtm
