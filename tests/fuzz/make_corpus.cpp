// Writes the fuzz targets' seed corpora (tests/fuzz/corpus/<target>/) from
// the project's own files and writers: marker frames from the wire encoder,
// TRC and C3D files from the io writers, configs, models and templates from
// config/ re-serialised and varied. Deterministic, so rerunning it changes
// nothing; files it does not write (regression seeds) are left alone.
//   fabrik_fuzz_corpus SOURCE_DIR OUT_DIR
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bridges/qtm/commands.hpp"
#include "bridges/qtm/data_packet.hpp"
#include "bridges/qtm/packet.hpp"
#include "bridges/qtm/parameters_xml.hpp"
#include "bridges/natnet_protocol.hpp"
#include "io/marker_trial.hpp"
#include "transport/marker_codec.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

fs::path g_out;

void write(const std::string& target, const std::string& name, const std::string& bytes) {
  const fs::path dir = g_out / target;
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary) << bytes;
}

json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  return json::parse(in);
}

void marker_frames(const json& fullbody) {
  // Model marker names as the default config tracks them, plus names the model does not know.
  std::vector<std::string> names;
  for (const json& segment : fullbody["segments"])
    if (segment.contains("markers"))
      for (auto it = segment["markers"].begin(); it != segment["markers"].end(); ++it)
        names.push_back(it.key());
  const std::vector<std::string> few = {names.at(0), names.at(1), names.at(2), "Subject:RKNE_long",
                                        "x"};
  auto positions = [](std::size_t n) {
    std::vector<Eigen::Vector3d> p_m(n);
    for (std::size_t i = 0; i < n; ++i)
      p_m[i] = Eigen::Vector3d(0.1 * static_cast<double>(i), 1.0 - 0.01 * static_cast<double>(i),
                               -0.25 + 0.003 * static_cast<double>(i));
    return p_m;
  };
  const double time_s = 12.34, stamp_us = 1.7e15;
  for (auto encoding : {fabrik::wire::PayloadEncoding::json, fabrik::wire::PayloadEncoding::msgpack}) {
    const std::string tag = encoding == fabrik::wire::PayloadEncoding::json ? "json" : "msgpack";
    std::string out;
    std::vector<std::uint8_t> visible(few.size(), 1);
    visible[1] = 0;
    fabrik::wire::encode_marker_frame(7, &time_s, few, positions(few.size()), visible, "mm",
                                      encoding, out);
    write("marker_decoder", tag + "_few_mm", out);
    fabrik::wire::encode_marker_frame(8, nullptr, few, positions(few.size()), visible, "m", encoding,
                                      out, &stamp_us);
    write("marker_decoder", tag + "_few_m_stamp", out);
    fabrik::wire::encode_marker_frame(18446744073709551615ull, &time_s, {}, {}, {}, "mm", encoding,
                                      out);
    write("marker_decoder", tag + "_no_markers", out);
    std::vector<std::uint8_t> all_visible(names.size(), 1);
    fabrik::wire::encode_marker_frame(9, &time_s, names, positions(names.size()), all_visible, "mm",
                                      encoding, out, &stamp_us);
    write("marker_decoder", tag + "_fullbody", out);
    if (encoding == fabrik::wire::PayloadEncoding::json) write("json_reader", "frame_fullbody", out);
  }
  // The contract's example frame, and corners the JSON grammar cares about.
  write("marker_decoder", "json_contract_example",
        R"({"frame": 1042, "time": 17.366, "units": "mm",)"
        "\n"
        R"( "markers": {"RASI": [617.2, 1055.3, 170.8], "LASI": null}})");
  write("json_reader", "frame_escapes",
        R"({"frame":1,"markers":{"\u00e9\ud83d\ude00\"\\\/\b\f\n\r\t":[-0,1E+2,-1.5e-3]}})");
  write("json_reader", "literals", "\xEF\xBB\xBF [true,false,null,{},[],\"\",18446744073709551616]");
}

