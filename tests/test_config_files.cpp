// Reading config and model files: only regular files of bounded size, never
// blocking; JSON errors (a number overflowing a double included) name the
// JSON pointer; the daemon config's input limits.
#include <sys/stat.h>

#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "common/edit_distance.hpp"
#include "common/safe_text.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/endpoint_check.hpp"
#include "config/json_reader.hpp"
#include "config/model_loader.hpp"
#include "config/solver_options_json.hpp"
#include "temp_file.hpp"

using namespace fabrik;
using nlohmann::json;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("read_text_file reads regular files and refuses anything else without blocking",
          "[config][files]") {
  test::TempFile file(".json"), dir(""), loop(""), fifo(""), link("");
  std::ofstream(file.path()) << R"({"a": 1})";
  std::filesystem::create_directory(dir.path());
  std::filesystem::create_symlink(loop.path(), loop.path());
  REQUIRE(mkfifo(fifo.path().c_str(), 0600) == 0);  // opening it for reading would wait for a writer
  std::filesystem::create_symlink(file.path(), link.path());
  std::string text;
  CHECK_FALSE(read_text_file(file.path(), text));
  CHECK(text == R"({"a": 1})");
  CHECK_FALSE(read_text_file(link.path(), text));  // a link to a regular file is fine
  CHECK(text == R"({"a": 1})");
  // /proc files are regular but say they are empty: read all the same.
  CHECK_FALSE(read_text_file("/proc/self/status", text));
  CHECK_THAT(text, Catch::Contains("Name:"));
  const std::vector<std::pair<std::string, std::string>> refused = {
      {dir.path(), "is a directory, not a regular file"},
      {loop.path(), "too many levels of symbolic links"},
      {fifo.path(), "is a FIFO, not a regular file"},
      {"/dev/zero", "is a character device (like /dev/zero), not a regular file"},
      {"/nonexistent/x.json", "cannot open the file: no such file"},
  };
  for (const auto& [path, expected] : refused) {
    CAPTURE(path);
    const auto t0 = std::chrono::steady_clock::now();
    const auto problem = read_text_file(path, text);
    CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(1));
    REQUIRE(problem);
    CHECK_THAT(problem->problem, Catch::Contains(expected));
    CHECK_FALSE(problem->fix.empty());
  }
  // The size limit, said in the error.
  std::ofstream(file.path()) << std::string(100, ' ');
  CHECK_FALSE(read_text_file(file.path(), text, 100));
  const auto big = read_text_file(file.path(), text, 99);
  REQUIRE(big);
  CHECK_THAT(big->problem, Catch::Contains("100 bytes, over the limit of 99 bytes"));
  CHECK(kMaxConfigFileBytes == 16u << 20);
}

TEST_CASE("JSON errors name the pointer: a number overflowing a double, syntax, depth",
          "[config][json]") {
  const std::string overflow =
      error_of([] { JsonReader::parse("{\"solver\": {\"tolerance_mm\": 1e400}}", "c.json"); });
  CHECK_THAT(overflow, Catch::StartsWith("c.json: at /solver/tolerance_mm: the number '1e400' "
                                         "(line 1, column"));
  CHECK_THAT(overflow, Catch::Contains("too large for a double") && Catch::Contains("Fix: "));
  CHECK_THAT(error_of([] { JsonReader::parse("{\"a\": [1, 2,\n -1e999]}", "c.json"); }),
             Catch::StartsWith("c.json: at /a/2: the number '-1e999' (line 2, column"));
  const std::string syntax = error_of(
      [] { JsonReader::parse("{\"format\": \"fabrikd-config/1\",\n \"model\" }", "c.json"); });
  CHECK_THAT(syntax, Catch::StartsWith("c.json: at /model: not valid JSON (line 2"));
  std::string deep = "{\"a\": ";
  for (int i = 0; i < 1000; ++i) deep += "[";
  const std::string depth = error_of([&] { JsonReader::parse(deep, "c.json"); });
  CHECK_THAT(depth, Catch::Contains("nesting deeper than 256 levels") && Catch::Contains("Fix: "));
  CHECK_THAT(depth, Catch::StartsWith("c.json: at /a/0/0/"));
  // Valid documents parse as before, tiny numbers included.
  const json doc = JsonReader::parse(R"({"a": [1e-400, -0.0, 1.7976931348623157e308]})", "c.json");
  CHECK(doc["a"][0].get<double>() == 0.0);
  CHECK(doc["a"][2].get<double>() > 1e308);
}

