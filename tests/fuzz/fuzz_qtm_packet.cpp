// The QTM RT codec on any byte stream, as fabrikd's QTM input will meet it:
// the first byte picks the byte order and a chunk size, the rest is fed to
// the packet splitter in chunks, and every whole packet goes to the decoder
// of its type. Nothing may crash, throw or read out of bounds, and:
//   - a packet the splitter yields lies within its limits;
//   - a decoded data frame, written again, decodes to the same frame, and
//     writing that gives the same bytes (the encoder is the decoder's inverse);
//   - accepted 3D parameters, written by the simulator's writer, read back equal.
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "fuzz_check.hpp"

namespace {

using namespace fabrik::qtm;
using fabrik::fuzz::require;

constexpr std::size_t kMaxPacketBytes = 1 << 16;
constexpr std::size_t kMaxMarkers = 512;

bool same_float(float a, float b) { return (std::isnan(a) && std::isnan(b)) || a == b; }

bool same_frame(const DataFrame& a, const DataFrame& b) {
  if (a.timestamp_us != b.timestamp_us || a.frame_number != b.frame_number || a.has_3d != b.has_3d ||
      a.has_3d_no_labels != b.has_3d_no_labels ||
      a.drop_rate_2d_permille != b.drop_rate_2d_permille ||
      a.out_of_sync_rate_2d_permille != b.out_of_sync_rate_2d_permille || a.labelled_p_qtm_mm.size() != b.labelled_p_qtm_mm.size() ||
      a.unlabelled.size() != b.unlabelled.size())
    return false;
  for (std::size_t i = 0; i < a.labelled_p_qtm_mm.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (!same_float(a.labelled_p_qtm_mm[i][k], b.labelled_p_qtm_mm[i][k])) return false;
  for (std::size_t i = 0; i < a.unlabelled.size(); ++i) {
    if (a.unlabelled[i].id != b.unlabelled[i].id) return false;
    for (int k = 0; k < 3; ++k)
      if (!same_float(a.unlabelled[i].p_qtm_mm[k], b.unlabelled[i].p_qtm_mm[k])) return false;
  }
  return true;
}

void check_data(const PacketView& packet, ByteOrder order) {
  static DataFrame frame, again;
  static std::vector<std::uint8_t> first, second;
  if (read_data(packet, order, kMaxMarkers, frame) != Status::ok) return;
  require(frame.labelled_p_qtm_mm.size() <= kMaxMarkers && frame.unlabelled.size() <= kMaxMarkers,
          "a data frame above the marker limit was accepted");
  write_data_packet(frame, order, first);
  PacketView view;
  require(read_packet(first, order, 1u << 30, view) == Status::ok, "our data packet is not one packet");
  require(read_data(view, order, kMaxMarkers, again) == Status::ok, "our data packet does not decode");
  require(same_frame(frame, again), "a data frame changed through write and read");
  write_data_packet(again, order, second);
  require(first == second, "writing a decoded data frame is not stable");
}

void check_xml(const PacketView& packet) {
  std::string_view text;
  if (read_string(packet, PacketType::xml, text) != Status::ok) return;
  Parameters3d params, back;
  std::string error;
  if (!read_parameters_3d(text, params, error)) {
    require(!error.empty(), "refused 3D parameters without a reason");
    return;
  }
  require(read_parameters_3d(write_parameters_3d(params, "1.19"), back, error),
          "the writer's 3D parameters do not read back");
  require(back.labels == params.labels, "labels changed through write and read");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const ByteOrder order = (data[0] & 1) ? ByteOrder::big : ByteOrder::little;
  const std::size_t chunk = 1 + (data[0] >> 1);  // 1..128 bytes per TCP read
  const std::span<const std::uint8_t> stream(data + 1, size - 1);

  PacketSplitter splitter(order, kMaxPacketBytes);
  for (std::size_t at = 0; at < stream.size(); at += chunk) {
    splitter.feed(stream.subspan(at, std::min(chunk, stream.size() - at)));
    PacketView packet;
    Status s;
    while ((s = splitter.next(packet)) == Status::ok) {
      require(packet.data.size() + kHeaderBytes <= kMaxPacketBytes, "a packet above the maximum");
      Event event;
      std::string_view text;
      switch (packet.type().value_or(PacketType::discover)) {
        case PacketType::data: check_data(packet, order); break;
        case PacketType::xml: check_xml(packet); break;
        case PacketType::event: (void)read_event(packet, event); break;
        case PacketType::error:
        case PacketType::command: (void)read_string(packet, *packet.type(), text); break;
        default: break;
      }
    }
    if (s != Status::need_more) return 0;  // a framing error: the stream ends here, as in the daemon
  }
  return 0;
}
