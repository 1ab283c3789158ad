#include "wire.hpp"

#include <cmath>
#include <stdexcept>

#include "config/endpoint_check.hpp"

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

void open_endpoint(zmq::socket_t& socket, const std::string& endpoint, bool bind,
                   const char* option) {
  require_usable_endpoint(endpoint, bind ? SocketMode::bind : SocketMode::connect, option);
  if (bind)
    socket.bind(endpoint);
  else
    socket.connect(endpoint);
}

}  // namespace fabrik::tools
