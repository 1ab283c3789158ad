#include "payload_document.hpp"

#include <cstdio>
#include <stdexcept>
#include <string>

namespace fabrik::wire {

PayloadEncoding document_encoding(std::string_view payload) {
  if (payload.empty()) throw std::runtime_error("empty payload");
  const auto b = static_cast<unsigned char>(payload.front());
  if (b == '{' || b == ' ' || b == '\t' || b == '\n' || b == '\r') return PayloadEncoding::json;
  if ((b >= 0x80 && b <= 0x8f) || b == 0xde || b == 0xdf) return PayloadEncoding::msgpack;
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02x", b);
  throw std::runtime_error(std::string("payload starts with byte ") + hex +
                           ": neither a JSON object nor a MessagePack map");
}

nlohmann::json decode_document(std::string_view payload) {
  const PayloadEncoding encoding = document_encoding(payload);
  try {
    if (encoding == PayloadEncoding::json) return nlohmann::json::parse(payload);
    return nlohmann::json::from_msgpack(payload.begin(), payload.end());
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(std::string("bad ") +
                             (encoding == PayloadEncoding::json ? "json" : "msgpack") +
                             " payload: " + e.what());
  }
}

}  // namespace fabrik::wire
