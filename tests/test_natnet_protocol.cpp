// The NatNet codec (src/bridges/natnet_*) against byte fixtures written by hand
// from the layouts NaturalPoint's NatNet SDK samples read (PacketClient.cpp,
// NatNetClient.py, NatNetTypes.h; the table is at the top of
// natnet_protocol.cpp), then round trips, truncations and hostile counts.
#include <catch2/catch.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "bridges/natnet_names.hpp"
#include "bridges/natnet_protocol.hpp"

using namespace fabrik::natnet;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr Version v30{3, 0, 0, 0}, v31{3, 1, 0, 0}, v40{4, 0, 0, 0}, v41{4, 1, 0, 0};

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
Bytes zeros(std::size_t n) { return Bytes(n, 0); }

Message split(const Bytes& datagram) {
  Message m;
  std::string error;
  INFO(error);
  REQUIRE(split_message(datagram, m, error));
  return m;
}

// NAT_FRAMEOFDATA, NatNet 3.0: frame 42; marker set "Sub" with (1,2,3) and
// (0.5,0.25,-1); one other marker (1.5,1.5,1.5); no rigid bodies or skeletons;
// labeled markers 0x00010001 at (1,2,3) and 0x00010002 occluded; no force
// plates or devices; timecode 0x01020304.5, timestamp 1.25 s, ticks
// 0x1000/0x1100/0x1200, params 1 (recording), end-of-data tag.
const Bytes kFrame30 = {
    0x07, 0x00, 0xAE, 0x00,                          // id 7, payload 174 bytes
    0x2A, 0x00, 0x00, 0x00,                          // frame number 42
    0x01, 0x00, 0x00, 0x00,                          // marker set count 1
    'S',  'u',  'b',  0x00,                          // name "Sub"
    0x02, 0x00, 0x00, 0x00,                          // marker count 2
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,  // 1, 2, 3
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0xBF,  // .5 .25 -1
    0x01, 0x00, 0x00, 0x00,                          // other marker count 1
    0x00, 0x00, 0xC0, 0x3F, 0x00, 0x00, 0xC0, 0x3F, 0x00, 0x00, 0xC0, 0x3F,  // 1.5 x3
    0x00, 0x00, 0x00, 0x00,                          // rigid body count 0
    0x00, 0x00, 0x00, 0x00,                          // skeleton count 0
    0x02, 0x00, 0x00, 0x00,                          // labeled marker count 2
    0x01, 0x00, 0x01, 0x00,                          //   id: model 1, member 1
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,  // 1, 2, 3
    0x0A, 0xD7, 0x23, 0x3C,                          //   size 0.01
    0x00, 0x00,                                      //   params 0
    0x00, 0x00, 0x00, 0x00,                          //   residual 0
    0x02, 0x00, 0x01, 0x00,                          //   id: model 1, member 2
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0xBF,  // .5 .25 -1
    0x0A, 0xD7, 0x23, 0x3C,                          //   size 0.01
    0x01, 0x00,                                      //   params: occluded
    0x00, 0x00, 0x80, 0x3E,                          //   residual 0.25
    0x00, 0x00, 0x00, 0x00,                          // force plate count 0
    0x00, 0x00, 0x00, 0x00,                          // device count 0
    0x04, 0x03, 0x02, 0x01,                          // timecode
    0x05, 0x00, 0x00, 0x00,                          // timecode subframe
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF4, 0x3F,  // timestamp 1.25 (double)
    0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // camera mid-exposure
    0x00, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // camera data received
    0x00, 0x12, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // transmit
    0x01, 0x00,                                      // params: recording
    0x00, 0x00, 0x00, 0x00,                          // end-of-data tag
};