TEST_CASE("Daemon config and model files go through the same checks", "[config][files]") {
  test::TempFile dir(""), config(".json"), model_dir("");
  std::filesystem::create_directory(dir.path());
  std::filesystem::create_directory(model_dir.path());
  CHECK_THAT(error_of([&] { load_daemon_config_file(dir.path()); }),
             Catch::Contains(dir.path() + ": at /: is a directory, not a regular file. Fix:"));
  std::ofstream(config.path()) << json{{"format", "fabrikd-config/1"}, {"model", model_dir.path()}};
  CHECK_THAT(error_of([&] { load_daemon_config_file(config.path()); }),
             Catch::Contains(config.path() + ": at /model: model file '" + model_dir.path() +
                             "' is a directory, not a regular file. Fix:"));
  // An empty path once read as the config's own folder: "is a directory".
  std::ofstream(config.path()) << json{{"format", "fabrikd-config/1"}, {"model", ""}};
  CHECK_THAT(error_of([&] { load_daemon_config_file(config.path()); }),
             Catch::Contains(config.path() + ": at /model: the model's path is empty. Fix:"));
  // An embedded default still stands in where nothing is on disk.
  std::ofstream(config.path()) << json{{"format", "fabrikd-config/1"},
                                       {"model", "models/fullbody.json"}};
  CHECK_NOTHROW(load_daemon_config_file(config.path()));
}

TEST_CASE("A model or a template given as a daemon config is named for what it is", "[config]") {
  // Before: "at /coordinates: unknown field 'coordinates'", the file's first field a config
  // does not have.
  const std::string source = FABRIK_SOURCE_DIR;
  CHECK_THAT(
      error_of([&] { load_daemon_config_file(source + "/config/models/fullbody.json"); }),
      Catch::Contains("at /format: this is a model, not a daemon config (fabrikd-config/1)") &&
          Catch::Contains("as a config's \"model\""));
  CHECK_THAT(error_of([&] { load_daemon_config_file(source + "/config/templates/gait2354.json"); }),
             Catch::Contains("at /format: this is a model template, not a daemon config") &&
                 Catch::Contains("fabrik calibrate --template"));
  json model = json::parse(R"({"segments": [], "description": "no format"})");
  CHECK_THAT(error_of([&] { load_daemon_config(model.dump(), "m.json"); }),
             Catch::Contains("m.json: at /: this is a model, not a daemon config"));
  CHECK_THAT(error_of([&] { load_daemon_config(R"({"format": "other/2"})", "o.json"); }),
             Catch::Contains("at /format: unsupported format 'other/2'"));
}

TEST_CASE("A sensors world whose up is not the model's or whose rotation is in radians is refused",
          "[config][sensors]") {
  const auto with_world = [](const json& world) {
    return json{{"format", "fabrikd-config/1"},
                {"model", "models/fullbody.json"},
                {"sensors",
                 {{"world", world}, {"orientations", {{"pelvis_imu", {{"segment", "pelvis"}}}}}}}}
        .dump();
  };
  // OpenSense's z-up sensors on a y-up model, as its tutorial gives them.
  const DaemonConfig ok =
      load_daemon_config(with_world({{"rotation_deg", {-90, 0, 0}}, {"up", "y"}}), "c.json");
  CHECK(ok.sensors.world.rotation_xyz_rad.x() == Approx(-std::numbers::pi / 2));
  CHECK(ok.sensors.world.up == "y");
  CHECK_NOTHROW(load_daemon_config(with_world({{"rotation_deg", {1.5, 0, 0}}}), "c.json"));
  // Without "up", the model's: y here, z on a z-up model (it was y whatever the model's).
  CHECK(load_daemon_config(with_world(json::object()), "c.json").sensors.world.up == "+y");
  std::ifstream model_file(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  json zup = json::parse(with_world(json::object()));
  zup["model"] = json::parse(model_file);
  zup["model"]["lab_axes"] = {{"up", "+z"}, {"forward", "+x"}};
  const DaemonConfig z = load_daemon_config(zup.dump(), "c.json");
  CHECK(z.sensors.world.up == "+z");
  CHECK(z.sensors.world.up_vector() == Eigen::Vector3d::UnitZ());
  CHECK_NOTHROW(load_daemon_config(with_world({{"rotation_deg", {0.0004, 0, 0}}}), "c.json"));
  // The sensors' own up written where the model's belongs (17 deg of sensor error, no word).
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_world({{"up", "z"}}), "c.json");
             }),
             Catch::Contains("at /sensors/world/up: the model's vertical is its lab_axes' up "
                             "(+y), not z") &&
                 Catch::Contains("\"rotation_deg\""));
  // OpenSim's sensor_to_opensim_rotations copied as they are: radians.
  CHECK_THAT(
      error_of([&] {
        load_daemon_config(with_world({{"rotation_deg", {-1.5707963267948966, 0, 0}}}), "c.json");
      }),
      Catch::Contains("at /sensors/world/rotation_deg: angle -1.57079633 is a multiple of "
                      "90 deg in radians") &&
          Catch::Contains("give degrees: -90 for -1.57079633"));
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_world({{"rotation_deg", {0, 3.1416, 0}}}), "c.json");
             }),
             Catch::Contains("give degrees: 180 for 3.1416"));
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_world({{"rotation_deg", {0, 0, 3.14}}}), "c.json");
             }),
             Catch::Contains("give degrees: 180 for 3.14"));
  CHECK_NOTHROW(load_daemon_config(with_world({{"rotation_deg", {1.55, 3.0, 6.2}}}), "c.json"));
}

