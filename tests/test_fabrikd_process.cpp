// The fabrikd executable: exit codes and messages for bad configs, clean
// shutdown on SIGTERM/SIGINT, reload on SIGHUP that survives a bad file.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "process.hpp"
#include "socket_client.hpp"

using namespace fabrik::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kFabrikd = FABRIKD_PATH;

std::filesystem::path temp_dir() {
  auto dir = std::filesystem::temp_directory_path() / ("fabrikd-test-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

std::string write_file(const std::string& name, const std::string& text) {
  const auto path = temp_dir() / name;
  std::ofstream(path) << text;
  return path.string();
}

// A valid config on ipc endpoints of this test's own.
json good_config(const std::string& tag) {
  const std::string base = "ipc://" + (temp_dir() / tag).string();
  return {{"format", "fabrikd-config/1"},
          {"model", "models/fullbody.json"},
          {"input", {{"endpoint", base + "-in"}}},
          {"output", {{"endpoint", base + "-out"}}},
          {"stats_interval_s", 0.1}};
}

}  // namespace

TEST_CASE("fabrikd --version and --help exit 0", "[fabrikd]") {
  Process v({kFabrikd, "--version"});
  CHECK(v.wait(5s) == 0);
  Process h({kFabrikd, "--help"});
  CHECK(h.wait(5s) == 0);
}

TEST_CASE("Bad configs exit with code 2 and name the file, the pointer and the fix", "[fabrikd]") {
  struct Case {
    std::string name, text, expected;
  };
  json unknown_key = good_config("a");
  unknown_key["solver"] = {{"tolerence_mm", 1}};
  json bad_mode = good_config("b");
  bad_mode["input"]["mode"] = "listen";
  json bad_marker = good_config("c");
  bad_marker["targets"] = {{"markers", {{"R.ASIS", {{"level", 2}}}}}};
  json bad_model = good_config("d");
  bad_model["model"] = "no/such/model.json";
  json same_endpoint = good_config("e");
  same_endpoint["output"]["endpoint"] = same_endpoint["input"]["endpoint"];
  json bad_encoding = good_config("f");
  bad_encoding["output"]["encoding"] = "protobuf";
  json bad_endpoint = good_config("g");
  bad_endpoint["input"]["endpoint"] = "127.0.0.1:5555";
  const std::vector<Case> cases = {
      {"syntax.json", "{\"format\": \"fabrikd-config/1\",\n \"model\" }", "line 2"},
      {"unknown_key.json", unknown_key.dump(), "at /solver/tolerence_mm: unknown field"},
      {"bad_mode.json", bad_mode.dump(), "at /input/mode: unknown socket mode 'listen'"},
      {"bad_marker.json", bad_marker.dump(),
       "at /targets/markers/R.ASIS: 'R.ASIS' is not a marker of the model"},
      {"bad_model.json", bad_model.dump(), "at /model: model file"},
      {"same_endpoint.json", same_endpoint.dump(),
       "at /output: input and output use the same endpoint"},
      {"bad_encoding.json", bad_encoding.dump(),
       "at /output/encoding: unknown encoding 'protobuf'"},
      {"bad_endpoint.json", bad_endpoint.dump(),
       "at /input/endpoint: '127.0.0.1:5555' is not a ZeroMQ endpoint"},
  };
  for (const Case& c : cases) {
    const std::string path = write_file(c.name, c.text);
    Process p({kFabrikd, "--config", path});
    CAPTURE(c.name);
    CHECK(p.wait(5s) == 2);
    CHECK_THAT(p.stderr_text(),
               Catch::Contains(path) && Catch::Contains(c.expected) && Catch::Contains("Fix:"));
  }
  Process missing({kFabrikd, "--config", "/nonexistent/fabrikd.json"});
  CHECK(missing.wait(5s) == 2);
  CHECK_THAT(missing.stderr_text(), Catch::Contains("/nonexistent/fabrikd.json"));
}

TEST_CASE("A busy port is a clear setup error with exit code 2", "[fabrikd]") {
  zmq::context_t context;
  zmq::socket_t holder(context, zmq::socket_type::pub);
  holder.bind("tcp://127.0.0.1:*");
  const std::string busy = holder.get(zmq::sockopt::last_endpoint);
  json c = good_config("busy");
  c["input"]["endpoint"] = busy;
  Process p({kFabrikd, "--config", write_file("busy.json", c.dump())});
  CHECK(p.wait(5s) == 2);
  CHECK_THAT(p.stderr_text(), Catch::Contains("cannot bind the input socket to '" + busy + "'"));
}

TEST_CASE("SIGTERM and SIGINT stop fabrikd cleanly within a second", "[fabrikd]") {
  for (int sig : {SIGTERM, SIGINT}) {
    const json c = good_config("sig" + std::to_string(sig));
    Process p({kFabrikd, "--config", write_file("sig.json", c.dump())});
    REQUIRE(p.wait_for_output("markers in on", 5s));
    zmq::context_t context;
    SocketClient client(context, c["input"]["endpoint"], c["output"]["endpoint"]);
    client.handshake();
    p.signal(sig);
    CHECK(p.wait(1s) == 0);
    CHECK_THAT(p.stderr_text(), Catch::Contains("stopping after"));
  }
}

TEST_CASE("SIGHUP reloads the config and keeps the old one when the new one is invalid",
          "[fabrikd]") {
  json c = good_config("hup");
  const std::string path = write_file("hup.json", c.dump());
  Process p({kFabrikd, "--config", path});
  REQUIRE(p.wait_for_output("markers in on", 5s));
  zmq::context_t context;
  SocketClient client(context, c["input"]["endpoint"], c["output"]["endpoint"]);
  std::uint64_t frame = client.handshake();

  // A valid change (output units) takes effect without reconnecting.
  c["output"]["units"] = "m";
  write_file("hup.json", c.dump());
  p.signal(SIGHUP);
  REQUIRE(p.wait_for_output("config reloaded", 5s));
  client.send_frame(++frame, {{"RASI", {10, 950, 120}}});
  auto pose = client.receive("pose");
  REQUIRE(pose);
  CHECK((*pose)["units"] == "m");

  // An invalid file is refused; the daemon keeps running on the old config.
  write_file("hup.json", "{\"format\": \"fabrikd-config/1\", \"model\": 3}");
  p.signal(SIGHUP);
  REQUIRE(p.wait_for_output("reload failed, keeping the running config", 5s));
  CHECK_THAT(p.stderr_text(), Catch::Contains("at /model"));
  client.send_frame(++frame, {{"RASI", {10, 950, 120}}});
  pose = client.receive("pose");
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
  CHECK((*pose)["units"] == "m");
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
}