void trials() {
  fabrik::io::MarkerTrial trial;
  trial.labels = {"RASI", "LASI", "Subject:RKNE"};
  trial.rate_hz = 100.0;
  trial.first_frame = 3;
  for (int f = 0; f < 4; ++f)
    for (int m = 0; m < 3; ++m)
      trial.positions_m.emplace_back(0.6 + 0.01 * f, 1.05 - 0.1 * m, 0.17 * (m - 1));
  trial.at(2, 1).setConstant(std::nan(""));  // a missing sample
  const fs::path dir = g_out / "trc";
  fs::create_directories(dir);
  fabrik::io::write_trc((dir / "small_mm.trc").string(), trial, "mm");
  fabrik::io::write_trc((dir / "small_m.trc").string(), trial, "m");
  const fs::path c3d = g_out / "c3d";
  fs::create_directories(c3d);
  using P = fabrik::io::C3dProcessor;
  for (auto [processor, name] : {std::pair{P::intel, "intel"}, {P::dec, "dec"}, {P::mips, "mips"}})
    for (bool float_data : {false, true})
      fabrik::io::write_c3d(
          (c3d / (std::string(name) + (float_data ? "_float" : "_int16") + ".c3d")).string(), trial,
          processor, float_data, "mm");
  fabrik::io::write_c3d((c3d / "intel_float_m.c3d").string(), trial, P::intel, true, "m");
}

void configs(const fs::path& config_dir, const json& fullbody, const json& paper_model) {
  const json default_config = read_json(config_dir / "default.json");
  write("daemon_config", "default", default_config.dump());
  json inline_model = default_config;
  inline_model["model"] = fullbody;
  inline_model.erase("targets");
  write("daemon_config", "inline_model", inline_model.dump());
  json varied = default_config;
  varied["targets"] = {{"default", {{"level", 2}, {"weight", 0.5}}},
                       {"markers", {{"STRN", {{"track", false}}},
                                    {"Subject:RWRA", {{"point", "RWRA"}, {"level", 3}}},
                                    {"wrist", {{"point", "r_wrist"}, {"weight", 0.1}}}}}};
  varied["solver"]["segment_fit"] = "paper";
  varied["solver"]["root"] = "fixed";
  varied["input"] = {{"endpoint", "ipc:///tmp/fabrikd.sock"}, {"mode", "connect"}, {"units", "m"}};
  varied["output"] = {{"endpoint", "inproc://poses"}, {"encoding", "msgpack"}, {"units", "m"}};
  varied["occlusion"]["hold_s"] = 0.25;
  write("daemon_config", "varied", varied.dump());

  write("model", "fullbody", fullbody.dump());
  write("model", "paper_upper_body", paper_model.dump(1));
  json in_mm = paper_model;
  in_mm["units"] = "mm";
  in_mm["root_position"] = {0, 950, 0};
  write("model", "paper_upper_body_mm", in_mm.dump());

  for (const char* name : {"gait2354", "vicon_upper_body"})
    write("template", name, read_json(config_dir / "templates" / (std::string(name) + ".json")).dump());
  write("json_reader", "default_config", default_config.dump(2));
}

// QTM RT streams (fuzz_qtm_packet): the first byte picks the byte order
// (bit 0) and the chunk size (bits 1-7); then what a server sends a client:
// welcome, version reply, 3D parameters, frames, an event, no more data, an error.
void qtm_streams() {
  using namespace fabrik::qtm;
  for (const ByteOrder order : {ByteOrder::little, ByteOrder::big}) {
    std::string stream(1, static_cast<char>((order == ByteOrder::big ? 1 : 0) | (6 << 1)));
    std::vector<std::uint8_t> packet;
    auto add = [&] { stream.append(packet.begin(), packet.end()); };
    write_string_packet(PacketType::command, "QTM RT Interface connected.", order, packet);
    add();
    write_string_packet(PacketType::command, "Version set to 1.19", order, packet);
    add();
    write_string_packet(PacketType::xml, write_parameters_3d({{"LASI", "RASI", "L&R"}, "+Z"}, "1.19"),
                        order, packet);
    add();
    DataFrame frame;
    frame.timestamp_us = 1000000;
    frame.frame_number = 42;
    frame.has_3d = frame.has_3d_no_labels = true;
    frame.drop_rate_2d_permille = 5;
    frame.labelled_p_qtm_mm = {{1.0f, 2.0f, 3.0f}, Eigen::Vector3f::Constant(std::nanf("")), {-4.5f, 0.0f, 1e4f}};
    frame.unlabelled = {{{10.0f, 20.0f, 30.0f}, 7}};
    write_data_packet(frame, order, packet);
    add();
    write_event_packet(Event::camera_settings_changed, order, packet);
    add();
    write_packet(PacketType::no_more_data, {}, order, packet);
    add();
    write_string_packet(PacketType::error, "Parse Error", order, packet);
    add();
    write("qtm_packet", order == ByteOrder::big ? "session_big" : "session_little", stream);
  }
}

}  // namespace

