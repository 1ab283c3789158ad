// The QTM RT protocol codec (src/bridges/qtm) against byte fixtures written
// by hand from Qualisys's protocol documentation
// (https://docs.qualisys.com/qtm-rt-protocol/, source
// github.com/qualisys/Real-Time-Protocol-Documentation client/index.md),
// not against our own encoder: section names are quoted beside each fixture.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"

using namespace fabrik::qtm;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr std::size_t kMax = 1 << 20;

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
Bytes ascii(std::string_view s, bool nul) {
  Bytes b(s.begin(), s.end());
  if (nul) b.push_back(0);
  return b;
}

PacketView whole(const Bytes& b, ByteOrder order) {
  PacketView v;
  REQUIRE(read_packet(b, order, kMax, v) == Status::ok);
  return v;
}

// "Error packet": Size 31 (8 header + 23 data), Type 0, "Command not supported." NUL.
const Bytes kErrorLittle = cat({{0x1F, 0, 0, 0, 0, 0, 0, 0}, ascii("Command not supported.", true)});
const Bytes kErrorBig = cat({{0, 0, 0, 0x1F, 0, 0, 0, 0}, ascii("Command not supported.", true)});

// "Command / Command Response packet": Size 20 (8 + 12), Type 1, "Version 1.2" NUL.
const Bytes kVersionCommandLittle = cat({{0x14, 0, 0, 0, 1, 0, 0, 0}, ascii("Version 1.2", true)});

// "No More Data packet": Size 8 (only the header), Type 4.
const Bytes kNoMoreDataBig = {0, 0, 0, 8, 0, 0, 0, 4};

// "Event packet": Size 9, Type 6, one byte: 12 = QTM Shutting Down ("Events").
const Bytes kShuttingDownLittle = {9, 0, 0, 0, 6, 0, 0, 0, 12};

// "Data packet" with one "3D component" (type 1), little endian:
//   header:  Size 64 = 8 + 16 frame header + 40 component, Type 3
//   frame:   Timestamp 1 000 000 us (u64 0x0F4240), Frame Number 42, Component Count 1
//   3D:      Component Size 40 = 8 + 4 + 2 + 2 + 2 markers * 12, Type 1,
//            Marker Count 2, 2D Drop Rate 5, 2D Out Of Sync Rate 7,
//            marker 1 (1.0, 2.0, 3.0) = 0x3F800000 0x40000000 0x40400000,
//            marker 2 not seen: "all their 32 bits set" = 0xFFFFFFFF x 3.
const Bytes kData3dLittle = {
    0x40, 0, 0, 0, 3, 0, 0, 0,                      // Size 64, Type 3
    0x40, 0x42, 0x0F, 0, 0, 0, 0, 0,                // Timestamp 1 000 000
    42, 0, 0, 0, 1, 0, 0, 0,                        // Frame Number 42, Component Count 1
    40, 0, 0, 0, 1, 0, 0, 0,                        // Component Size 40, Type 1 (3D)
    2, 0, 0, 0, 5, 0, 7, 0,                         // Marker Count 2, Drop 5, Out Of Sync 7
    0, 0, 0x80, 0x3F, 0, 0, 0, 0x40, 0, 0, 0x40, 0x40,  // 1.0 2.0 3.0
    0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};  // not seen
// The same packet big endian (port base + 2, "IP port numbers").
const Bytes kData3dBig = {
    0, 0, 0, 0x40, 0, 0, 0, 3,
    0, 0, 0, 0, 0, 0x0F, 0x42, 0x40,
    0, 0, 0, 42, 0, 0, 0, 1,
    0, 0, 0, 40, 0, 0, 0, 1,
    0, 0, 0, 2, 0, 5, 0, 7,
    0x3F, 0x80, 0, 0, 0x40, 0, 0, 0, 0x40, 0x40, 0, 0,
    0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};

