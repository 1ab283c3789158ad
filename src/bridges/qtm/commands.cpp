#include "bridges/qtm/commands.hpp"

#include <cctype>
#include <charconv>

#include "bridges/qtm/packet.hpp"
#include "common/ascii_case.hpp"

namespace fabrik::qtm {

namespace {

bool istarts_with(std::string_view s, std::string_view prefix) {
  return s.size() >= prefix.size() && iequals(s.substr(0, prefix.size()), prefix);
}

std::optional<int> parse_int(std::string_view s) {
  int v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v < 0) return std::nullopt;
  return v;
}

// "1.19" -> {1, 19}; nothing else.
std::optional<ProtocolVersion> parse_version_number(std::string_view s) {
  const std::size_t dot = s.find('.');
  if (dot == std::string_view::npos) return std::nullopt;
  const auto major = parse_int(s.substr(0, dot));
  const auto minor = parse_int(s.substr(dot + 1));
  if (!major || !minor || s.substr(0, dot).empty() || s.substr(dot + 1).empty()) return std::nullopt;
  return ProtocolVersion{*major, *minor};
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && s[i] == ' ') ++i;
    std::size_t j = i;
    while (j < s.size() && s[j] != ' ') ++j;
    if (j > i) out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

}  // namespace

std::string version_command(ProtocolVersion v) {
  return "Version " + std::to_string(v.major) + "." + std::to_string(v.minor);
}
std::string byte_order_command() { return "ByteOrder"; }
std::string get_parameters_3d_command() { return "GetParameters 3D"; }
std::string stream_frames_command(StreamRate rate, Components components) {
  std::string s = "StreamFrames ";
  s += rate.frequency_divisor <= 1 ? std::string("AllFrames")
                                   : "FrequencyDivisor:" + std::to_string(rate.frequency_divisor);
  s += components == Components::labelled_3d ? " 3D" : " 3D 3DNoLabels";
  return s;
}
std::string stream_stop_command() { return "StreamFrames Stop"; }

void write_command_packet(std::string_view command, ByteOrder order, std::vector<std::uint8_t>& out) {
  write_string_packet(PacketType::command, command, order, out);
}

bool is_welcome(std::string_view reply) {
  return reply == "QTM RT Interface connected." || reply == "QTM RT Interface connected";
}

std::optional<ProtocolVersion> parse_version_reply(std::string_view reply) {
  for (std::string_view prefix : {"Version set to ", "Version is "})
    if (istarts_with(reply, prefix)) return parse_version_number(reply.substr(prefix.size()));
  return std::nullopt;
}

std::optional<ByteOrder> parse_byte_order_reply(std::string_view reply) {
  if (iequals(reply, "Byte order is little endian")) return ByteOrder::little;
  if (iequals(reply, "Byte order is big endian")) return ByteOrder::big;
  return std::nullopt;
}

ParsedCommand parse_command(std::string_view command) {
  ParsedCommand out;
  const std::vector<std::string_view> w = words(command);
  if (w.empty()) return out;
  for (std::size_t i = 1; i < w.size(); ++i) out.arguments.emplace_back(w[i]);
  const std::string_view name = w[0];
  if (iequals(name, "Version")) {
    out.kind = ParsedCommand::Kind::version;
    if (w.size() == 2) out.version = parse_version_number(w[1]);
  } else if (iequals(name, "ByteOrder")) {
    out.kind = ParsedCommand::Kind::byte_order;
  } else if (iequals(name, "GetParameters")) {
    out.kind = ParsedCommand::Kind::get_parameters;
    for (std::size_t i = 1; i < w.size(); ++i)
      if (iequals(w[i], "3D") || iequals(w[i], "All")) out.wants_3d = true;
  } else if (iequals(name, "StreamFrames")) {
    if (w.size() == 2 && iequals(w[1], "Stop")) {
      out.kind = ParsedCommand::Kind::stream_stop;
      return out;
    }
    out.kind = ParsedCommand::Kind::stream_frames;
    out.rate_valid = false;
    for (std::size_t i = 1; i < w.size(); ++i) {
      const std::string_view a = w[i];
      if (iequals(a, "AllFrames")) {
        out.rate = {1};
        out.rate_valid = true;
      } else if (istarts_with(a, "FrequencyDivisor:")) {
        const auto n = parse_int(a.substr(17));
        out.rate_valid = n && *n >= 1;
        if (out.rate_valid) out.rate = {static_cast<std::uint32_t>(*n)};
      } else if (iequals(a, "3D")) {
        out.wants_3d = true;
      } else if (iequals(a, "3DNoLabels")) {
        out.wants_3d_no_labels = true;
      } else if (iequals(a, "All")) {
        out.wants_3d = out.wants_3d_no_labels = true;
      }
    }
  }
  return out;
}

}  // namespace fabrik::qtm
