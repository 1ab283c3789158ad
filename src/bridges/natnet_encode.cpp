// NatNet encoding, for the simulator (`fabrik sim natnet`) and the tests: the
// same layouts as natnet_protocol.cpp decodes (see the table there). Frames
// end with the 4-byte end-of-data tag PacketClient reads; byte counts are
// written for NatNet 4.1+, the precision timestamp for 4.x.
#include <cstring>

#include "bridges/natnet_bytes.hpp"
#include "bridges/natnet_protocol.hpp"

namespace fabrik::natnet {

using detail::Writer;

namespace {

void put_point(Writer& w, const Point3f& p) {
  for (float c : p) w.put(c);
}

void put_version(Writer& w, const Version& v) {
  w.put(v.major);
  w.put(v.minor);
  w.put(v.build);
  w.put(v.revision);
}

void put_name256(Writer& w, const std::string& name) {
  const std::size_t n = std::min<std::size_t>(name.size(), 255);
  w.bytes.insert(w.bytes.end(), name.begin(), name.begin() + static_cast<std::ptrdiff_t>(n));
  w.zeros(256 - n);
}

void put_count(Writer& w, std::size_t n) { w.put(static_cast<std::int32_t>(n)); }

// Writes the section's byte count (4.1+) around what `body` writes.
template <class Body>
void section(Writer& w, const Version& v, Body body) {
  if (!has_byte_counts(v)) {
    body();
    return;
  }
  const std::size_t at = w.reserve_int32();
  body();
  w.patch_int32(at, static_cast<std::int32_t>(w.bytes.size() - at - 4));
}

void put_rigid_body(Writer& w, const RigidBodyData& b) {
  w.put(b.id);
  put_point(w, b.p_m);
  for (float c : b.q_xyzw) w.put(c);
  w.put(b.mean_error_m);
  w.put(b.params);
}

void put_rigid_body_description(Writer& w, const Version& v, const RigidBodyDescription& d) {
  w.cstring(d.name);
  w.put(d.id);
  w.put(d.parent_id);
  put_point(w, d.offset_m);
  put_count(w, d.markers.size());
  for (const auto& m : d.markers) put_point(w, m.offset_m);
  for (const auto& m : d.markers) w.put(m.active_label);
  if (v.major >= 4)
    for (const auto& m : d.markers) w.cstring(m.name);
}

template <class Body>
void description(Writer& w, const Version& v, std::int32_t type, Body body) {
  w.put(type);
  section(w, v, body);
}

}  // namespace

std::vector<std::uint8_t> encode_message(MessageId id, std::span<const std::uint8_t> payload) {
  if (payload.size() > kMaxPayloadBytes) return {};  // the uint16 size cannot say it
  Writer w;
  w.put(static_cast<std::uint16_t>(id));
  w.put(static_cast<std::uint16_t>(payload.size()));
  w.bytes.insert(w.bytes.end(), payload.begin(), payload.end());
  return std::move(w.bytes);
}

std::vector<std::uint8_t> encode_connect_request(const Version& requested) {
  // As NatNetClient.py (SDK 4.x) sends it: 270 bytes, "Ping" as the sender's
  // name, the version at 265 (sConnectionOptions.BitstreamVersion), then a NUL.
  Writer w;
  put_name256(w, "Ping");
  w.zeros(4 + 4);  // sSender version and NatNet version: unused by the server
  w.put<std::uint8_t>(0);  // subscribedDataOnly
  put_version(w, requested);
  w.zeros(270 - w.bytes.size());
  w.put<std::uint8_t>(0);
  return std::move(w.bytes);
}

std::vector<std::uint8_t> encode_server_info(const ServerInfo& info) {
  Writer w;
  put_name256(w, info.application_name);
  put_version(w, info.application_version);
  put_version(w, info.natnet_version);
  w.put(info.high_res_clock_frequency_hz);
  w.put(info.data_port);
  w.put<std::uint8_t>(info.is_multicast ? 1 : 0);
  for (std::uint8_t b : info.multicast_group) w.put(b);
  return std::move(w.bytes);
}

std::vector<std::uint8_t> encode_model_definitions(const ModelDefinitions& defs,
                                                   const Version& v) {
  Writer w;
  put_count(w, defs.marker_sets.size() + defs.rigid_bodies.size() + defs.skeletons.size());
  for (const auto& m : defs.marker_sets)
    description(w, v, 0, [&] {
      w.cstring(m.name);
      put_count(w, m.marker_names.size());
      for (const auto& name : m.marker_names) w.cstring(name);
    });
  for (const auto& b : defs.rigid_bodies)
    description(w, v, 1, [&] { put_rigid_body_description(w, v, b); });
  for (const auto& s : defs.skeletons)
    description(w, v, 2, [&] {
      w.cstring(s.name);
      w.put(s.id);
      put_count(w, s.bones.size());
      for (const auto& b : s.bones) put_rigid_body_description(w, v, b);
    });
  return std::move(w.bytes);
}

std::vector<std::uint8_t> encode_frame_of_data(const FrameOfData& f, const Version& v) {
  Writer w;
  w.put(f.frame_number);
  put_count(w, f.marker_sets.size());
  section(w, v, [&] {
    for (const auto& m : f.marker_sets) {
      w.cstring(m.name);
      put_count(w, m.p_m.size());
      for (const auto& p : m.p_m) put_point(w, p);
    }
  });
  put_count(w, f.other_markers_p_m.size());
  section(w, v, [&] {
    for (const auto& p : f.other_markers_p_m) put_point(w, p);
  });
  put_count(w, f.rigid_bodies.size());
  section(w, v, [&] {
    for (const auto& b : f.rigid_bodies) put_rigid_body(w, b);
  });
  put_count(w, f.skeletons.size());
  section(w, v, [&] {
    for (const auto& s : f.skeletons) {
      w.put(s.id);
      put_count(w, s.bones.size());
      for (const auto& b : s.bones) put_rigid_body(w, b);
    }
  });
  if (has_byte_counts(v)) {  // no assets
    put_count(w, 0);
    section(w, v, [] {});
  }
  put_count(w, f.labeled_markers.size());
  section(w, v, [&] {
    for (const auto& m : f.labeled_markers) {
      w.put(m.id);
      put_point(w, m.p_m);
      w.put(m.size_m);
      w.put(m.params);
      w.put(m.residual_m);
    }
  });
  for (int i = 0; i < 2; ++i) {  // no force plates, no devices
    put_count(w, 0);
    section(w, v, [] {});
  }
  w.put(f.timecode);
  w.put(f.timecode_subframe);
  w.put(f.timestamp_s);
  w.put(f.camera_mid_exposure_ticks);
  w.put(f.camera_data_received_ticks);
  w.put(f.transmit_ticks);
  if (v.major >= 4) {
    w.put(f.precision_timestamp_s);
    w.put(f.precision_timestamp_fraction);
  }
  w.put(f.params);
  w.put<std::int32_t>(0);  // end-of-data tag
  return std::move(w.bytes);
}

}  // namespace fabrik::natnet