// The same frame in NatNet 4.1: a byte count after every section's count, an
// (empty) asset section before the labeled markers, and the precision
// timestamp (60 s, fraction 7) before the params.
const Bytes kFrame41 = {
    0x07, 0x00, 0xDA, 0x00,                          // id 7, payload 218 bytes
    0x2A, 0x00, 0x00, 0x00,                          // frame number 42
    0x01, 0x00, 0x00, 0x00,                          // marker set count 1
    0x20, 0x00, 0x00, 0x00,                          //   byte count 32 = 4 + 4 + 24
    'S',  'u',  'b',  0x00,
    0x02, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0xBF,
    0x01, 0x00, 0x00, 0x00,                          // other marker count 1
    0x0C, 0x00, 0x00, 0x00,                          //   byte count 12
    0x00, 0x00, 0xC0, 0x3F, 0x00, 0x00, 0xC0, 0x3F, 0x00, 0x00, 0xC0, 0x3F,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // rigid bodies 0, byte count 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // skeletons 0, byte count 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // assets 0, byte count 0
    0x02, 0x00, 0x00, 0x00,                          // labeled marker count 2
    0x34, 0x00, 0x00, 0x00,                          //   byte count 52 = 2 x 26
    0x01, 0x00, 0x01, 0x00,
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,
    0x0A, 0xD7, 0x23, 0x3C, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x01, 0x00,
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0xBF,
    0x0A, 0xD7, 0x23, 0x3C, 0x01, 0x00, 0x00, 0x00, 0x80, 0x3E,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // force plates 0, byte count 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // devices 0, byte count 0
    0x04, 0x03, 0x02, 0x01, 0x05, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF4, 0x3F,
    0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x12, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x3C, 0x00, 0x00, 0x00,                          // precision timestamp 60 s
    0x07, 0x00, 0x00, 0x00,                          // precision fraction 7
    0x01, 0x00,                                      // params: recording
    0x00, 0x00, 0x00, 0x00,                          // end-of-data tag
};

// NAT_MODELDEF, NatNet 3.0: marker set "Sub" (LKNE, RKNE) and rigid body "RB"
// id 7, parent -1, offset (1,2,3), one marker at (.5,.5,.5) with active label 5.
const Bytes kModelDef30 = {
    0x05, 0x00, 0x49, 0x00,                          // id 5, payload 73 bytes
    0x02, 0x00, 0x00, 0x00,                          // 2 descriptions
    0x00, 0x00, 0x00, 0x00,                          // type 0: marker set
    'S',  'u',  'b',  0x00,
    0x02, 0x00, 0x00, 0x00,                          // 2 markers
    'L',  'K',  'N',  'E',  0x00,
    'R',  'K',  'N',  'E',  0x00,
    0x01, 0x00, 0x00, 0x00,                          // type 1: rigid body
    'R',  'B',  0x00,
    0x07, 0x00, 0x00, 0x00,                          // id 7
    0xFF, 0xFF, 0xFF, 0xFF,                          // parent -1
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,  // 1, 2, 3
    0x01, 0x00, 0x00, 0x00,                          // 1 marker: positions, then labels
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0x3F,
    0x05, 0x00, 0x00, 0x00,                          // active label 5
};

// The same in NatNet 4.1: a byte count after each type, marker names (4.0+)
// after the rigid body's labels.
const Bytes kModelDef41 = {
    0x05, 0x00, 0x54, 0x00,                          // id 5, payload 84 bytes
    0x02, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00,                          // type 0: marker set
    0x12, 0x00, 0x00, 0x00,                          //   byte count 18 = 4 + 4 + 5 + 5
    'S',  'u',  'b',  0x00,
    0x02, 0x00, 0x00, 0x00,
    'L',  'K',  'N',  'E',  0x00,
    'R',  'K',  'N',  'E',  0x00,
    0x01, 0x00, 0x00, 0x00,                          // type 1: rigid body
    0x2E, 0x00, 0x00, 0x00,                          //   byte count 46
    'R',  'B',  0x00,
    0x07, 0x00, 0x00, 0x00,
    0xFF, 0xFF, 0xFF, 0xFF,
    0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,
    0x01, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0x3F,
    0x05, 0x00, 0x00, 0x00,
    'M',  '1',  0x00,                                // marker name "M1"
};

// NAT_SERVERINFO: sSender_Server (packed): name "Motive" in 256 bytes, Motive
// 3.1.0.0, NatNet 4.1.0.0, clock 10 MHz, data port 1511, multicast to 239.255.42.99.
const Bytes kServerInfo = cat({
    {0x01, 0x00, 0x17, 0x01},  // id 1, payload 279 bytes
    {'M', 'o', 't', 'i', 'v', 'e'}, zeros(250),
    {0x03, 0x01, 0x00, 0x00},                          // application version
    {0x04, 0x01, 0x00, 0x00},                          // NatNet version
    {0x80, 0x96, 0x98, 0x00, 0x00, 0x00, 0x00, 0x00},  // 10 000 000 Hz
    {0xE7, 0x05},                                      // data port 1511
    {0x01},                                            // multicast
    {0xEF, 0xFF, 0x2A, 0x63},                          // 239.255.42.99
});