// Two components, little endian: a "6DOF component" (type 5) with Body Count
// 0 (Size 16 = 8 + 4 + 2 + 2), which we skip by its size, then a "3D no
// labels component" (type 2) with one marker (-1.5, 0.5, 100.0) = 0xBFC00000
// 0x3F000000 0x42C80000 and ID 7 (Size 32 = 8 + 8 + 16).
// Packet Size 8 + 16 + 16 + 32 = 72; Timestamp 0, Frame Number 1, Count 2.
const Bytes kDataSkipAndNoLabelsLittle = {
    72, 0, 0, 0, 3, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0,
    1, 0, 0, 0, 2, 0, 0, 0,
    16, 0, 0, 0, 5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,  // 6D: 0 bodies, rates 0
    32, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 3, 0, 4, 0,  // 3D no labels: 1 marker, rates 3 4
    0, 0, 0xC0, 0xBF, 0, 0, 0, 0x3F, 0, 0, 0xC8, 0x42, 7, 0, 0, 0};

// "3D XML parameters" example (threed_xml_example.md), version 1.12.
const std::string kXml3dExample = R"(<QTM_Parameters_Ver_1.12>
    <The_3D>
        <AxisUpwards>+Z</AxisUpwards>
        <CalibrationTime>2011.09.23 11:23:11</CalibrationTime>
        <Labels>2</Labels>
        <Label>
             <Name>th12</Name>
             <RGBColor>ff00ff</RGBColor>
        </Label>
        <Label>
             <Name>r_asis</Name>
             <RGBColor>00ffff</RGBColor>
        </Label>
        <Bones>
             <Bone From="fromName" To="toName" Color="ffff00" />
        </Bones>
    </The_3D>
</QTM_Parameters_Ver_1.12>)";

}  // namespace

TEST_CASE("qtm: the documented error packet decodes in both byte orders", "[qtm]") {
  for (const auto& [bytes, order] : {std::pair{kErrorLittle, ByteOrder::little}, {kErrorBig, ByteOrder::big}}) {
    const PacketView p = whole(bytes, order);
    CHECK(p.type() == PacketType::error);
    std::string_view text;
    REQUIRE(read_string(p, PacketType::error, text) == Status::ok);
    CHECK(text == "Command not supported.");
    CHECK(read_string(p, PacketType::command, text) == Status::wrong_type);
  }
  // The size field read in the other byte order is 0x1F000000: above any sane maximum.
  PacketView p;
  CHECK(read_packet(kErrorLittle, ByteOrder::big, kMax, p) == Status::too_large);
}

TEST_CASE("qtm: the Version command is encoded byte for byte as documented", "[qtm]") {
  Bytes out;
  write_command_packet("Version 1.2", ByteOrder::little, out);
  CHECK(out == kVersionCommandLittle);
  CHECK(version_command({1, 2}) == "Version 1.2");
  CHECK(version_command({1, 19}) == "Version 1.19");
  // Clients may omit the NUL ("NULL-termination is optional for command strings").
  const Bytes no_nul = cat({{0x13, 0, 0, 0, 1, 0, 0, 0}, ascii("Version 1.2", false)});
  std::string_view text;
  REQUIRE(read_string(whole(no_nul, ByteOrder::little), PacketType::command, text) == Status::ok);
  CHECK(text == "Version 1.2");
  // Bytes after the NUL other than NULs are not a string packet.
  const Bytes junk = cat({{0x15, 0, 0, 0, 1, 0, 0, 0}, ascii("Version 1.2", true), {'x'}});
  CHECK(read_string(whole(junk, ByteOrder::little), PacketType::command, text) == Status::malformed);
}

TEST_CASE("qtm: commands fabrikd sends and the replies it reads", "[qtm]") {
  CHECK(byte_order_command() == "ByteOrder");
  CHECK(get_parameters_3d_command() == "GetParameters 3D");
  CHECK(stream_frames_command({1}, Components::labelled_3d) == "StreamFrames AllFrames 3D");
  CHECK(stream_frames_command({4}, Components::labelled_3d) == "StreamFrames FrequencyDivisor:4 3D");
  CHECK(stream_frames_command({1}, Components::labelled_and_unlabelled_3d) ==
        "StreamFrames AllFrames 3D 3DNoLabels");
  CHECK(stream_stop_command() == "StreamFrames Stop");

  // "Version": "Version set to 1.12" or "Version is 1.12"; "Version NOT supported".
  CHECK(parse_version_reply("Version set to 1.12") == ProtocolVersion{1, 12});
  CHECK(parse_version_reply("Version is 1.19") == ProtocolVersion{1, 19});
  CHECK_FALSE(parse_version_reply("Version NOT supported"));
  CHECK_FALSE(parse_version_reply("Version set to 1."));
  CHECK_FALSE(parse_version_reply("Version set to x.2"));
  // "ByteOrder": "Byte order is little endian" or "Byte order is big endian".
  CHECK(parse_byte_order_reply("Byte order is little endian") == ByteOrder::little);
  CHECK(parse_byte_order_reply("Byte order is big endian") == ByteOrder::big);
  CHECK_FALSE(parse_byte_order_reply("Byte order is middle endian"));
  // "Connecting": the welcome string.
  CHECK(is_welcome("QTM RT Interface connected."));
  CHECK_FALSE(is_welcome("Connection refused. Max number of clients reached."));
  // Ports: base + 1 little endian, base + 2 big endian.
  CHECK(port_for(ByteOrder::little) == 22223);
  CHECK(port_for(ByteOrder::big) == 22224);
}

