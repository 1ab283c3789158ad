// NatNet (OptiTrack Motive's streaming protocol), versions 3.x and 4.x: a pure
// codec of its messages, no sockets. Layouts follow NaturalPoint's NatNet SDK
// samples (PacketClient.cpp, NatNetClient.py, NatNetTypes.h); the byte-level
// facts and their sources are listed in docs at the top of natnet_protocol.cpp.
//
// Decoding never throws: every decode_* returns false with a message in
// `error` for a truncated, oversized or inconsistent payload. Units stay as the
// wire has them (metres, Motive's axes); callers convert at their edge.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace fabrik::natnet {

// Message ids (NatNetTypes.h / PacketClient.cpp "NATNET message ids").
enum class MessageId : std::uint16_t {
  connect = 0,  // NAT_CONNECT (NAT_PING in NatNet 2.x)
  server_info = 1,
  request = 2,
  response = 3,
  request_model_def = 4,
  model_def = 5,
  request_frame_of_data = 6,
  frame_of_data = 7,
  message_string = 8,
  disconnect = 9,
  keep_alive = 10,
  unrecognized_request = 100,
};

inline constexpr std::uint16_t kCommandPort = 1510;
inline constexpr std::uint16_t kDataPort = 1511;
inline constexpr const char* kDefaultMulticastGroup = "239.255.42.99";
inline constexpr std::size_t kHeaderBytes = 4;  // uint16 id + uint16 payload size
inline constexpr std::size_t kMaxPayloadBytes = 0xFFFF;

struct Version {
  std::uint8_t major = 0, minor = 0, build = 0, revision = 0;
  friend bool operator==(const Version&, const Version&) = default;
};
std::string to_string(const Version& v);
// The versions this codec decodes and encodes frames and model definitions for.
bool supported(const Version& v);
// NatNet 4.1 (Motive 3.1) and later: a byte count after each frame section's
// count and each description's type, and the asset section in frames.
inline bool has_byte_counts(const Version& v) {
  return v.major > 4 || (v.major == 4 && v.minor >= 1);
}

using Point3f = std::array<float, 3>;

// One datagram split into its header and payload.
struct Message {
  MessageId id{};
  std::span<const std::uint8_t> payload;
};
// The payload size in the header must equal the datagram's rest exactly:
// shorter is truncated, longer is oversized; both are errors.
bool split_message(std::span<const std::uint8_t> datagram, Message& out, std::string& error);
// Empty if the payload is longer than the header's uint16 size can say.
std::vector<std::uint8_t> encode_message(MessageId id, std::span<const std::uint8_t> payload);

// --- connect / server info ---------------------------------------------------
// NAT_CONNECT as the SDK 4.x clients send it: sSender (name "Ping", 256 + 4 + 4
// bytes), then sConnectionOptions (bool subscribedDataOnly, uint8 BitstreamVersion[4])
// with the NatNet version asked for, zero padded to 270 bytes plus a NUL.
std::vector<std::uint8_t> encode_connect_request(const Version& requested);
// Server side: the version a client asks for; {0,0,0,0} (server's choice) for a
// short request (older clients send an empty or sSender-only payload).
bool decode_connect_request(std::span<const std::uint8_t> payload, Version& requested,
                            std::string& error);

struct ServerInfo {
  std::string application_name;  // e.g. "Motive"
  Version application_version;
  Version natnet_version;
  // sSender_Server's additions (NatNet 3.0+).
  std::uint64_t high_res_clock_frequency_hz = 0;
  std::uint16_t data_port = 0;
  bool is_multicast = false;
  std::array<std::uint8_t, 4> multicast_group{};
};
// Exactly the 279-byte sSender_Server; a 264-byte bare sSender (NatNet 2.x) is an error.
bool decode_server_info(std::span<const std::uint8_t> payload, ServerInfo& out,
                        std::string& error);
std::vector<std::uint8_t> encode_server_info(const ServerInfo& info);  // payload only