// NatNet datagrams from the codec's encoders, one per message kind and version;
// the first byte picks the version in fuzz_natnet_packet (0: 3.0 ... 3: 4.1).
void natnet_packets() {
  namespace nn = fabrik::natnet;
  const nn::Version versions[] = {{3, 0, 0, 0}, {3, 1, 0, 0}, {4, 0, 0, 0}, {4, 1, 0, 0}};
  auto put = [](const std::string& name, std::uint8_t version_index, nn::MessageId id,
                const std::vector<std::uint8_t>& payload) {
    const std::vector<std::uint8_t> datagram = nn::encode_message(id, payload);
    std::string bytes(1, static_cast<char>(version_index));
    bytes.append(datagram.begin(), datagram.end());
    write("natnet_packet", name, bytes);
  };
  for (std::uint8_t i = 0; i < std::size(versions); ++i) {
    const nn::Version& v = versions[i];
    const std::string tag = std::to_string(v.major) + std::to_string(v.minor);
    nn::FrameOfData f;
    f.frame_number = 7;
    f.marker_sets = {{"subject01", {{0.1f, 0.2f, 0.3f}, {0.4f, 0.5f, 0.6f}}}};
    f.other_markers_p_m = {{1.f, 1.f, 1.f}};
    f.rigid_bodies = {{1, {0.f, 1.f, 0.f}, {0.f, 0.f, 0.f, 1.f}, 0.001f, 1}};
    f.skeletons = {{2, {{65537, {0.f, 1.f, 0.f}, {0.f, 0.f, 0.f, 1.f}, 0.f, 1}}}};
    f.labeled_markers = {{65537, {0.1f, 0.2f, 0.3f}, 0.014f, 0, 0.0002f},
                         {65538, {0.f, 0.f, 0.f}, 0.014f, 1, 0.f}};
    f.timestamp_s = 0.01;
    put("frame_" + tag, i, nn::MessageId::frame_of_data, nn::encode_frame_of_data(f, v));
    nn::ModelDefinitions d;
    d.marker_sets = {{"subject01", {"LASI", "RASI"}}};
    d.rigid_bodies = {{"wand", 1, -1, {0.f, 0.f, 0.f}, {{{0.01f, 0.f, 0.f}, 1, "w1"}}}};
    d.skeletons = {{"subject01", 2, {{"Hip", 65537, -1, {0.f, 1.f, 0.f}, {}}}}};
    put("model_" + tag, i, nn::MessageId::model_def, nn::encode_model_definitions(d, v));
  }
  nn::ServerInfo info{"Motive", {3, 1, 0, 0}, {4, 1, 0, 0}, 10'000'000, 1511, true, {239, 255, 42, 99}};
  put("server_info", 3, nn::MessageId::server_info, nn::encode_server_info(info));
  put("connect", 3, nn::MessageId::connect, nn::encode_connect_request({4, 1, 0, 0}));
}

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: fabrik_fuzz_corpus SOURCE_DIR OUT_DIR\n";
    return 2;
  }
  try {
    const fs::path config_dir = fs::path(argv[1]) / "config";
    g_out = argv[2];
    const json fullbody = read_json(config_dir / "models" / "fullbody.json");
    const json paper_model = read_json(config_dir / "models" / "paper_upper_body.json");
    marker_frames(fullbody);
    trials();
    configs(config_dir, fullbody, paper_model);
    qtm_streams();
    natnet_packets();
  } catch (const std::exception& e) {
    std::cerr << "fabrik_fuzz_corpus: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