TEST_CASE("qtm: a server reads the commands back, case insensitive", "[qtm]") {
  const ParsedCommand v = parse_command("version 1.19");
  CHECK(v.kind == ParsedCommand::Kind::version);
  CHECK(v.version == ProtocolVersion{1, 19});
  CHECK(parse_command("Version").kind == ParsedCommand::Kind::version);
  CHECK_FALSE(parse_command("Version").version);
  CHECK(parse_command("BYTEORDER").kind == ParsedCommand::Kind::byte_order);
  const ParsedCommand g = parse_command(get_parameters_3d_command());
  CHECK((g.kind == ParsedCommand::Kind::get_parameters && g.wants_3d));
  CHECK_FALSE(parse_command("GetParameters General").wants_3d);
  const ParsedCommand s = parse_command(stream_frames_command({3}, Components::labelled_and_unlabelled_3d));
  CHECK(s.kind == ParsedCommand::Kind::stream_frames);
  CHECK(s.rate_valid);
  CHECK(s.rate.frequency_divisor == 3);
  CHECK((s.wants_3d && s.wants_3d_no_labels));
  CHECK(parse_command("streamframes allframes 3d").rate.frequency_divisor == 1);
  CHECK_FALSE(parse_command("StreamFrames FrequencyDivisor:0 3D").rate_valid);
  CHECK_FALSE(parse_command("StreamFrames 3D").rate_valid);
  CHECK(parse_command("StreamFrames Stop").kind == ParsedCommand::Kind::stream_stop);
  CHECK(parse_command("Start").kind == ParsedCommand::Kind::other);
  CHECK(parse_command("").kind == ParsedCommand::Kind::other);
}

TEST_CASE("qtm: the no-more-data and event packets", "[qtm]") {
  const PacketView none = whole(kNoMoreDataBig, ByteOrder::big);
  CHECK(none.type() == PacketType::no_more_data);
  CHECK(none.data.empty());

  Event e{};
  REQUIRE(read_event(whole(kShuttingDownLittle, ByteOrder::little), e) == Status::ok);
  CHECK(e == Event::qtm_shutting_down);
  Bytes out;
  write_event_packet(Event::qtm_shutting_down, ByteOrder::little, out);
  CHECK(out == kShuttingDownLittle);
  // Every documented id, and the ids outside 1..16 refused.
  for (int id = 0; id < 256; ++id) {
    const Bytes b = {9, 0, 0, 0, 6, 0, 0, 0, static_cast<std::uint8_t>(id)};
    const Status s = read_event(whole(b, ByteOrder::little), e);
    CHECK((s == Status::ok) == (id >= 1 && id <= 16));
  }
  const Bytes two = {10, 0, 0, 0, 6, 0, 0, 0, 1, 1};
  CHECK(read_event(whole(two, ByteOrder::little), e) == Status::malformed);
  const Bytes none_at_all = {8, 0, 0, 0, 6, 0, 0, 0};
  CHECK(read_event(whole(none_at_all, ByteOrder::little), e) == Status::truncated);
  CHECK(read_event(whole(kErrorLittle, ByteOrder::little), e) == Status::wrong_type);
}