TEST_CASE("input.max_abs_coordinate_mm and input.zero_is_missing", "[config]") {
  const auto with_input = [](const json& input) {
    return json{{"format", "fabrikd-config/1"}, {"model", "models/fullbody.json"}, {"input", input}}
        .dump();
  };
  const DaemonConfig d = default_daemon_config();
  CHECK(d.max_abs_coordinate_m == 100.0);
  CHECK(d.zero_is_missing);
  const DaemonConfig c = load_daemon_config(
      with_input({{"max_abs_coordinate_mm", 5000}, {"zero_is_missing", false}}), "c.json");
  CHECK(c.max_abs_coordinate_m == 5.0);
  CHECK_FALSE(c.zero_is_missing);
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_input({{"max_abs_coordinate_mm", 0}}), "c.json");
             }),
             Catch::Contains("at /input/max_abs_coordinate_mm: value 0 is out of range"));
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_input({{"zero_is_missing", "yes"}}), "c.json");
             }),
             Catch::Contains("at /input/zero_is_missing: expected true or false"));
}

TEST_CASE("solver.fallback_carry: read, written back when not the default, range-checked",
          "[config]") {
  const auto with_solver = [](const json& solver) {
    return json{
        {"format", "fabrikd-config/1"}, {"model", "models/fullbody.json"}, {"solver", solver}}
        .dump();
  };
  CHECK(default_daemon_config().tracker.solver.fallback_carry == SolverOptions{}.fallback_carry);
  const DaemonConfig off = load_daemon_config(with_solver({{"fallback_carry", 0}}), "c.json");
  CHECK(off.tracker.solver.fallback_carry == 0.0);
  CHECK(solver_options_json(off.tracker.solver)["fallback_carry"] == 0.0);
  CHECK_FALSE(solver_options_json(SolverOptions{}).contains("fallback_carry"));
  CHECK_THAT(error_of([&] {
               load_daemon_config(with_solver({{"fallback_carry", -1}}), "c.json");
             }),
             Catch::Contains("at /solver/fallback_carry: value -1 is out of range"));
}

TEST_CASE("An integer over 2^63 - 1 is refused by its range, not read wrapped negative",
          "[config]") {
  const auto config = [](const json& targets, const json& solver) {
    return json{{"format", "fabrikd-config/1"},
                {"model", "models/fullbody.json"},
                {"targets", targets},
                {"solver", solver}}
        .dump();
  };
  // 2^64 - 1 read as a long long is -1: a level inside [-1000, 1000].
  for (const std::uint64_t big : {18446744073709551615ULL, 9223372036854775808ULL}) {
    CAPTURE(big);
    CHECK_THAT(
        error_of([&] {
          load_daemon_config(config({{"default", {{"level", big}}}}, json::object()), "c.json");
        }),
        Catch::Contains("at /targets/default/level: value " + std::to_string(big) +
                        " is out of range"));
    CHECK_THAT(error_of([&] {
                 load_daemon_config(config(json::object(), {{"max_iterations", big}}), "c.json");
               }),
               Catch::Contains("at /solver/max_iterations: value " + std::to_string(big) +
                               " is out of range"));
  }
  // The largest a range allows is still read.
  const DaemonConfig c = load_daemon_config(
      config({{"default", {{"level", 1000ULL}}}}, {{"max_iterations", 10000000ULL}}), "c.json");
  CHECK(c.tracker.solver.max_iterations == 10000000);
  CHECK(c.tracker.markers.front().level == 1000);
}