// --- model definitions (NAT_MODELDEF) ----------------------------------------
struct MarkerSetDescription {
  std::string name;
  std::vector<std::string> marker_names;
  friend bool operator==(const MarkerSetDescription&, const MarkerSetDescription&) = default;
};
struct RigidBodyMarkerDescription {
  Point3f offset_m{};
  std::int32_t active_label = 0;
  std::string name;  // NatNet 4.0+
  friend bool operator==(const RigidBodyMarkerDescription&,
                         const RigidBodyMarkerDescription&) = default;
};
struct RigidBodyDescription {
  std::string name;
  std::int32_t id = 0;
  std::int32_t parent_id = -1;
  Point3f offset_m{};
  std::vector<RigidBodyMarkerDescription> markers;
  friend bool operator==(const RigidBodyDescription&, const RigidBodyDescription&) = default;
};
struct SkeletonDescription {
  std::string name;
  std::int32_t id = 0;
  std::vector<RigidBodyDescription> bones;
  friend bool operator==(const SkeletonDescription&, const SkeletonDescription&) = default;
};
struct ModelDefinitions {
  std::vector<MarkerSetDescription> marker_sets;
  std::vector<RigidBodyDescription> rigid_bodies;
  std::vector<SkeletonDescription> skeletons;
  int skipped = 0;  // force plates, devices, cameras, assets: read past, not kept
};
bool decode_model_definitions(std::span<const std::uint8_t> payload, const Version& v,
                              ModelDefinitions& out, std::string& error);
std::vector<std::uint8_t> encode_model_definitions(const ModelDefinitions& defs,
                                                   const Version& v);

// --- frame of data (NAT_FRAMEOFDATA) -----------------------------------------
struct MarkerSetData {
  std::string name;
  std::vector<Point3f> p_m;  // in the order of the description's marker_names
  friend bool operator==(const MarkerSetData&, const MarkerSetData&) = default;
};
struct RigidBodyData {
  std::int32_t id = 0;
  Point3f p_m{};
  std::array<float, 4> q_xyzw{0, 0, 0, 1};
  float mean_error_m = 0;
  std::int16_t params = 0;  // bit 0: tracking valid
  friend bool operator==(const RigidBodyData&, const RigidBodyData&) = default;
};
struct SkeletonData {
  std::int32_t id = 0;
  std::vector<RigidBodyData> bones;
  friend bool operator==(const SkeletonData&, const SkeletonData&) = default;
};
struct LabeledMarker {
  std::int32_t id = 0;  // asset (model) id << 16 | member id
  Point3f p_m{};
  float size_m = 0;
  std::int16_t params = 0;  // bit 0 occluded, 1 point-cloud solved, 2 model solved
  float residual_m = 0;
  std::int32_t model_id() const { return id >> 16; }
  std::int32_t member_id() const { return id & 0xFFFF; }
  bool occluded() const { return (params & kOccluded) != 0; }
  static constexpr std::int16_t kOccluded = 0x01;
  static constexpr std::int16_t kPointCloudSolved = 0x02;
  static constexpr std::int16_t kModelSolved = 0x04;
  friend bool operator==(const LabeledMarker&, const LabeledMarker&) = default;
};
struct FrameOfData {
  std::int32_t frame_number = 0;
  std::vector<MarkerSetData> marker_sets;
  std::vector<Point3f> other_markers_p_m;  // "legacy other" (unlabeled) markers
  std::vector<RigidBodyData> rigid_bodies;
  std::vector<SkeletonData> skeletons;
  std::vector<LabeledMarker> labeled_markers;
  int skipped_assets = 0, skipped_force_plates = 0, skipped_devices = 0;  // read past
  std::uint32_t timecode = 0, timecode_subframe = 0;
  double timestamp_s = 0;  // seconds since Motive's start of streaming
  // High-resolution clock ticks (ServerInfo::high_res_clock_frequency_hz per second).
  std::uint64_t camera_mid_exposure_ticks = 0, camera_data_received_ticks = 0, transmit_ticks = 0;
  bool has_precision_timestamp = false;  // NatNet 4.x
  std::uint32_t precision_timestamp_s = 0, precision_timestamp_fraction = 0;
  std::int16_t params = 0;  // bit 0: recording, bit 1: tracked models changed
  bool recording() const { return (params & 0x01) != 0; }
  bool tracked_models_changed() const { return (params & 0x02) != 0; }
};
// `out` is reused (its vectors keep their capacity across frames).
bool decode_frame_of_data(std::span<const std::uint8_t> payload, const Version& v,
                          FrameOfData& out, std::string& error);
std::vector<std::uint8_t> encode_frame_of_data(const FrameOfData& frame, const Version& v);

}  // namespace fabrik::natnet