TEST_CASE("qtm: the documented 3D data packet decodes in both byte orders", "[qtm]") {
  for (const auto& [bytes, order] : {std::pair{kData3dLittle, ByteOrder::little}, {kData3dBig, ByteOrder::big}}) {
    DataFrame f;
    REQUIRE(read_data(whole(bytes, order), order, 1000, f) == Status::ok);
    CHECK(f.timestamp_us == 1000000);
    CHECK(f.frame_number == 42);
    CHECK(f.component_count == 1);
    CHECK(f.has_3d);
    CHECK_FALSE(f.has_3d_no_labels);
    CHECK(f.drop_rate_2d_permille == 5);
    CHECK(f.out_of_sync_rate_2d_permille == 7);
    REQUIRE(f.labelled_p_qtm_mm.size() == 2);
    CHECK(f.labelled_p_qtm_mm[0] == Eigen::Vector3f(1.0f, 2.0f, 3.0f));
    CHECK(f.labelled_p_qtm_mm[1].array().isNaN().all());
    // Our encoder writes exactly the documented bytes (NaN as all bits set).
    Bytes again;
    write_data_packet(f, order, again);
    CHECK(again == bytes);
  }
}

TEST_CASE("qtm: other components are skipped by their size, 3D no labels read", "[qtm]") {
  DataFrame f;
  REQUIRE(read_data(whole(kDataSkipAndNoLabelsLittle, ByteOrder::little), ByteOrder::little, 1000, f) ==
          Status::ok);
  CHECK(f.frame_number == 1);
  CHECK(f.components_skipped == 1);
  CHECK_FALSE(f.has_3d);
  REQUIRE(f.has_3d_no_labels);
  REQUIRE(f.unlabelled.size() == 1);
  CHECK(f.unlabelled[0].p_qtm_mm == Eigen::Vector3f(-1.5f, 0.5f, 100.0f));
  CHECK(f.unlabelled[0].id == 7);
  // Without a 3D component the rates are the 3D no labels component's, not a previous frame's.
  CHECK(f.drop_rate_2d_permille == 3);
  CHECK(f.out_of_sync_rate_2d_permille == 4);
  REQUIRE(read_data(whole(kData3dLittle, ByteOrder::little), ByteOrder::little, 1000, f) == Status::ok);
  REQUIRE(read_data(whole(kDataSkipAndNoLabelsLittle, ByteOrder::little), ByteOrder::little, 1000, f) ==
          Status::ok);
  CHECK(f.drop_rate_2d_permille == 3);
}

TEST_CASE("qtm: every truncation of a valid packet is an error, never a crash", "[qtm]") {
  const std::vector<std::pair<Bytes, ByteOrder>> packets = {
      {kData3dLittle, ByteOrder::little}, {kData3dBig, ByteOrder::big},
      {kDataSkipAndNoLabelsLittle, ByteOrder::little}, {kErrorLittle, ByteOrder::little},
      {kShuttingDownLittle, ByteOrder::little}, {kNoMoreDataBig, ByteOrder::big}};
  for (const auto& [bytes, order] : packets) {
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      const std::span<const std::uint8_t> prefix(bytes.data(), n);
      PacketView p;
      CHECK(read_packet(prefix, order, kMax, p) == Status::truncated);
      // A splitter holding the prefix waits for more.
      PacketSplitter splitter(order, kMax);
      splitter.feed(prefix);
      CHECK(splitter.next(p) == Status::need_more);
    }
    // The packet's data cut short (a lying Size would present it so): the data decoder refuses.
    const PacketView full = whole(bytes, order);
    if (full.type() != PacketType::data) continue;
    for (std::size_t n = 0; n < full.data.size(); ++n) {
      PacketView cut{full.raw_type, full.data.first(n)};
      DataFrame f;
      CHECK(read_data(cut, order, 1000, f) != Status::ok);
    }
  }
}