TEST_CASE("Endpoints: tcp ports 1-65535 in digits or any free port to bind, else refused with "
          "the pointer and the fix, ipc and inproc as given",
          "[config][endpoint]") {
  const auto config = [](const std::string& endpoint, const std::string& mode) {
    return json{{"format", "fabrikd-config/1"},
                {"model", "models/fullbody.json"},
                {"input", {{"endpoint", endpoint}, {"mode", mode}}}}
        .dump();
  };
  struct Case {
    std::string endpoint, mode, expected;  // expected empty: accepted
  };
  const std::vector<Case> cases = {
      // ZeroMQ would open these modulo 65536: 4464, 34463, 65535.
      {"tcp://127.0.0.1:70000", "bind", "port '70000' of 'tcp://127.0.0.1:70000' is out of range"},
      {"tcp://127.0.0.1:99999", "connect",
       "port '99999' of 'tcp://127.0.0.1:99999' is out of range"},
      {"tcp://127.0.0.1:-1", "bind", "port '-1' of 'tcp://127.0.0.1:-1' is not a port number"},
      {"tcp://127.0.0.1:0", "bind", "port 0 of 'tcp://127.0.0.1:0' is not a port"},
      {"tcp://127.0.0.1:abc", "bind", "port 'abc' of 'tcp://127.0.0.1:abc' is not a port number"},
      {"tcp://127.0.0.1:", "bind", "port '' of 'tcp://127.0.0.1:' is not a port number"},
      {"tcp://127.0.0.1:+80", "bind", "is not a port number"},
      {"tcp://127.0.0.1:0000000000080", "bind", ""},  // digits, 80
      {"tcp://127.0.0.1:123456789012345678901", "bind", "is out of range"},
      {"tcp://127.0.0.1", "bind", "'tcp://127.0.0.1' has no port"},
      {"tcp://[::1]", "bind", "'tcp://[::1]' has no port"},
      {"tcp://127.0.0.1:*", "connect", "port * of 'tcp://127.0.0.1:*' means any free port"},
      {"tcp://127.0.0.1:*", "bind", ""},
      {"tcp://127.0.0.1:1", "bind", ""},
      {"tcp://127.0.0.1:65535", "bind", ""},
      {"tcp://[::1]:5555", "bind", ""},
      {"tcp://127.0.0.1:6000;192.0.2.1:5555", "connect", ""},  // source;destination
      {"tcp://127.0.0.1:6000;192.0.2.1:65536", "connect", "port '65536'"},
      {"ws://127.0.0.1:8080/markers", "bind", ""},
      {"ws://127.0.0.1:80800/markers", "bind", "port '80800'"},
      // A ws path's own ';' and ':' are not a source;destination or a port (was "has no port").
      {"ws://127.0.0.1:8080/a;b", "bind", ""},
      {"ws://127.0.0.1:80800/a;b:99", "bind", "port '80800'"},
      {"127.0.0.1:5555", "bind", "'127.0.0.1:5555' is not a ZeroMQ endpoint"},
      // ZeroMQ's transports are lower case: a bind to TCP:// fails ("Protocol not supported").
      {"TCP://127.0.0.1:5555", "bind", "transport 'TCP' of 'TCP://127.0.0.1:5555' is not one"},
      {"Ipc:///tmp/f.sock", "connect", "Fix: write \"ipc:///tmp/f.sock\""},
      {"tcp2://127.0.0.1:5555", "bind", "transport 'tcp2'"},
      {"tcp2://127.0.0.1:5555", "bind", "Fix: write tcp://, ipc:// or inproc://"},
      {"connect:tcp://127.0.0.1:5555", "bind", "Fix: give the mode apart: \"mode\" in a config"},
      // A lower-case word no libzmq has (a typo) is refused here, with its fix, not at the bind.
      {"tpc://127.0.0.1:5555", "bind",
       "transport 'tpc' of 'tpc://127.0.0.1:5555' is not one ZeroMQ has (tcp, ipc, inproc,"},
      {"tpc://127.0.0.1:5555", "bind", "inproc, udp (not for PUB/SUB), ws,"},
      {"tpc://127.0.0.1:5555", "bind",
       "Fix: write the transport meant (tcp://, ipc://, tipc://), e.g. "
       "\"tcp://127.0.0.1:5555\""},
      {"ipcc:///tmp/f.sock", "connect", "Fix: write \"ipc:///tmp/f.sock\""},
      {"zmq://127.0.0.1:5555", "bind", "Fix: write tcp://, ipc:// or inproc://"},
      {"norm://127.0.0.1:5555", "bind", ""},  // ZeroMQ's, if its build has it
      // ZeroMQ's udp is for RADIO/DISH sockets: a PUB or SUB fails at the bind.
      {"udp://127.0.0.1:5555", "bind", "udp:// serves RADIO and DISH sockets only"},
      {"udp://127.0.0.1:5555", "connect", "Fix: use tcp://, or pgm:// or epgm:// for multicast"},
      {"upd://127.0.0.1:5555", "bind", "Fix: write tcp://, ipc:// or inproc://"},  // not udp
      {"ipc:///tmp/fabrik:99999", "bind", ""},  // a path: ZeroMQ's business
      {"inproc://markers:-1", "connect", ""},
  };
  for (const Case& c : cases) {
    CAPTURE(c.endpoint, c.mode);
    const std::string error =
        error_of([&] { load_daemon_config(config(c.endpoint, c.mode), "c.json"); });
    if (c.expected.empty()) {
      CHECK(error == "(no error)");
      CHECK_FALSE(
          endpoint_problem(c.endpoint, c.mode == "bind" ? SocketMode::bind : SocketMode::connect));
    } else {
      CHECK_THAT(error, Catch::StartsWith("c.json: at /input/endpoint: ") &&
                            Catch::Contains(c.expected) && Catch::Contains(". Fix: "));
    }
  }
  // The command-line form names the option instead of a pointer.
  try {
    require_usable_endpoint("tcp://127.0.0.1:99999", SocketMode::bind, "--input");
    FAIL("no error");
  } catch (const std::invalid_argument& e) {
    CHECK_THAT(e.what(), Catch::StartsWith("--input: port '99999'") &&
                             Catch::Contains("Fix: use a port from 1 to 65535"));
  }
}