// NAT_CONNECT as NatNetClient.py (SDK 4.x) sends it, asking for NatNet 4.1:
// "Ping" in the sender name, BitstreamVersion at byte 265, 270 bytes and a NUL.
const Bytes kConnect41 = cat({
    {0x00, 0x00, 0x0F, 0x01},  // id 0, payload 271 bytes
    {'P', 'i', 'n', 'g'}, zeros(261),
    {0x04, 0x01, 0x00, 0x00},  // bytes 265..268: the version asked for
    zeros(2),
});

FrameOfData rich_frame(const Version& v) {
  FrameOfData f;
  f.frame_number = 123456;
  f.marker_sets = {{"subject01", {{0.1f, 0.2f, 0.3f}, {-1.f, 0.f, 2.5f}}}, {"all", {}}};
  f.other_markers_p_m = {{9.f, 8.f, 7.f}};
  f.rigid_bodies = {{3, {1.f, 2.f, 3.f}, {0.f, 0.f, 0.7071f, 0.7071f}, 0.001f, 1}};
  f.skeletons = {{5, {{65537, {0.f, 1.f, 0.f}, {0, 0, 0, 1}, 0.002f, 1},
                      {65538, {0.f, 1.5f, 0.f}, {0, 0, 0, 1}, 0.f, 0}}}};
  f.labeled_markers = {{0x00050003, {0.1f, 0.2f, 0.3f}, 0.014f, LabeledMarker::kModelSolved, 0.0005f},
                       {0x00050004, {0.f, 0.f, 0.f}, 0.014f, LabeledMarker::kOccluded, 0.f}};
  f.timecode = 77;
  f.timecode_subframe = 2;
  f.timestamp_s = 12.345678901234;
  f.camera_mid_exposure_ticks = 0x0123456789ABCDEFull;
  f.camera_data_received_ticks = 0x0123456789ABCDFFull;
  f.transmit_ticks = 0x0123456789ABCEFFull;
  if (v.major >= 4) {
    f.has_precision_timestamp = true;
    f.precision_timestamp_s = 3600;
    f.precision_timestamp_fraction = 999;
  }
  f.params = 0x02;
  return f;
}

ModelDefinitions rich_defs(const Version& v) {
  ModelDefinitions d;
  d.marker_sets = {{"subject01", {"LASI", "RASI", "LKNE"}}, {"all", {"subject01:LASI"}}};
  RigidBodyDescription rb{"wand", 3, -1, {0.f, 0.f, 0.f}, {{{0.01f, 0.f, 0.f}, 1, ""}, {{0.f, 0.02f, 0.f}, 2, ""}}};
  if (v.major >= 4) {
    rb.markers[0].name = "wand_1";
    rb.markers[1].name = "wand_2";
  }
  d.rigid_bodies = {rb};
  d.skeletons = {{"subject01", 5, {{"Hip", 65537, -1, {0.f, 1.f, 0.f}, {}}, rb}}};
  return d;
}

void require_same(const FrameOfData& a, const FrameOfData& b) {
  CHECK(a.frame_number == b.frame_number);
  CHECK(a.marker_sets == b.marker_sets);
  CHECK(a.other_markers_p_m == b.other_markers_p_m);
  CHECK(a.rigid_bodies == b.rigid_bodies);
  CHECK(a.skeletons == b.skeletons);
  CHECK(a.labeled_markers == b.labeled_markers);
  CHECK(a.timecode == b.timecode);
  CHECK(a.timecode_subframe == b.timecode_subframe);
  CHECK(a.timestamp_s == b.timestamp_s);
  CHECK(a.camera_mid_exposure_ticks == b.camera_mid_exposure_ticks);
  CHECK(a.camera_data_received_ticks == b.camera_data_received_ticks);
  CHECK(a.transmit_ticks == b.transmit_ticks);
  CHECK(a.has_precision_timestamp == b.has_precision_timestamp);
  CHECK(a.precision_timestamp_s == b.precision_timestamp_s);
  CHECK(a.precision_timestamp_fraction == b.precision_timestamp_fraction);
  CHECK(a.params == b.params);
}

