// QTM RT protocol packets (docs.qualisys.com/qtm-rt-protocol, "QTM RT Packets"):
// an 8-byte header, Size (u32, the whole packet including the header) then
// Type (u32), then Size - 8 bytes of data. Decoders never throw: they return
// a Status, and a bad packet is a value, not an exception.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "bridges/qtm/byte_io.hpp"

namespace fabrik::qtm {

inline constexpr std::size_t kHeaderBytes = 8;
// Default ports (doc, "IP port numbers"): base 22222 is protocol 1.0 only.
inline constexpr std::uint16_t kDefaultBasePort = 22222;
inline constexpr std::uint16_t port_for(ByteOrder order, std::uint16_t base = kDefaultBasePort) {
  return static_cast<std::uint16_t>(base + (order == ByteOrder::little ? 1 : 2));
}

enum class PacketType : std::uint32_t {
  error = 0,
  command = 1,
  xml = 2,
  data = 3,
  no_more_data = 4,
  c3d_file = 5,
  event = 6,
  discover = 7,
  qtm_file = 8,
};
std::optional<PacketType> packet_type_of(std::uint32_t raw);
const char* to_string(PacketType type);

enum class Status {
  ok,
  need_more,       // the splitter holds a partial packet: feed more bytes
  too_small,       // Size below the 8-byte header
  too_large,       // Size above the configured maximum
  truncated,       // a field or component runs past the end of its packet
  wrong_type,      // the packet is not of the type this decoder reads
  unknown_type,    // a Type the documentation does not list
  malformed,       // sizes or counts that contradict each other, trailing bytes
  too_many,        // more markers/labels than the configured maximum
};
const char* to_string(Status status);

// One whole packet; `data` is what follows the header.
struct PacketView {
  std::uint32_t raw_type = 0;
  std::span<const std::uint8_t> data;
  std::optional<PacketType> type() const { return packet_type_of(raw_type); }
};

// Reads one packet at the start of `bytes` (exactly one packet: trailing
// bytes are malformed). For fixtures and datagrams; TCP goes through the splitter.
Status read_packet(std::span<const std::uint8_t> bytes, ByteOrder order, std::size_t max_packet_bytes,
                   PacketView& out);

// Cuts a TCP byte stream into whole packets. Feed it chunks as they arrive,
// then call next() until it says need_more. A framing error (too_small,
// too_large) poisons the stream: every later next() repeats it until reset(),
// since the position of the next header is lost. Its buffer grows to the
// largest packet seen plus one chunk, then stays: no allocation afterwards.
class PacketSplitter {
 public:
  PacketSplitter(ByteOrder order, std::size_t max_packet_bytes);

  void feed(std::span<const std::uint8_t> chunk);
  // On ok, `out` views the splitter's buffer until the next feed() or next().
  Status next(PacketView& out);
  void reset();
  std::size_t buffered_bytes() const { return buffer_.size() - consumed_; }

 private:
  void compact();

  ByteOrder order_;
  std::size_t max_packet_bytes_;
  std::vector<std::uint8_t> buffer_;
  std::size_t consumed_ = 0;
  Status poisoned_ = Status::ok;
};

// Writes a whole packet (header + data) into `out`, replacing its content.
void write_packet(PacketType type, std::span<const std::uint8_t> data, ByteOrder order,
                  std::vector<std::uint8_t>& out);

// Error, command and XML packets carry one NUL-terminated ASCII string (the
// NUL is optional from clients). `text` views the packet's bytes up to the
// first NUL; anything but NULs after it is malformed.
Status read_string(const PacketView& packet, PacketType expected, std::string_view& text);
// Writes a string packet with its terminating NUL, as the server does.
void write_string_packet(PacketType type, std::string_view text, ByteOrder order,
                         std::vector<std::uint8_t>& out);

// Event packet (doc, "Event packet" and "Events"): Size 9, Type 6, one byte.
enum class Event : std::uint8_t {
  connected = 1,
  connection_closed = 2,
  capture_started = 3,
  capture_stopped = 4,
  fetching_finished = 5,  // deprecated since protocol 1.10, "Not used"
  calibration_started = 6,
  calibration_stopped = 7,
  rt_from_file_started = 8,
  rt_from_file_stopped = 9,
  waiting_for_trigger = 10,
  camera_settings_changed = 11,
  qtm_shutting_down = 12,
  capture_saved = 13,
  reserved_14 = 14,
  reserved_15 = 15,
  trigger = 16,
};
const char* to_string(Event event);
// ok only for a 1-byte event in 1..16 (the documented ids); others are malformed.
Status read_event(const PacketView& packet, Event& event);
void write_event_packet(Event event, ByteOrder order, std::vector<std::uint8_t>& out);

}  // namespace fabrik::qtm