TEST_CASE("Input and output endpoints that meet at one address clash, written alike or not",
          "[config][endpoint]") {
  const SocketMode B = SocketMode::bind, C = SocketMode::connect;
  struct Case {
    Endpoint a, b;
    bool clash;
  };
  const std::vector<Case> cases = {
      {{"tcp://127.0.0.1:5556", B}, {"tcp://127.0.0.1:5556", B}, true},
      {{"ipc:///tmp/f.sock", B}, {"ipc:///tmp/f.sock", C}, true},
      {{"ipc:///tmp/f.sock", B}, {"ipc:///tmp/g.sock", B}, false},
      // Both bound: any address overlaps every one of the same port.
      {{"tcp://*:5556", B}, {"tcp://127.0.0.1:5556", B}, true},
      {{"tcp://127.0.0.1:5556", B}, {"tcp://0.0.0.0:5556", B}, true},
      {{"tcp://[::]:5556", B}, {"tcp://192.0.2.7:5556", B}, true},
      {{"tcp://localhost:5556", B}, {"tcp://127.0.0.1:5556", B}, true},
      {{"tcp://LocalHost:05556", C}, {"tcp://127.0.0.1:5556", B}, true},
      {{"tcp://127.0.0.1:000022607", B}, {"tcp://127.0.0.1:22607", B}, true},  // 9 characters
      {{"tcp://127.0.0.1:0000022608", B}, {"tcp://127.0.0.1:0000022609", B}, false},
      {{"tcp://127.0.0.1:5556", B}, {"tcp://192.0.2.7:5556", B}, false},
      {{"tcp://*:5556", B}, {"tcp://*:5557", B}, false},
      {{"tcp://*:*", B}, {"tcp://*:*", B}, false},          // each its own free port
      {{"tcp://127.0.0.1:*", B}, {"tcp://*:*", B}, false},  // each its own free port
      // Bound and connected: a connect to this machine meets a bind of any address.
      {{"tcp://*:5556", B}, {"tcp://127.0.0.1:5556", C}, true},
      {{"tcp://[::1]:5556", C}, {"tcp://[::]:5556", B}, true},
      // IPv6 addresses however they are written (were told apart by their text).
      {{"tcp://[0:0:0:0:0:0:0:0]:5556", B}, {"tcp://192.0.2.7:5556", B}, true},
      {{"tcp://[0::1]:5556", C}, {"tcp://[::0]:5556", B}, true},
      {{"tcp://[0:0:0:0:0:0:0:1]:5556", C}, {"tcp://[::1]:5556", C}, true},
      {{"tcp://[2001:DB8::7]:5556", C}, {"tcp://[2001:db8:0::7]:5556", C}, true},
      {{"tcp://[2001:db8::7]:5556", C}, {"tcp://[2001:db8::8]:5556", C}, false},
      {{"tcp://[::ffff:127.0.0.1]:5556", C}, {"tcp://*:5556", B}, true},  // IPv4-mapped loopback
      {{"tcp://[::FFFF:7f00:1]:5556", C}, {"tcp://127.0.0.1:5556", B}, true},
      {{"tcp://[::ffff:192.0.2.7]:5556", C}, {"tcp://192.0.2.7:5556", C}, true},
      {{"tcp://*:5556", B}, {"tcp://192.0.2.7:5556", C}, false},  // another machine's port
      {{"tcp://127.0.0.2:5556", C}, {"tcp://127.0.0.1:5556", B}, false},
      // Both connected to one peer's port.
      {{"tcp://localhost:5556", C}, {"tcp://127.0.0.1:5556", C}, true},
      {{"tcp://192.0.2.7:5556", C}, {"tcp://192.0.2.8:5556", C}, false},
      // Not ZeroMQ tcp: a NatNet or QTM source never meets the pose output.
      {{"natnet://127.0.0.1:5556", C}, {"tcp://*:5556", B}, false},
      {{"qtm://127.0.0.1:5556", C}, {"tcp://127.0.0.1:5556", B}, false},
      {{"tcp://127.0.0.1:6000;127.0.0.1:5556", C}, {"tcp://*:5556", B}, true},  // source;dest
  };
  for (const Case& c : cases) {
    CAPTURE(c.a.address, c.b.address);
    CHECK(endpoints_clash(c.a, c.b) == c.clash);
    CHECK(endpoints_clash(c.b, c.a) == c.clash);
  }
  // A wildcard bind, however it is written: the taken-port advice asks for the host's address.
  for (const char* any : {"tcp://*:5556", "tcp://0.0.0.0:5556", "tcp://[::]:5556",
                          "tcp://[0:0:0:0:0:0:0:0]:5556", "tcp://[::0]:5556", "tcp://[0::]:*",
                          "ws://*:8080/poses", "wss://0.0.0.0:8443", "udp://*:5556"}) {
    CAPTURE(any);
    CHECK(binds_any_address(any));
  }
  for (const char* one :
       {"tcp://127.0.0.1:5556", "tcp://[::1]:5556", "tcp://[0::1]:5556", "tcp://eth0:5556",
        "ipc:///tmp/x", "tcp://192.0.2.7:*", "ws://127.0.0.1:8080/*", "inproc://*"}) {
    CAPTURE(one);
    CHECK_FALSE(binds_any_address(one));
  }
  // The config names both spellings.
  const json j = {{"format", "fabrikd-config/1"},
                  {"model", "models/fullbody.json"},
                  {"input", {{"endpoint", "tcp://127.0.0.1:22011"}, {"mode", "connect"}}},
                  {"output", {{"endpoint", "tcp://*:22011"}}}};
  CHECK_THAT(error_of([&] { load_daemon_config(j.dump(), "c.json"); }),
             Catch::StartsWith("c.json: at /output: input and output use the same endpoint "
                               "'tcp://127.0.0.1:22011' ('tcp://*:22011', one port of this "
                               "machine)") &&
                 Catch::Contains(". Fix: "));
}

