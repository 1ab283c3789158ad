// NatNet decoding. The layouts, as NaturalPoint's NatNet SDK samples read them
// (PacketClient.cpp of SDK 3.1/4.x, NatNetClient.py of SDK 4.x, NatNetTypes.h);
// all little endian, strings NUL-terminated, counts int32:
//   header      uint16 message id, uint16 payload bytes
//   sSender     char name[256], uint8 version[4], uint8 natnet_version[4]      264 bytes
//   server info sSender + uint64 clock Hz, uint16 data port, bool multicast,
//               uint8 group[4] (sSender_Server, packed)                        279 bytes
//   frame       int32 frame number
//               marker sets:  n, { name, n, n * float3 }
//               other markers: n, n * float3
//               rigid bodies: n, { int32 id, float3 pos, float4 quat, float err, int16 params }
//               skeletons:    n, { int32 id, n, rigid bodies as above }
//               assets (4.1+): n, { int32 id, n, n * 38 bytes, n, n * 26 bytes }
//               labeled markers: n, { int32 id, float3 pos, float size, int16 params, float residual }
//               force plates, devices: n, { int32 id, n channels, { n frames, n * float } }
//               suffix: uint32 timecode, uint32 subframe, double timestamp,
//                       uint64 mid-exposure, uint64 data received, uint64 transmit,
//                       [4.x: uint32 precision s, uint32 precision fraction],
//                       int16 params, int32 end-of-data tag (PacketClient reads it)
//   NatNet 4.1+ puts an int32 byte count after each section's count (the bytes
//   of that section that follow it), and after each description's type.
#include "bridges/natnet_protocol.hpp"

#include "bridges/natnet_bytes.hpp"

namespace fabrik::natnet {

using detail::Reader;

std::string to_string(const Version& v) {
  return std::to_string(v.major) + "." + std::to_string(v.minor) + "." + std::to_string(v.build) +
         "." + std::to_string(v.revision);
}

bool supported(const Version& v) { return v.major == 3 || v.major == 4; }

namespace {

constexpr std::size_t kSenderBytes = 256 + 4 + 4;
constexpr std::size_t kServerInfoBytes = kSenderBytes + 8 + 2 + 1 + 4;
constexpr std::size_t kRigidBodyBytes = 4 + 12 + 16 + 4 + 2;
constexpr std::size_t kLabeledMarkerBytes = 4 + 12 + 4 + 2 + 4;

bool finish(const Reader& r, std::string& error, const char* what) {
  if (r.ok()) return true;
  error = std::string(what) + ": " + r.error();
  return false;
}

bool check_version(const Version& v, std::string& error, const char* what) {
  if (supported(v)) return true;
  error = std::string(what) + ": NatNet " + to_string(v) +
          " is not supported (this codec reads NatNet 3.x and 4.x)";
  return false;
}

Point3f point(Reader& r, const char* what) {
  Point3f p;
  for (float& c : p) c = r.get<float>(what);
  return p;
}

// A section's NatNet 4.1 byte count: read it, and after the section check it.
class Section {
 public:
  Section(Reader& r, const Version& v, const char* what) : r_(r), what_(what) {
    if (!has_byte_counts(v) || !r.ok()) return;
    const std::int32_t n = r.get<std::int32_t>(what);
    if (!r.ok()) return;
    if (n < 0 || static_cast<std::size_t>(n) > r.remaining()) {
      r.fail(std::string(what) + " byte count " + std::to_string(n) + " does not fit in the " +
             std::to_string(r.remaining()) + " bytes left");
      return;
    }
    bytes_ = static_cast<std::size_t>(n);
    start_ = r.offset();
    counted_ = true;
  }
  void check() {
    if (!counted_ || !r_.ok()) return;
    const std::size_t used = r_.offset() - start_;
    if (used != bytes_)
      r_.fail(std::string(what_) + " byte count says " + std::to_string(bytes_) +
              " but its data has " + std::to_string(used));
  }
  bool counted() const { return counted_; }
  std::size_t bytes() const { return bytes_; }
  std::size_t start() const { return start_; }