TEST_CASE("qtm: sizes and counts that disagree are refused", "[qtm]") {
  PacketView p;
  Bytes b = kData3dLittle;
  b[0] = 7;  // Size below the header
  CHECK(read_packet(b, ByteOrder::little, kMax, p) == Status::too_small);
  CHECK(read_packet(kData3dLittle, ByteOrder::little, 63, p) == Status::too_large);
  Bytes longer = kData3dLittle;
  longer.push_back(0);
  CHECK(read_packet(longer, ByteOrder::little, kMax, p) == Status::malformed);

  DataFrame f;
  auto decode = [&](const Bytes& bytes, std::size_t max_markers = 1000) {
    return read_data(whole(bytes, ByteOrder::little), ByteOrder::little, max_markers, f);
  };
  CHECK(decode(kData3dLittle, 1) == Status::too_many);
  Bytes count = kData3dLittle;
  count[32] = 3;  // Marker Count 3 in a component sized for 2
  CHECK(decode(count) == Status::malformed);
  Bytes comp_size = kData3dLittle;
  comp_size[24] = 7;  // Component Size below its own header
  CHECK(decode(comp_size) == Status::malformed);
  Bytes comps = kData3dLittle;
  comps[20] = 2;  // Component Count 2, one present
  CHECK(decode(comps) == Status::truncated);
  Bytes zero = kData3dLittle;
  zero[20] = 0;  // Component Count 0: the 3D component becomes trailing bytes
  CHECK(decode(zero) == Status::malformed);
  CHECK(read_data(whole(kErrorLittle, ByteOrder::little), ByteOrder::little, 10, f) == Status::wrong_type);
  // Two 3D components in one frame are ambiguous.
  Bytes twice = kData3dLittle;
  twice.insert(twice.end(), kData3dLittle.begin() + 24, kData3dLittle.end());
  twice[0] = static_cast<std::uint8_t>(twice.size());
  twice[20] = 2;
  CHECK(decode(twice) == Status::malformed);
}

TEST_CASE("qtm: the splitter yields whole packets from any chunking of a stream", "[qtm]") {
  const Bytes stream = cat({kErrorLittle, kData3dLittle, kShuttingDownLittle, kDataSkipAndNoLabelsLittle,
                            kVersionCommandLittle});
  const std::vector<Bytes> expected = {kErrorLittle, kData3dLittle, kShuttingDownLittle,
                                       kDataSkipAndNoLabelsLittle, kVersionCommandLittle};
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    PacketSplitter splitter(ByteOrder::little, 4096);
    std::vector<Bytes> got;
    std::size_t at = 0;
    while (at < stream.size()) {
      // Chunk sizes 1..17 bytes: headers and fields split everywhere.
      const std::size_t n = std::min<std::size_t>(1 + rng() % 17, stream.size() - at);
      splitter.feed({stream.data() + at, n});
      at += n;
      PacketView p;
      Status s;
      while ((s = splitter.next(p)) == Status::ok) {
        Bytes whole_packet;
        write_packet(static_cast<PacketType>(p.raw_type), p.data, ByteOrder::little, whole_packet);
        got.push_back(whole_packet);
      }
      REQUIRE(s == Status::need_more);
    }
    REQUIRE(got == expected);
    CHECK(splitter.buffered_bytes() == 0);
  }
}

TEST_CASE("qtm: a framing error poisons the splitter until reset", "[qtm]") {
  PacketSplitter splitter(ByteOrder::little, 64);
  PacketView p;
  splitter.feed(kErrorLittle);
  REQUIRE(splitter.next(p) == Status::ok);
  Bytes huge = {0x41, 0, 0, 0, 3, 0, 0, 0};  // Size 65 > 64
  splitter.feed(huge);
  CHECK(splitter.next(p) == Status::too_large);
  splitter.feed(kShuttingDownLittle);
  CHECK(splitter.next(p) == Status::too_large);  // the framing is lost: no guessing
  CHECK(splitter.buffered_bytes() == huge.size());  // and nothing more is buffered
  splitter.reset();
  splitter.feed(kShuttingDownLittle);
  CHECK(splitter.next(p) == Status::ok);
  splitter.feed(Bytes{3, 0, 0, 0, 1, 0, 0, 0});  // Size 3 < 8
  CHECK(splitter.next(p) == Status::too_small);
}