TEST_CASE("An endpoint option takes bind: and connect: prefixes, and a tool's --bind agrees",
          "[config][endpoint]") {
  const SocketMode B = SocketMode::bind, C = SocketMode::connect;
  const auto is = [](const Endpoint& e, const std::string& address, SocketMode mode) {
    return e.address == address && e.mode == mode;
  };
  CHECK(is(endpoint_option("tcp://127.0.0.1:5555", B, "--input"), "tcp://127.0.0.1:5555", B));
  CHECK(is(endpoint_option("tcp://127.0.0.1:5555", C, "--input"), "tcp://127.0.0.1:5555", C));
  CHECK(
      is(endpoint_option("connect:tcp://127.0.0.1:5555", B, "--input"), "tcp://127.0.0.1:5555", C));
  CHECK(is(endpoint_option("bind:ipc:///tmp/x.sock", C, "--to"), "ipc:///tmp/x.sock", B));
  // A tool's --bind given: "bind:" agrees, "connect:" is refused (replay once took the
  // prefix for part of the address: "Protocol not supported").
  CHECK(is(endpoint_option("bind:tcp://*:5555", B, "--to", "--bind"), "tcp://*:5555", B));
  CHECK_THROWS_WITH(endpoint_option("connect:tcp://127.0.0.1:5555", B, "--to", "--bind"),
                    Catch::StartsWith("--to: 'connect:tcp://127.0.0.1:5555' connects, and --bind "
                                      "binds") &&
                        Catch::Contains(". Fix: "));
  CHECK_THROWS_WITH(endpoint_option("connect:tcp://127.0.0.1:*", B, "--output"),
                    Catch::StartsWith("--output: port * of"));
}

