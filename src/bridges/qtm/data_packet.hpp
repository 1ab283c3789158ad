// The data packet (doc, "Data packet", "3D component", "3D no labels
// component"): Timestamp (u64, microseconds from start), Frame Number (u32),
// Component Count (u32), then components, each with Size (including its
// 8-byte header) and Type. fabrikd reads 3D (type 1) and 3D No Labels (type 2)
// and skips every other component by its size.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "bridges/qtm/byte_io.hpp"
#include "bridges/qtm/packet.hpp"

namespace fabrik::qtm {

inline constexpr std::uint32_t kComponent3d = 1;
inline constexpr std::uint32_t kComponent3dNoLabels = 2;

struct UnlabelledMarker {
  Eigen::Vector3f p_qtm_mm;
  std::uint32_t id = 0;  // QTM's id, the same marker across frames
};

// One decoded frame. Positions are in QTM's global frame, millimetres, as
// sent; a marker QTM did not see is NaN (doc: all 32 bits set). Reuse one
// DataFrame across packets: its vectors keep their capacity.
struct DataFrame {
  std::uint64_t timestamp_us = 0;
  std::uint32_t frame_number = 0;
  std::uint32_t component_count = 0;
  std::uint32_t components_skipped = 0;  // types other than 1 and 2

  // The 2D rates of the 3D component, else of the 3D no labels component, else 0.
  std::uint16_t drop_rate_2d_permille = 0;
  std::uint16_t out_of_sync_rate_2d_permille = 0;

  bool has_3d = false;
  std::vector<Eigen::Vector3f> labelled_p_qtm_mm;  // in the order of the 3D parameters' labels

  bool has_3d_no_labels = false;
  std::vector<UnlabelledMarker> unlabelled;
};

// Decodes a data packet (type 3). Markers per component above `max_markers`
// are too_many; a component whose size disagrees with its marker count is
// malformed; bytes after the last component are malformed. On error `out`
// holds no promise but stays valid for reuse.
Status read_data(const PacketView& packet, ByteOrder order, std::size_t max_markers, DataFrame& out);

// Writes a whole data packet (header included) with the 3D component if
// has_3d and the 3D no labels component if has_3d_no_labels, replacing `out`'s
// content. A NaN coordinate is written as all bits set, as QTM does.
void write_data_packet(const DataFrame& frame, ByteOrder order, std::vector<std::uint8_t>& out);

}  // namespace fabrik::qtm