void check_fixture_frame(const FrameOfData& f) {
  CHECK(f.frame_number == 42);
  REQUIRE(f.marker_sets.size() == 1);
  CHECK(f.marker_sets[0].name == "Sub");
  CHECK(f.marker_sets[0].p_m == std::vector<Point3f>{{1.f, 2.f, 3.f}, {0.5f, 0.25f, -1.f}});
  CHECK(f.other_markers_p_m == std::vector<Point3f>{{1.5f, 1.5f, 1.5f}});
  CHECK(f.rigid_bodies.empty());
  CHECK(f.skeletons.empty());
  REQUIRE(f.labeled_markers.size() == 2);
  CHECK(f.labeled_markers[0].model_id() == 1);
  CHECK(f.labeled_markers[0].member_id() == 1);
  CHECK(f.labeled_markers[0].p_m == Point3f{1.f, 2.f, 3.f});
  CHECK(f.labeled_markers[0].size_m == 0.01f);
  CHECK_FALSE(f.labeled_markers[0].occluded());
  CHECK(f.labeled_markers[1].member_id() == 2);
  CHECK(f.labeled_markers[1].occluded());
  CHECK(f.labeled_markers[1].residual_m == 0.25f);
  CHECK(f.timecode == 0x01020304u);
  CHECK(f.timecode_subframe == 5u);
  CHECK(f.timestamp_s == 1.25);
  CHECK(f.camera_mid_exposure_ticks == 0x1000u);
  CHECK(f.camera_data_received_ticks == 0x1100u);
  CHECK(f.transmit_ticks == 0x1200u);
  CHECK(f.recording());
  CHECK_FALSE(f.tracked_models_changed());
}

}  // namespace

TEST_CASE("NatNet message ids are the SDK's", "[natnet]") {
  CHECK(static_cast<int>(MessageId::connect) == 0);
  CHECK(static_cast<int>(MessageId::server_info) == 1);
  CHECK(static_cast<int>(MessageId::request) == 2);
  CHECK(static_cast<int>(MessageId::response) == 3);
  CHECK(static_cast<int>(MessageId::request_model_def) == 4);
  CHECK(static_cast<int>(MessageId::model_def) == 5);
  CHECK(static_cast<int>(MessageId::request_frame_of_data) == 6);
  CHECK(static_cast<int>(MessageId::frame_of_data) == 7);
  CHECK(static_cast<int>(MessageId::message_string) == 8);
  CHECK(static_cast<int>(MessageId::unrecognized_request) == 100);
}

TEST_CASE("NatNet header: the payload size must match the datagram", "[natnet]") {
  const Message m = split(kFrame30);
  CHECK(m.id == MessageId::frame_of_data);
  CHECK(m.payload.size() == 174);
  std::string error;
  Message out;
  Bytes longer = kFrame30;
  longer.push_back(0);
  CHECK_FALSE(split_message(longer, out, error));
  CHECK(error.find("oversized") != std::string::npos);
  for (std::size_t n = 0; n < kFrame30.size(); ++n) {
    error.clear();
    CHECK_FALSE(split_message(std::span(kFrame30).first(n), out, error));
    CHECK_FALSE(error.empty());
  }
  const Bytes empty_request = encode_message(MessageId::request_model_def, {});
  CHECK(empty_request == Bytes{0x04, 0x00, 0x00, 0x00});
  CHECK(encode_message(MessageId::frame_of_data, zeros(kMaxPayloadBytes)).size() ==
        kHeaderBytes + kMaxPayloadBytes);
  CHECK(encode_message(MessageId::frame_of_data, zeros(kMaxPayloadBytes + 1)).empty());
}

TEST_CASE("NatNet connect request carries the version asked for", "[natnet]") {
  CHECK(encode_message(MessageId::connect, encode_connect_request(v41)) == kConnect41);
  Version asked;
  std::string error;
  REQUIRE(decode_connect_request(split(kConnect41).payload, asked, error));
  CHECK(asked == v41);
  // PacketClient.cpp sends sSender + sConnectionOptions + 4 = 273 bytes, all zero:
  // the server's own version.
  REQUIRE(decode_connect_request(zeros(273), asked, error));
  CHECK(asked == Version{});
}

TEST_CASE("NatNet server info decodes from the sSender_Server bytes", "[natnet]") {
  ServerInfo info;
  std::string error;
  REQUIRE(decode_server_info(split(kServerInfo).payload, info, error));
  CHECK(info.application_name == "Motive");
  CHECK(info.application_version == Version{3, 1, 0, 0});
  CHECK(info.natnet_version == v41);
  CHECK(info.high_res_clock_frequency_hz == 10'000'000u);
  CHECK(info.data_port == 1511);
  CHECK(info.is_multicast);
  CHECK(info.multicast_group == std::array<std::uint8_t, 4>{239, 255, 42, 99});
  CHECK(encode_message(MessageId::server_info, encode_server_info(info)) == kServerInfo);

  const auto payload = split(kServerInfo).payload;
  REQUIRE_FALSE(decode_server_info(payload.first(264), info, error));
  CHECK(error.find("NatNet 4.1.0.0") != std::string::npos);  // says what the bare sSender was
  Bytes unterminated(payload.begin(), payload.end());
  std::fill(unterminated.begin(), unterminated.begin() + 256, 'x');
  CHECK_FALSE(decode_server_info(unterminated, info, error));
}