TEST_CASE("qtm: data packets round trip through the encoder, both byte orders", "[qtm]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coord(-5000.0f, 5000.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  DataFrame decoded;
  Bytes bytes;
  for (int trial = 0; trial < 100; ++trial) {
    DataFrame f;
    f.timestamp_us = (static_cast<std::uint64_t>(rng()) << 32) | rng();
    f.frame_number = static_cast<std::uint32_t>(rng());
    f.has_3d = trial % 3 != 0;
    f.has_3d_no_labels = trial % 2 == 0;
    f.drop_rate_2d_permille = static_cast<std::uint16_t>(rng() % 1001);
    f.out_of_sync_rate_2d_permille = static_cast<std::uint16_t>(rng() % 1001);
    if (f.has_3d)
      for (std::size_t i = rng() % 60; i > 0; --i)
        f.labelled_p_qtm_mm.emplace_back(rng() % 4 == 0 ? Eigen::Vector3f::Constant(nan)
                                                        : Eigen::Vector3f(coord(rng), coord(rng), coord(rng)));
    if (f.has_3d_no_labels)
      for (std::size_t i = rng() % 20; i > 0; --i)
        f.unlabelled.push_back({Eigen::Vector3f(coord(rng), coord(rng), coord(rng)), static_cast<std::uint32_t>(rng())});
    for (ByteOrder order : {ByteOrder::little, ByteOrder::big}) {
      write_data_packet(f, order, bytes);
      REQUIRE(read_data(whole(bytes, order), order, 1000, decoded) == Status::ok);
      CHECK(decoded.timestamp_us == f.timestamp_us);
      CHECK(decoded.frame_number == f.frame_number);
      CHECK(decoded.has_3d == f.has_3d);
      CHECK(decoded.has_3d_no_labels == f.has_3d_no_labels);
      REQUIRE(decoded.labelled_p_qtm_mm.size() == f.labelled_p_qtm_mm.size());
      for (std::size_t i = 0; i < f.labelled_p_qtm_mm.size(); ++i) {
        const Eigen::Vector3f& a = f.labelled_p_qtm_mm[i];
        const Eigen::Vector3f& b = decoded.labelled_p_qtm_mm[i];
        if (std::isnan(a.x())) CHECK(b.array().isNaN().all());
        else CHECK(a == b);
      }
      REQUIRE(decoded.unlabelled.size() == f.unlabelled.size());
      for (std::size_t i = 0; i < f.unlabelled.size(); ++i) {
        CHECK(decoded.unlabelled[i].p_qtm_mm == f.unlabelled[i].p_qtm_mm);
        CHECK(decoded.unlabelled[i].id == f.unlabelled[i].id);
      }
      const bool rates_sent = f.has_3d || f.has_3d_no_labels;
      CHECK(decoded.drop_rate_2d_permille == (rates_sent ? f.drop_rate_2d_permille : 0));
      CHECK(decoded.out_of_sync_rate_2d_permille == (rates_sent ? f.out_of_sync_rate_2d_permille : 0));
    }
  }
}

TEST_CASE("qtm: a reused frame keeps its buffers after warm-up", "[qtm]") {
  DataFrame f;
  REQUIRE(read_data(whole(kData3dLittle, ByteOrder::little), ByteOrder::little, 10, f) == Status::ok);
  const Eigen::Vector3f* buffer = f.labelled_p_qtm_mm.data();
  for (int i = 0; i < 10; ++i) {
    REQUIRE(read_data(whole(kData3dBig, ByteOrder::big), ByteOrder::big, 10, f) == Status::ok);
    CHECK(f.labelled_p_qtm_mm.data() == buffer);
  }
}

TEST_CASE("qtm: the documented 3D parameters XML gives the labels in order", "[qtm]") {
  Parameters3d params;
  std::string error;
  REQUIRE(read_parameters_3d(kXml3dExample, params, error));
  CHECK(params.labels == std::vector<std::string>{"th12", "r_asis"});
  CHECK(params.axis_upwards == "+Z");
  // With an XML declaration, comments, entities and character references.
  const std::string decorated =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- from QTM -->"
      "<QTM_Parameters_Ver_1.19><General><Frequency>100</Frequency></General>"
      "<The_3D><Labels>2</Labels><Label><Name>L&amp;R &#x41;</Name><Trajectory_Type>Measured</Trajectory_Type></Label>"
      "<Label><Name> LASI </Name></Label></The_3D></QTM_Parameters_Ver_1.19>";
  REQUIRE(read_parameters_3d(decorated, params, error));
  CHECK(params.labels == std::vector<std::string>{"L&R A", "LASI"});
  CHECK(params.axis_upwards.empty());
  // No labels at all is a valid, empty list.
  REQUIRE(read_parameters_3d("<QTM_Parameters_Ver_1.19><The_3D><Labels>0</Labels></The_3D></QTM_Parameters_Ver_1.19>",
                             params, error));
  CHECK(params.labels.empty());
}

