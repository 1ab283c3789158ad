#include "bridges/qtm/packet.hpp"

#include <algorithm>
#include <cstring>

namespace fabrik::qtm {

std::optional<PacketType> packet_type_of(std::uint32_t raw) {
  if (raw <= static_cast<std::uint32_t>(PacketType::qtm_file)) return static_cast<PacketType>(raw);
  return std::nullopt;
}

const char* to_string(PacketType type) {
  switch (type) {
    case PacketType::error: return "error";
    case PacketType::command: return "command";
    case PacketType::xml: return "XML";
    case PacketType::data: return "data";
    case PacketType::no_more_data: return "no more data";
    case PacketType::c3d_file: return "C3D file";
    case PacketType::event: return "event";
    case PacketType::discover: return "discover";
    case PacketType::qtm_file: return "QTM file";
  }
  return "?";
}

const char* to_string(Status status) {
  switch (status) {
    case Status::ok: return "ok";
    case Status::need_more: return "incomplete packet, more bytes needed";
    case Status::too_small: return "packet size below the 8-byte header";
    case Status::too_large: return "packet size above the configured maximum";
    case Status::truncated: return "truncated packet: a field runs past its end";
    case Status::wrong_type: return "packet of another type than expected";
    case Status::unknown_type: return "packet or component type not in the protocol";
    case Status::malformed: return "malformed packet: sizes or counts disagree";
    case Status::too_many: return "more markers or labels than the configured maximum";
  }
  return "?";
}

namespace {

// Size field check shared by read_packet and the splitter.
Status check_size(std::uint32_t size, std::size_t max_packet_bytes) {
  if (size < kHeaderBytes) return Status::too_small;
  if (size > max_packet_bytes) return Status::too_large;
  return Status::ok;
}

}  // namespace

Status read_packet(std::span<const std::uint8_t> bytes, ByteOrder order, std::size_t max_packet_bytes,
                   PacketView& out) {
  ByteReader r(bytes, order);
  const std::uint32_t size = r.u32();
  const std::uint32_t type = r.u32();
  if (!r.ok()) return Status::truncated;
  if (const Status s = check_size(size, max_packet_bytes); s != Status::ok) return s;
  if (bytes.size() < size) return Status::truncated;
  if (bytes.size() > size) return Status::malformed;
  out.raw_type = type;
  out.data = bytes.subspan(kHeaderBytes, size - kHeaderBytes);
  return Status::ok;
}

PacketSplitter::PacketSplitter(ByteOrder order, std::size_t max_packet_bytes)
    : order_(order), max_packet_bytes_(std::max(max_packet_bytes, kHeaderBytes)) {}

void PacketSplitter::compact() {
  if (consumed_ == 0) return;
  const std::size_t left = buffer_.size() - consumed_;
  if (left > 0) std::memmove(buffer_.data(), buffer_.data() + consumed_, left);
  buffer_.resize(left);
  consumed_ = 0;
}

void PacketSplitter::feed(std::span<const std::uint8_t> chunk) {
  if (poisoned_ != Status::ok) return;  // nothing after a framing error can be trusted
  compact();
  buffer_.insert(buffer_.end(), chunk.begin(), chunk.end());
}

Status PacketSplitter::next(PacketView& out) {
  if (poisoned_ != Status::ok) return poisoned_;
  const std::span<const std::uint8_t> pending(buffer_.data() + consumed_, buffer_.size() - consumed_);
  ByteReader r(pending, order_);
  const std::uint32_t size = r.u32();
  const std::uint32_t type = r.u32();
  if (!r.ok()) return Status::need_more;
  if (const Status s = check_size(size, max_packet_bytes_); s != Status::ok) {
    poisoned_ = s;
    return s;
  }
  if (pending.size() < size) return Status::need_more;
  out.raw_type = type;
  out.data = pending.subspan(kHeaderBytes, size - kHeaderBytes);
  consumed_ += size;
  return Status::ok;
}

void PacketSplitter::reset() {
  buffer_.clear();
  consumed_ = 0;
  poisoned_ = Status::ok;
}

void write_packet(PacketType type, std::span<const std::uint8_t> data, ByteOrder order,
                  std::vector<std::uint8_t>& out) {
  out.clear();
  ByteWriter w(out, order);
  w.u32(static_cast<std::uint32_t>(kHeaderBytes + data.size()));
  w.u32(static_cast<std::uint32_t>(type));
  w.bytes(data);
}

Status read_string(const PacketView& packet, PacketType expected, std::string_view& text) {
  if (packet.raw_type != static_cast<std::uint32_t>(expected)) return Status::wrong_type;
  const auto* begin = reinterpret_cast<const char*>(packet.data.data());
  const std::string_view all(begin, packet.data.size());
  const std::size_t nul = all.find('\0');
  if (nul != std::string_view::npos &&
      all.find_first_not_of('\0', nul) != std::string_view::npos)
    return Status::malformed;
  text = all.substr(0, nul);
  return Status::ok;
}

void write_string_packet(PacketType type, std::string_view text, ByteOrder order,
                         std::vector<std::uint8_t>& out) {
  out.clear();
  ByteWriter w(out, order);
  w.u32(static_cast<std::uint32_t>(kHeaderBytes + text.size() + 1));
  w.u32(static_cast<std::uint32_t>(type));
  w.bytes({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
  w.u8(0);
}

const char* to_string(Event event) {
  switch (event) {
    case Event::connected: return "Connected";
    case Event::connection_closed: return "Connection Closed";
    case Event::capture_started: return "Capture Started";
    case Event::capture_stopped: return "Capture Stopped";
    case Event::fetching_finished: return "Fetching Finished";
    case Event::calibration_started: return "Calibration Started";
    case Event::calibration_stopped: return "Calibration Stopped";
    case Event::rt_from_file_started: return "RT From File Started";
    case Event::rt_from_file_stopped: return "RT From File Stopped";
    case Event::waiting_for_trigger: return "Waiting For Trigger";
    case Event::camera_settings_changed: return "Camera Settings Changed";
    case Event::qtm_shutting_down: return "QTM Shutting Down";
    case Event::capture_saved: return "Capture Saved";
    case Event::reserved_14: return "Reserved (14)";
    case Event::reserved_15: return "Reserved (15)";
    case Event::trigger: return "Trigger";
  }
  return "?";
}

Status read_event(const PacketView& packet, Event& event) {
  if (packet.raw_type != static_cast<std::uint32_t>(PacketType::event)) return Status::wrong_type;
  if (packet.data.empty()) return Status::truncated;
  if (packet.data.size() > 1) return Status::malformed;
  const std::uint8_t id = packet.data[0];
  if (id < 1 || id > static_cast<std::uint8_t>(Event::trigger)) return Status::malformed;
  event = static_cast<Event>(id);
  return Status::ok;
}

void write_event_packet(Event event, ByteOrder order, std::vector<std::uint8_t>& out) {
  const std::uint8_t id = static_cast<std::uint8_t>(event);
  write_packet(PacketType::event, {&id, 1}, order, out);
}

}  // namespace fabrik::qtm