TEST_CASE("A config error quoting bytes that are not UTF-8 says them as escapes",
          "[config][safe_text]") {
  // nlohmann's parse error quotes what it last read: '"\xff'.
  const std::string bad_name = "bad\xfe\x1b[31m.json";
  const std::string error = error_of([&] { load_daemon_config("{\"format\": \"\xff", bad_name); });
  CAPTURE(error);
  CHECK_THAT(error, Catch::Contains("bad\\xfe\\x1b[31m.json: at /format: not valid JSON") &&
                        Catch::Contains("last read: '\"\\xff'"));
  CHECK(error.find('\xff') == std::string::npos);
  CHECK(error.find('\xfe') == std::string::npos);
  CHECK(error.find('\x1b') == std::string::npos);
  CHECK(safe_lines(error) == error);  // valid UTF-8 without control characters already
  // Values quoted from a parsed config too (an unknown socket mode).
  const std::string mode_error = error_of([&] {
    load_daemon_config(json{{"format", "fabrikd-config/1"},
                            {"model", "models/fullbody.json"},
                            {"input", {{"mode", "li\xc3\xa9\x07n"}}}}
                           .dump(),
                       "c.json");
  });
  CHECK_THAT(mode_error, Catch::Contains("unknown socket mode 'li\xc3\xa9\\x07n'"));
}

TEST_CASE("A config tracks at most as many markers as a model may have", "[config][limits]") {
  std::ifstream in(std::string(FABRIK_SOURCE_DIR) + "/config/default.json");
  json c = json::parse(in);
  for (int k = 0; k <= ModelLimits::kMarkers; ++k)
    c["targets"]["markers"]["S" + std::to_string(k)] = {{"point", "RASI"}};
  const std::string listed = std::to_string(c["targets"]["markers"].size());
  try {
    load_daemon_config(c.dump(), std::string(FABRIK_SOURCE_DIR) + "/config/many.json");
    FAIL("loaded");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("at /targets/markers:") &&
                             Catch::Contains(listed + " marker targets"));
  }
}

TEST_CASE("A typo's distance counts two neighbours swapped as one edit", "[endpoint]") {
  struct Case {
    std::string a, b;
    std::size_t levenshtein, typo;
  };
  for (const Case& c : std::vector<Case>{{"tpc", "tcp", 2, 1},
                                         {"tcp", "tcp", 0, 0},
                                         {"", "ipc", 3, 3},
                                         {"ipc", "", 3, 3},
                                         {"icp", "ipc", 2, 1},
                                         {"ab", "ba", 2, 1},
                                         {"abcd", "badc", 3, 2},
                                         {"inprco", "inproc", 2, 1},
                                         {"tpc", "tipc", 1, 1},
                                         {"kitten", "sitting", 3, 3}}) {
    CAPTURE(c.a, c.b);
    CHECK(fabrik::edit_distance(c.a, c.b) == c.levenshtein);
    CHECK(fabrik::typo_distance(c.a, c.b) == c.typo);
    CHECK(fabrik::typo_distance(c.b, c.a) == c.typo);
  }
}
