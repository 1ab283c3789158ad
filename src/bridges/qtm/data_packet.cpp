#include "bridges/qtm/data_packet.hpp"

#include <bit>
#include <cmath>

namespace fabrik::qtm {

namespace {

constexpr std::size_t kComponentHeaderBytes = 8;  // size, type
constexpr std::size_t k3dHeaderBytes = 8;         // marker count, drop rate, out of sync rate
constexpr std::size_t kLabelledBytes = 12;        // x y z
constexpr std::size_t kUnlabelledBytes = 16;      // x y z id

// The marker count and rates shared by both 3D components; checks that the
// component holds exactly `count` markers of `marker_bytes` each.
Status read_3d_header(ByteReader& r, std::size_t body_bytes, std::size_t marker_bytes,
                      std::size_t max_markers, std::uint32_t& count, std::uint16_t& drop,
                      std::uint16_t& out_of_sync) {
  count = r.u32();
  drop = r.u16();
  out_of_sync = r.u16();
  if (!r.ok()) return Status::truncated;
  if (count > max_markers) return Status::too_many;
  if (body_bytes != k3dHeaderBytes + static_cast<std::size_t>(count) * marker_bytes)
    return Status::malformed;
  return Status::ok;
}

Eigen::Vector3f read_xyz(ByteReader& r) {
  const float x = r.f32();
  const float y = r.f32();
  const float z = r.f32();
  return {x, y, z};
}

void write_coordinate(ByteWriter& w, float v) {
  w.u32(std::isnan(v) ? 0xFFFFFFFFu : std::bit_cast<std::uint32_t>(v));
}

// Component header and the 3D header; both 3D components share the frame's rates.
void write_3d_header(ByteWriter& w, std::uint32_t type, std::size_t count, std::size_t marker_bytes,
                     const DataFrame& frame) {
  w.u32(static_cast<std::uint32_t>(kComponentHeaderBytes + k3dHeaderBytes + count * marker_bytes));
  w.u32(type);
  w.u32(static_cast<std::uint32_t>(count));
  w.u16(frame.drop_rate_2d_permille);
  w.u16(frame.out_of_sync_rate_2d_permille);
}

}  // namespace

Status read_data(const PacketView& packet, ByteOrder order, std::size_t max_markers, DataFrame& out) {
  if (packet.raw_type != static_cast<std::uint32_t>(PacketType::data)) return Status::wrong_type;
  ByteReader r(packet.data, order);
  out.timestamp_us = r.u64();
  out.frame_number = r.u32();
  out.component_count = r.u32();
  if (!r.ok()) return Status::truncated;
  out.components_skipped = 0;
  out.has_3d = out.has_3d_no_labels = false;
  out.drop_rate_2d_permille = out.out_of_sync_rate_2d_permille = 0;
  out.labelled_p_qtm_mm.clear();
  out.unlabelled.clear();

  for (std::uint32_t c = 0; c < out.component_count; ++c) {
    const std::uint32_t size = r.u32();
    const std::uint32_t type = r.u32();
    if (!r.ok()) return Status::truncated;
    if (size < kComponentHeaderBytes) return Status::malformed;
    const std::size_t body_bytes = size - kComponentHeaderBytes;
    if (r.remaining() < body_bytes) return Status::truncated;
    ByteReader body(packet.data.subspan(r.position(), body_bytes), order);
    r.skip(body_bytes);

    if (type == kComponent3d) {
      if (out.has_3d) return Status::malformed;  // one 3D component per frame
      std::uint32_t count = 0;
      if (const Status s = read_3d_header(body, body_bytes, kLabelledBytes, max_markers, count,
                                          out.drop_rate_2d_permille, out.out_of_sync_rate_2d_permille);
          s != Status::ok)
        return s;
      out.labelled_p_qtm_mm.resize(count);
      for (auto& p : out.labelled_p_qtm_mm) p = read_xyz(body);
      out.has_3d = true;
    } else if (type == kComponent3dNoLabels) {
      if (out.has_3d_no_labels) return Status::malformed;
      std::uint32_t count = 0;
      std::uint16_t drop = 0, out_of_sync = 0;
      if (const Status s =
              read_3d_header(body, body_bytes, kUnlabelledBytes, max_markers, count, drop, out_of_sync);
          s != Status::ok)
        return s;
      if (!out.has_3d) {  // the 3D component's rates win; both describe the same cameras
        out.drop_rate_2d_permille = drop;
        out.out_of_sync_rate_2d_permille = out_of_sync;
      }
      out.unlabelled.resize(count);
      for (auto& m : out.unlabelled) {
        m.p_qtm_mm = read_xyz(body);
        m.id = body.u32();
      }
      out.has_3d_no_labels = true;
    } else {
      ++out.components_skipped;  // other components are not ours: skipped by their size
    }
    if (!body.ok()) return Status::truncated;  // unreachable when the size checks hold
  }
  if (r.remaining() != 0) return Status::malformed;
  return Status::ok;
}

void write_data_packet(const DataFrame& frame, ByteOrder order, std::vector<std::uint8_t>& out) {
  out.clear();
  ByteWriter w(out, order);
  w.u32(0);  // size, patched below
  w.u32(static_cast<std::uint32_t>(PacketType::data));
  w.u64(frame.timestamp_us);
  w.u32(frame.frame_number);
  w.u32(static_cast<std::uint32_t>(frame.has_3d) + static_cast<std::uint32_t>(frame.has_3d_no_labels));
  if (frame.has_3d) {
    write_3d_header(w, kComponent3d, frame.labelled_p_qtm_mm.size(), kLabelledBytes, frame);
    for (const auto& p : frame.labelled_p_qtm_mm)
      for (int k = 0; k < 3; ++k) write_coordinate(w, p[k]);
  }
  if (frame.has_3d_no_labels) {
    write_3d_header(w, kComponent3dNoLabels, frame.unlabelled.size(), kUnlabelledBytes, frame);
    for (const auto& m : frame.unlabelled) {
      for (int k = 0; k < 3; ++k) write_coordinate(w, m.p_qtm_mm[k]);
      w.u32(m.id);
    }
  }
  w.patch_u32(0, static_cast<std::uint32_t>(out.size()));
}

}  // namespace fabrik::qtm