TEST_CASE("qtm: the 3D parameters reader refuses what it does not know", "[qtm]") {
  Parameters3d params;
  std::string error;
  auto refused = [&](const std::string& xml, std::string_view why) {
    INFO(xml);
    const bool ok = read_parameters_3d(xml, params, error);
    INFO(error);
    CHECK_FALSE(ok);
    CHECK(error.find(why) != std::string::npos);
  };
  const std::string root = "QTM_Parameters_Ver_1.19";
  auto doc = [&](const std::string& inner) { return "<" + root + ">" + inner + "</" + root + ">"; };
  refused(doc("<General/>"), "no The_3D");
  refused(doc("<The_3D><Label><RGBColor>1</RGBColor></Label></The_3D>"), "without a Name");
  refused(doc("<The_3D><Label><Name></Name></Label></The_3D>"), "empty Name");
  refused(doc("<The_3D><Label><Name>a</Name><Name>b</Name></Label></The_3D>"), "two Names");
  refused(doc("<The_3D><Label><Name>a</Name></Label><Label><Name>a</Name></Label></The_3D>"), "twice");
  refused(doc("<The_3D><Labels>3</Labels><Label><Name>a</Name></Label></The_3D>"), "Labels says 3");
  refused(doc("<The_3D><Labels>two</Labels></The_3D>"), "not a count");
  refused(doc("<The_3D></The_3D><The_3D></The_3D>"), "more than one The_3D");
  refused(doc("<The_3D><Label><Name>a</Label></Name></The_3D>"), "does not match");
  refused(doc("<The_3D><Label><Name>&bogus;</Name></Label></The_3D>"), "unknown entity");
  refused(doc("<The_3D><Label><Name>&#0;</Name></Label></The_3D>"), "character reference");
  refused(doc("<The_3D><Label><Name><![CDATA[a]]></Name></Label></The_3D>"), "CDATA");
  refused("<!DOCTYPE x [<!ENTITY a \"b\">]>" + doc("<The_3D/>"), "DOCTYPE");
  refused(doc("<The_3D/>") + "<x/>", "more than one root");
  refused("<Other><The_3D/></Other>", "root element");
  refused(doc("<The_3D a=b/>"), "unquoted");
  refused("", "no XML element");
  std::string deep;
  for (int i = 0; i < 40; ++i) deep += "<a>";
  for (int i = 0; i < 40; ++i) deep += "</a>";
  refused(doc(deep), "deeper");
  XmlLimits small;
  small.max_bytes = 100;
  CHECK_FALSE(read_parameters_3d(kXml3dExample, params, error, small));
  small = {};
  small.max_labels = 1;
  CHECK_FALSE(read_parameters_3d(kXml3dExample, params, error, small));
  CHECK(error.find("limit") != std::string::npos);
  // Every prefix of the documented example is refused: the root never closes.
  for (std::size_t n = 0; n < kXml3dExample.size(); ++n)
    CHECK_FALSE(read_parameters_3d(std::string_view(kXml3dExample).substr(0, n), params, error));
}

TEST_CASE("qtm: the simulator's 3D parameters XML reads back", "[qtm]") {
  Parameters3d params{{"LASI", "R&D <1>", "quote\"'s", "Ünïcode"}, "+Y"};
  const std::string xml = write_parameters_3d(params, "1.19");
  CHECK(xml.rfind("<QTM_Parameters_Ver_1.19>", 0) == 0);
  Parameters3d back;
  std::string error;
  REQUIRE(read_parameters_3d(xml, back, error));
  CHECK(back.labels == params.labels);
  CHECK(back.axis_upwards == "+Y");
  // Sent as an XML packet (type 2) with its NUL, and read back as a string.
  Bytes packet;
  write_string_packet(PacketType::xml, xml, ByteOrder::little, packet);
  std::string_view text;
  REQUIRE(read_string(whole(packet, ByteOrder::little), PacketType::xml, text) == Status::ok);
  CHECK(text == xml);
}