TEST_CASE("NatNet 3.0 frame of data decodes from hand-written bytes", "[natnet]") {
  for (const Version& v : {v30, v31}) {
    FrameOfData f;
    std::string error;
    INFO(to_string(v) << ": " << error);
    REQUIRE(decode_frame_of_data(split(kFrame30).payload, v, f, error));
    check_fixture_frame(f);
    CHECK_FALSE(f.has_precision_timestamp);
    CHECK(encode_message(MessageId::frame_of_data, encode_frame_of_data(f, v)) == kFrame30);
  }
}

TEST_CASE("NatNet 4.1 frame of data decodes from hand-written bytes", "[natnet]") {
  FrameOfData f;
  std::string error;
  INFO(error);
  REQUIRE(decode_frame_of_data(split(kFrame41).payload, v41, f, error));
  check_fixture_frame(f);
  CHECK(f.has_precision_timestamp);
  CHECK(f.precision_timestamp_s == 60u);
  CHECK(f.precision_timestamp_fraction == 7u);
  CHECK(encode_message(MessageId::frame_of_data, encode_frame_of_data(f, v41)) == kFrame41);
}

TEST_CASE("NatNet frames are read with the version they were sent in", "[natnet]") {
  FrameOfData f;
  std::string error;
  // 3.0 bytes read as 4.1: the marker set count's next int32 is taken as a byte count.
  CHECK_FALSE(decode_frame_of_data(split(kFrame30).payload, v41, f, error));
  CHECK_FALSE(decode_frame_of_data(split(kFrame41).payload, v30, f, error));
  // 4.0 has the precision timestamp but no byte counts: 3.0 bytes lack 8 bytes.
  CHECK_FALSE(decode_frame_of_data(split(kFrame30).payload, v40, f, error));
  CHECK_FALSE(decode_frame_of_data(split(kFrame30).payload, Version{2, 9, 0, 0}, f, error));
  CHECK(error.find("not supported") != std::string::npos);
}

TEST_CASE("NatNet model definitions decode from hand-written bytes", "[natnet]") {
  for (const auto& [v, bytes] : {std::pair{v30, kModelDef30}, std::pair{v41, kModelDef41}}) {
    ModelDefinitions d;
    std::string error;
    INFO(to_string(v) << ": " << error);
    REQUIRE(decode_model_definitions(split(bytes).payload, v, d, error));
    REQUIRE(d.marker_sets.size() == 1);
    CHECK(d.marker_sets[0].name == "Sub");
    CHECK(d.marker_sets[0].marker_names == std::vector<std::string>{"LKNE", "RKNE"});
    REQUIRE(d.rigid_bodies.size() == 1);
    const auto& rb = d.rigid_bodies[0];
    CHECK(rb.name == "RB");
    CHECK(rb.id == 7);
    CHECK(rb.parent_id == -1);
    CHECK(rb.offset_m == Point3f{1.f, 2.f, 3.f});
    REQUIRE(rb.markers.size() == 1);
    CHECK(rb.markers[0].offset_m == Point3f{0.5f, 0.5f, 0.5f});
    CHECK(rb.markers[0].active_label == 5);
    CHECK(rb.markers[0].name == (v.major >= 4 ? "M1" : ""));
    CHECK(encode_message(MessageId::model_def, encode_model_definitions(d, v)) == bytes);
  }
}

TEST_CASE("NatNet messages round-trip in 3.0, 3.1, 4.0 and 4.1", "[natnet]") {
  for (const Version& v : {v30, v31, v40, v41}) {
    INFO(to_string(v));
    const FrameOfData sent = rich_frame(v);
    FrameOfData got;
    got.marker_sets = {{"stale", {{1, 1, 1}}}};  // reused frames are overwritten
    std::string error;
    REQUIRE(decode_frame_of_data(encode_frame_of_data(sent, v), v, got, error));
    require_same(got, sent);

    const ModelDefinitions defs = rich_defs(v);
    ModelDefinitions back;
    REQUIRE(decode_model_definitions(encode_model_definitions(defs, v), v, back, error));
    CHECK(back.marker_sets == defs.marker_sets);
    CHECK(back.rigid_bodies == defs.rigid_bodies);
    CHECK(back.skeletons == defs.skeletons);
  }
}

