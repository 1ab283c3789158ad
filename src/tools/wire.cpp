#include "wire.hpp"

#include <cmath>
#include <stdexcept>

namespace fabrik::tools {

WireEncoding parse_wire_encoding(const std::string& name) {
  if (name == "json") return WireEncoding::json;
  if (name == "msgpack") return WireEncoding::msgpack;
  throw std::invalid_argument("unknown encoding '" + name + "': use json or msgpack");
}

const char* wire_encoding_name(WireEncoding encoding) {
  return encoding == WireEncoding::json ? "json" : "msgpack";
}

WireEncoding detect_encoding(std::string_view payload) {
  if (payload.empty()) throw std::runtime_error("empty payload");
  const auto b = static_cast<unsigned char>(payload.front());
  if (b == '{' || b == ' ' || b == '\t' || b == '\n' || b == '\r') return WireEncoding::json;
  if ((b >= 0x80 && b <= 0x8f) || b == 0xde || b == 0xdf) return WireEncoding::msgpack;
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02x", b);
  throw std::runtime_error(std::string("payload starts with byte ") + hex +
                           ": neither a JSON object nor a MessagePack map");
}

nlohmann::json decode_payload(std::string_view payload) {
  const WireEncoding encoding = detect_encoding(payload);
  try {
    if (encoding == WireEncoding::json) return nlohmann::json::parse(payload);
    return nlohmann::json::from_msgpack(payload.begin(), payload.end());
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(std::string("bad ") + wire_encoding_name(encoding) +
                             " payload: " + e.what());
  }
}

std::string encode_payload(const nlohmann::json& doc, WireEncoding encoding) {
  if (encoding == WireEncoding::json) return doc.dump();
  std::string out;
  nlohmann::json::to_msgpack(doc, out);
  return out;
}

nlohmann::json marker_frame(const io::MarkerTrial& trial, std::size_t index,
                            std::uint64_t frame_number, double time_s,
                            const std::vector<std::uint8_t>& hidden) {
  nlohmann::json markers = nlohmann::json::object();
  for (std::size_t m = 0; m < trial.markers(); ++m) {
    const Eigen::Vector3d& p = trial.at(index, m);
    if ((m < hidden.size() && hidden[m]) || !p.allFinite()) {
      markers[trial.labels[m]] = nullptr;
    } else {
      const auto mm = [](double v_m) { return std::round(v_m * 1e9) / 1e6; };
      markers[trial.labels[m]] = {mm(p.x()), mm(p.y()), mm(p.z())};
    }
  }
  return {{"frame", frame_number}, {"time", time_s}, {"units", "mm"}, {"markers", markers}};
}

}  // namespace fabrik::tools