 private:
  Reader& r_;
  const char* what_;
  bool counted_ = false;
  std::size_t bytes_ = 0, start_ = 0;
};

RigidBodyData rigid_body(Reader& r) {
  RigidBodyData b;
  b.id = r.get<std::int32_t>("rigid body id");
  b.p_m = point(r, "rigid body position");
  for (float& c : b.q_xyzw) c = r.get<float>("rigid body orientation");
  b.mean_error_m = r.get<float>("rigid body mean error");
  b.params = r.get<std::int16_t>("rigid body params");
  return b;
}

void skip_channels(Reader& r, const char* what) {
  const std::size_t n = r.count(what, 4);
  for (std::size_t c = 0; c < n && r.ok(); ++c) {
    const std::size_t frames = r.count("channel frame count", 4);
    r.skip(frames * 4, "channel frames");
  }
}

void frame_suffix(Reader& r, const Version& v, FrameOfData& f) {
  f.timecode = r.get<std::uint32_t>("timecode");
  f.timecode_subframe = r.get<std::uint32_t>("timecode subframe");
  f.timestamp_s = r.get<double>("timestamp");
  f.camera_mid_exposure_ticks = r.get<std::uint64_t>("camera mid-exposure timestamp");
  f.camera_data_received_ticks = r.get<std::uint64_t>("camera data received timestamp");
  f.transmit_ticks = r.get<std::uint64_t>("transmit timestamp");
  if (!r.ok()) return;
  // NatNet 4.x adds the precision timestamp (NatNetClient.py reads it for
  // major >= 4); every frame ends with params and the end-of-data tag.
  const bool precision = v.major >= 4;
  const std::size_t expected = (precision ? 8 : 0) + 2 + 4;
  if (r.remaining() != expected) {
    r.fail("frame suffix: " + std::to_string(r.remaining()) +
           " bytes after the transmit timestamp, NatNet " + to_string(v) + " has " +
           std::to_string(expected) + (r.remaining() > expected ? " (oversized)" : " (truncated)"));
    return;
  }
  f.has_precision_timestamp = precision;
  f.precision_timestamp_s = precision ? r.get<std::uint32_t>("precision timestamp") : 0;
  f.precision_timestamp_fraction =
      precision ? r.get<std::uint32_t>("precision timestamp fraction") : 0;
  f.params = r.get<std::int16_t>("frame params");
  r.skip(4, "end-of-data tag");
}

RigidBodyDescription rigid_body_description(Reader& r, const Version& v) {
  RigidBodyDescription d;
  d.name = r.cstring("rigid body name");
  d.id = r.get<std::int32_t>("rigid body id");
  d.parent_id = r.get<std::int32_t>("rigid body parent id");
  d.offset_m = point(r, "rigid body offset");
  // Positions of all markers, then all active labels, then (4.0+) all names.
  const std::size_t n = r.count("rigid body marker count", 16 + (v.major >= 4 ? 1 : 0));
  if (!r.ok()) return d;
  d.markers.resize(n);
  for (auto& m : d.markers) m.offset_m = point(r, "rigid body marker offset");
  for (auto& m : d.markers) m.active_label = r.get<std::int32_t>("rigid body marker label");
  if (v.major >= 4)
    for (auto& m : d.markers) m.name = r.cstring("rigid body marker name");
  return d;
}

constexpr std::size_t kMinRigidBodyDescriptionBytes = 1 + 4 + 4 + 12 + 4;

void skip_names(Reader& r, const char* what) {
  const std::size_t n = r.count(what, 1);
  for (std::size_t i = 0; i < n && r.ok(); ++i) r.cstring(what);
}

// Returns false for a type it does not know (the caller may skip it by size).
bool description(Reader& r, const Version& v, std::int32_t type, ModelDefinitions& out) {
  switch (type) {
    case 0: {  // marker set
      MarkerSetDescription m;
      m.name = r.cstring("marker set name");
      const std::size_t n = r.count("marker set marker count", 1);
      for (std::size_t i = 0; i < n && r.ok(); ++i)
        m.marker_names.push_back(r.cstring("marker set marker name"));
      out.marker_sets.push_back(std::move(m));
      return true;
    }
    case 1:
      out.rigid_bodies.push_back(rigid_body_description(r, v));
      return true;
    case 2: {  // skeleton
      SkeletonDescription s;
      s.name = r.cstring("skeleton name");
      s.id = r.get<std::int32_t>("skeleton id");
      const std::size_t n = r.count("skeleton bone count", kMinRigidBodyDescriptionBytes);
      for (std::size_t i = 0; i < n && r.ok(); ++i) s.bones.push_back(rigid_body_description(r, v));
      out.skeletons.push_back(std::move(s));
      return true;
    }
    case 3:  // force plate
      r.get<std::int32_t>("force plate id");
      r.cstring("force plate serial number");
      r.skip(4 + 4 + 12 + 12 * 12 * 4 + 4 * 3 * 4 + 4 + 4, "force plate geometry");
      skip_names(r, "force plate channel name");
      ++out.skipped;
      return true;
    case 4:  // device
      r.get<std::int32_t>("device id");
      r.cstring("device name");
      r.cstring("device serial number");
      r.skip(4 + 4, "device types");
      skip_names(r, "device channel name");
      ++out.skipped;
      return true;
    case 5:  // camera
      r.cstring("camera name");
      r.skip(12 + 16, "camera pose");
      ++out.skipped;
      return true;
    case 6: {  // asset (4.1+)
      r.cstring("asset name");
      r.skip(4 + 4, "asset type and id");
      const std::size_t n = r.count("asset rigid body count", kMinRigidBodyDescriptionBytes);
      for (std::size_t i = 0; i < n && r.ok(); ++i) rigid_body_description(r, v);
      const std::size_t m = r.count("asset marker count", 1 + 4 + 12 + 4 + 2);
      for (std::size_t i = 0; i < m && r.ok(); ++i) {
        r.cstring("asset marker name");
        r.skip(4 + 12 + 4 + 2, "asset marker");
      }
      ++out.skipped;
      return true;
    }
    default:
      return false;
  }
}

}  // namespace

bool split_message(std::span<const std::uint8_t> datagram, Message& out, std::string& error) {
  Reader r(datagram);
  const auto id = r.get<std::uint16_t>("message id");
  const auto size = r.get<std::uint16_t>("payload size");
  if (!finish(r, error, "NatNet header")) return false;
  if (r.remaining() != size) {
    error = "NatNet message " + std::to_string(id) + ": header says " + std::to_string(size) +
            " payload bytes, the datagram has " + std::to_string(r.remaining()) +
            (r.remaining() < size ? " (truncated)" : " (oversized)");
    return false;
  }
  out.id = static_cast<MessageId>(id);
  out.payload = datagram.subspan(kHeaderBytes);
  return true;
}

bool decode_connect_request(std::span<const std::uint8_t> payload, Version& requested,
                            std::string& error) {
  requested = {};
  // sSender (264) + bool subscribedDataOnly, then BitstreamVersion[4] at 265.
  constexpr std::size_t kVersionAt = kSenderBytes + 1;
  if (payload.size() > 1024) {
    error = "NatNet connect request: " + std::to_string(payload.size()) +
            " bytes, more than any client sends (at most 273)";
    return false;
  }
  if (payload.size() >= kVersionAt + 4)
    requested = {payload[kVersionAt], payload[kVersionAt + 1], payload[kVersionAt + 2],
                 payload[kVersionAt + 3]};
  return true;
}

bool decode_server_info(std::span<const std::uint8_t> payload, ServerInfo& out,
                        std::string& error) {
  out = {};
  if (payload.size() != kServerInfoBytes) {
    error = "NatNet server info: " + std::to_string(payload.size()) + " bytes, expected " +
            std::to_string(kServerInfoBytes) + " (sSender_Server of NatNet 3.0 and later)";
    if (payload.size() == kSenderBytes)  // a NatNet 2.x server sends sSender alone
      error += "; it is a bare sSender, NatNet " +
               to_string({payload[260], payload[261], payload[262], payload[263]});
    return false;
  }
  Reader r(payload);
  const auto name = r.take(256, "application name");
  const auto* nul = static_cast<const std::uint8_t*>(std::memchr(name.data(), 0, name.size()));
  if (nul == nullptr) {
    error = "NatNet server info: the application name has no terminating NUL in its 256 bytes";
    return false;
  }
  out.application_name.assign(reinterpret_cast<const char*>(name.data()),
                              static_cast<std::size_t>(nul - name.data()));
  auto version = [&r](const char* what) {
    Version v;
    v.major = r.get<std::uint8_t>(what);
    v.minor = r.get<std::uint8_t>(what);
    v.build = r.get<std::uint8_t>(what);
    v.revision = r.get<std::uint8_t>(what);
    return v;
  };
  out.application_version = version("application version");
  out.natnet_version = version("NatNet version");
  {
    out.high_res_clock_frequency_hz = r.get<std::uint64_t>("clock frequency");
    out.data_port = r.get<std::uint16_t>("data port");
    out.is_multicast = r.get<std::uint8_t>("multicast flag") != 0;
    for (auto& b : out.multicast_group) b = r.get<std::uint8_t>("multicast group");
  }
  return finish(r, error, "NatNet server info");
}

bool decode_model_definitions(std::span<const std::uint8_t> payload, const Version& v,
                              ModelDefinitions& out, std::string& error) {
  out = {};
  if (!check_version(v, error, "NatNet model definitions")) return false;
  Reader r(payload);
  const std::size_t n = r.count("description count", has_byte_counts(v) ? 8 : 4);
  for (std::size_t i = 0; i < n && r.ok(); ++i) {
    const auto type = r.get<std::int32_t>("description type");
    Section section(r, v, "description");
    if (!r.ok()) break;
    if (!description(r, v, type, out)) {
      if (!section.counted()) {
        r.fail("unknown description type " + std::to_string(type) +
               " (NatNet before 4.1 gives no size to skip it by)");
        break;
      }
      r.skip(section.bytes(), "unknown description");
      ++out.skipped;
    }
    section.check();
  }
  if (r.ok() && r.remaining() != 0)
    r.fail(std::to_string(r.remaining()) + " bytes after the last description (oversized)");
  return finish(r, error, "NatNet model definitions");
}

bool decode_frame_of_data(std::span<const std::uint8_t> payload, const Version& v,
                          FrameOfData& f, std::string& error) {
  if (!check_version(v, error, "NatNet frame of data")) return false;
  Reader r(payload);
  f.frame_number = r.get<std::int32_t>("frame number");

  f.marker_sets.clear();
  {
    const std::size_t n = r.count("marker set count", 1 + 4);
    Section s(r, v, "marker sets");
    for (std::size_t i = 0; i < n && r.ok(); ++i) {
      MarkerSetData m;
      m.name = r.cstring("marker set name");
      const std::size_t k = r.count("marker set marker count", 12);
      m.p_m.resize(k);
      for (auto& p : m.p_m) p = point(r, "marker set marker");
      f.marker_sets.push_back(std::move(m));
    }
    s.check();
  }
  {
    const std::size_t n = r.count("other marker count", 12);
    Section s(r, v, "other markers");
    f.other_markers_p_m.resize(n);
    for (auto& p : f.other_markers_p_m) p = point(r, "other marker");
    s.check();
  }
  {
    const std::size_t n = r.count("rigid body count", kRigidBodyBytes);
    Section s(r, v, "rigid bodies");
    f.rigid_bodies.resize(n);
    for (auto& b : f.rigid_bodies) b = rigid_body(r);
    s.check();
  }
  f.skeletons.clear();
  {
    const std::size_t n = r.count("skeleton count", 8);
    Section s(r, v, "skeletons");
    for (std::size_t i = 0; i < n && r.ok(); ++i) {
      SkeletonData sk;
      sk.id = r.get<std::int32_t>("skeleton id");
      const std::size_t k = r.count("skeleton bone count", kRigidBodyBytes);
      sk.bones.resize(k);
      for (auto& b : sk.bones) b = rigid_body(r);
      f.skeletons.push_back(std::move(sk));
    }
    s.check();
  }
  f.skipped_assets = 0;
  if (has_byte_counts(v)) {  // assets: NatNet 4.1 (Motive 3.1) and later
    const std::size_t n = r.count("asset count", 12);
    Section s(r, v, "assets");
    for (std::size_t i = 0; i < n && r.ok(); ++i) {
      r.get<std::int32_t>("asset id");
      r.skip(r.count("asset rigid body count", kRigidBodyBytes) * kRigidBodyBytes, "asset rigid bodies");
      r.skip(r.count("asset marker count", kLabeledMarkerBytes) * kLabeledMarkerBytes, "asset markers");
      ++f.skipped_assets;
    }
    s.check();
  }
  {
    const std::size_t n = r.count("labeled marker count", kLabeledMarkerBytes);
    Section s(r, v, "labeled markers");
    f.labeled_markers.resize(n);
    for (auto& m : f.labeled_markers) {
      m.id = r.get<std::int32_t>("labeled marker id");
      m.p_m = point(r, "labeled marker position");
      m.size_m = r.get<float>("labeled marker size");
      m.params = r.get<std::int16_t>("labeled marker params");
      m.residual_m = r.get<float>("labeled marker residual");
    }
    s.check();
  }
  auto skip_devices = [&](const char* count_what, const char* section_what) {
    const std::size_t n = r.count(count_what, 8);
    Section s(r, v, section_what);
    for (std::size_t i = 0; i < n && r.ok(); ++i) {
      r.get<std::int32_t>("id");
      skip_channels(r, "channel count");
    }
    s.check();
    return static_cast<int>(n);
  };
  f.skipped_force_plates = skip_devices("force plate count", "force plates");
  f.skipped_devices = skip_devices("device count", "devices");
  frame_suffix(r, v, f);
  return finish(r, error, "NatNet frame of data");
}

}  // namespace fabrik::natnet