TEST_CASE("NatNet: every truncation and every extra byte is an error", "[natnet]") {
  struct Case {
    const char* what;
    Bytes payload;
    Version v;
  };
  std::vector<Case> cases = {
      {"frame 3.0", Bytes(kFrame30.begin() + 4, kFrame30.end()), v30},
      {"frame 4.1", Bytes(kFrame41.begin() + 4, kFrame41.end()), v41},
      {"model 3.0", Bytes(kModelDef30.begin() + 4, kModelDef30.end()), v30},
      {"model 4.1", Bytes(kModelDef41.begin() + 4, kModelDef41.end()), v41},
      {"server info", Bytes(kServerInfo.begin() + 4, kServerInfo.end()), v41},
  };
  for (const Version& v : {v30, v40, v41}) {
    cases.push_back({"rich frame", encode_frame_of_data(rich_frame(v), v), v});
    cases.push_back({"rich model", encode_model_definitions(rich_defs(v), v), v});
  }
  auto decode = [](const Case& c, std::span<const std::uint8_t> bytes, std::string& error) {
    const std::string what = c.what;
    if (what.starts_with("frame") || what == "rich frame") {
      FrameOfData f;
      return decode_frame_of_data(bytes, c.v, f, error);
    }
    if (what == "server info") {
      ServerInfo s;
      return decode_server_info(bytes, s, error);
    }
    ModelDefinitions d;
    return decode_model_definitions(bytes, c.v, d, error);
  };
  for (const Case& c : cases) {
    INFO(c.what << " NatNet " << to_string(c.v));
    std::string error;
    REQUIRE(decode(c, c.payload, error));
    for (std::size_t n = 0; n < c.payload.size(); ++n) {
      INFO("truncated to " << n << " of " << c.payload.size() << " bytes");
      error.clear();
      CHECK_FALSE(decode(c, std::span(c.payload).first(n), error));
      CHECK_FALSE(error.empty());
    }
    Bytes longer = c.payload;
    longer.push_back(0);
    error.clear();
    CHECK_FALSE(decode(c, longer, error));
    CHECK_FALSE(error.empty());
  }
}

TEST_CASE("NatNet: hostile counts and byte counts are errors", "[natnet]") {
  Bytes payload(kFrame30.begin() + 4, kFrame30.end());
  FrameOfData f;
  std::string error;
  Bytes huge = payload;
  huge[4] = 0xFF, huge[5] = 0xFF, huge[6] = 0xFF, huge[7] = 0x7F;  // marker set count 2^31-1
  CHECK_FALSE(decode_frame_of_data(huge, v30, f, error));
  CHECK(error.find("does not fit") != std::string::npos);
  Bytes negative = payload;
  negative[7] = 0x80;  // marker set count < 0
  CHECK_FALSE(decode_frame_of_data(negative, v30, f, error));
  CHECK(error.find("negative") != std::string::npos);

  Bytes wrong_count(kFrame41.begin() + 4, kFrame41.end());
  wrong_count[8] = 0x1F;  // marker sets' byte count 31 instead of 32
  CHECK_FALSE(decode_frame_of_data(wrong_count, v41, f, error));
  CHECK(error.find("byte count") != std::string::npos);

  Bytes unknown_type(kModelDef30.begin() + 4, kModelDef30.end());
  unknown_type[4] = 0x09;  // description type 9 has no layout
  ModelDefinitions d;
  CHECK_FALSE(decode_model_definitions(unknown_type, v30, d, error));
  CHECK(error.find("unknown description type") != std::string::npos);
  // NatNet 4.1 gives each description a byte count: an unknown type is skipped by it.
  Bytes unknown41(kModelDef41.begin() + 4, kModelDef41.end());
  unknown41[4] = 0x09;
  REQUIRE(decode_model_definitions(unknown41, v41, d, error));
  CHECK(d.marker_sets.empty());
  CHECK(d.skipped == 1);
  CHECK(d.rigid_bodies.size() == 1);
}

TEST_CASE("NatNet marker names: Subject:Marker", "[natnet]") {
  const MarkerSetDescription set{"subject01", {"LASI", "other:RASI"}};
  CHECK(qualified_marker_names(set) == std::vector<std::string>{"subject01:LASI", "other:RASI"});
}
