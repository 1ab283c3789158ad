// The NatNet codec on any datagram: the first input byte picks the NatNet
// version the client believes in (3.0, 3.1, 4.0, 4.1, 4.2), the rest is the
// datagram. Decoding answers true or false with a reason and never crashes,
// throws or reads out of bounds; what decodes, re-encodes to bytes that decode
// to the same message (encode . decode is idempotent).
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bridges/natnet_protocol.hpp"
#include "fuzz_check.hpp"

namespace {

using namespace fabrik::natnet;
using fabrik::fuzz::require;

constexpr Version kVersions[] = {{3, 0, 0, 0}, {3, 1, 0, 0}, {4, 0, 0, 0}, {4, 1, 0, 0}, {4, 2, 0, 0}};

void frame(std::span<const std::uint8_t> payload, const Version& v) {
  static FrameOfData f;  // reused across inputs, as a client reuses its frame
  std::string error;
  if (!decode_frame_of_data(payload, v, f, error)) {
    require(!error.empty(), "frame decode failed without a reason");
    return;
  }
  const std::vector<std::uint8_t> once = encode_frame_of_data(f, v);
  FrameOfData again;
  require(decode_frame_of_data(once, v, again, error), "a re-encoded frame does not decode");
  require(encode_frame_of_data(again, v) == once, "frame encode . decode is not idempotent");
}

void model(std::span<const std::uint8_t> payload, const Version& v) {
  ModelDefinitions d;
  std::string error;
  if (!decode_model_definitions(payload, v, d, error)) {
    require(!error.empty(), "model definitions decode failed without a reason");
    return;
  }
  const std::vector<std::uint8_t> once = encode_model_definitions(d, v);
  ModelDefinitions again;
  require(decode_model_definitions(once, v, again, error),
          "re-encoded model definitions do not decode");
  require(encode_model_definitions(again, v) == once,
          "model definitions encode . decode is not idempotent");
}

void server_info(std::span<const std::uint8_t> payload) {
  ServerInfo info;
  std::string error;
  if (!decode_server_info(payload, info, error)) {
    require(!error.empty(), "server info decode failed without a reason");
    return;
  }
  ServerInfo again;
  require(decode_server_info(encode_server_info(info), again, error) &&
              again.application_name == info.application_name &&
              again.natnet_version == info.natnet_version,
          "server info does not round-trip");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const Version& v = kVersions[data[0] % std::size(kVersions)];
  const std::span<const std::uint8_t> datagram(data + 1, size - 1);
  Message m;
  std::string error;
  if (!split_message(datagram, m, error)) {
    require(!error.empty(), "split_message failed without a reason");
    // The payload decoders face unframed bytes too (a lying header is caught
    // above, but the decoders must not depend on it).
    frame(datagram, v);
    model(datagram, v);
    return 0;
  }
  switch (m.id) {
    case MessageId::frame_of_data: frame(m.payload, v); break;
    case MessageId::model_def: model(m.payload, v); break;
    case MessageId::server_info: server_info(m.payload); break;
    case MessageId::connect: {
      Version asked;
      if (!decode_connect_request(m.payload, asked, error))
        require(!error.empty(), "connect decode failed without a reason");
      break;
    }
    default: break;
  }
  return 0;
}
