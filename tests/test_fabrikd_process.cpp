// The fabrikd executable: exit codes and messages for bad configs and
// unusable files, clean shutdown on SIGTERM/SIGINT (also during a reload),
// reload on SIGHUP that survives a bad file while frames are answered, and
// the limits at its transport edge (message size, file descriptors).
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>

#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "config/daemon_config.hpp"
#include "process.hpp"
#include "sanitized.hpp"
#include "socket_client.hpp"

using namespace fabrik::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

// FABRIKD_UNDER_TEST runs these tests on another build (e.g. an older one,
// for before-and-after figures).
const std::string kFabrikd =
    std::getenv("FABRIKD_UNDER_TEST") ? std::getenv("FABRIKD_UNDER_TEST") : FABRIKD_PATH;

// This process's scratch folder, removed when the process ends (spawned
// children exec at once, so they never run this destructor).
struct ScratchDir {
  std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("fabrikd-test-" + std::to_string(getpid()));
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};

std::filesystem::path temp_dir() {
  static const ScratchDir dir;
  std::filesystem::create_directories(dir.path);
  return dir.path;
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

// fabrikd started on a config file, with a client connected both ways.
struct Running {
  Running(const std::string& config_path, const json& config)
      : process({kFabrikd, "--config", config_path}) {
    REQUIRE(process.wait_for_output("markers in on", 5s));
    client.emplace(context, config["input"]["endpoint"], config["output"]["endpoint"]);
    frame = client->handshake();
  }
  Process process;
  zmq::context_t context;
  std::optional<SocketClient> client;
  std::uint64_t frame = 0;
};

}  // namespace

TEST_CASE("fabrikd --version and --help exit 0, or 2 when they could not be written", "[fabrikd]") {
  Process v({kFabrikd, "--version"});
  CHECK(v.wait(5s) == 0);
  Process h({kFabrikd, "--help"});
  CHECK(h.wait(5s) == 0);
  // On a full disk they are an error: they exited 0 with nothing written.
  if (!std::filesystem::exists("/dev/full")) {
    WARN("skipped: no /dev/full on this machine");
    return;
  }
  for (const char* flag : {"--version", "--help"}) {
    CAPTURE(flag);
    Process full(
        {"/bin/sh", "-c", "exec '" + std::string(kFabrikd) + "' " + flag + " > /dev/full"});
    CHECK(full.wait(5s) == 2);
    CHECK_THAT(full.stderr_text(), Catch::Contains("fabrikd: writing the standard output failed"));
  }
}

// CLI11 gives each kind of command-line error its own code (105 an unexpected argument, 109 a
// value not in the set...): the daemon says 2, as for every wrong input (README).
TEST_CASE("A command line fabrikd cannot take exits 2 and says what was wrong", "[fabrikd][cli]") {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--bogus"}, "--bogus"},
      {{"--log-level", "loud"}, "loud"},
      {{"--config"}, "--config"},
      {{"extra"}, "extra"},
  };
  for (const auto& [extra, named] : cases) {
    std::vector<std::string> args = {kFabrikd};
    args.insert(args.end(), extra.begin(), extra.end());
    Process p(args);
    CAPTURE(extra);
    CHECK(p.wait(5s) == 2);
    CAPTURE(p.stderr_text());
    CHECK_THAT(p.stderr_text(), Catch::Contains(named) && Catch::Contains("--help"));
  }
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
  // The input on the output's default endpoint, the output left out: the clash is the input's.
  json input_on_default_output = good_config("h");
  input_on_default_output.erase("output");
  input_on_default_output["input"]["endpoint"] = fabrik::DaemonConfig{}.output.address;
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
      {"input_on_default_output.json", input_on_default_output.dump(),
       "at /input: the input's endpoint '" + fabrik::DaemonConfig{}.output.address +
           "' is the pose output's default"},
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
    Running r(write_file("sig.json", c.dump()), c);
    Process& p = r.process;
    p.signal(sig);
    CHECK(p.wait(1s) == 0);
    CHECK_THAT(p.stderr_text(), Catch::Contains("stopping after"));
  }
}

TEST_CASE("SIGHUP reloads the config and keeps the old one when the new one is invalid",
          "[fabrikd]") {
  json c = good_config("hup");
  const std::string path = write_file("hup.json", c.dump());
  Running r(path, c);
  Process& p = r.process;
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;

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
  // The units reload kept the endpoints: they were logged once, at the start.
  CHECK(p.count("poses out on") == 1);

  // A reload that moves the output says where the poses go now.
  const std::string moved = "ipc://" + (temp_dir() / "hup-moved-out").string();
  c["output"]["endpoint"] = moved;
  write_file("hup.json", c.dump());
  p.signal(SIGHUP);
  REQUIRE(p.wait_for_count("config reloaded", 2, 5s));
  REQUIRE(p.wait_for_count("poses out on", 2, 5s));
  CHECK_THAT(p.stderr_text(), Catch::Contains("poses out on " + moved + " (bind)"));
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
}

namespace {

using Clock = std::chrono::steady_clock;

// A path made unusable in one of the ways a config or model file can be:
// what is written there, and the words the error must contain.
struct BadFile {
  std::string what;
  std::function<void(const std::string& path)> make;
  std::string expected;
};

void remove_any(const std::string& path) {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

std::vector<BadFile> bad_files() {
  return {
      {"a directory", [](const std::string& p) { std::filesystem::create_directory(p); },
       "is a directory, not a regular file"},
      {"a symlink loop", [](const std::string& p) { std::filesystem::create_symlink(p, p); },
       "too many levels of symbolic links"},
      {"/dev/zero", [](const std::string& p) { std::filesystem::create_symlink("/dev/zero", p); },
       "is a character device (like /dev/zero), not a regular file"},
      {"17 MiB", [](const std::string& p) { std::ofstream(p) << std::string(17 << 20, ' '); },
       "over the limit of 16 MiB"},
  };
}

// The daemon's CPU time so far (user + system), seconds.
double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(text.substr(text.rfind(')') + 2));
  std::string f;
  long ticks = 0;
  for (int i = 3; i <= 15 && fields >> f; ++i)
    if (i == 14 || i == 15) ticks += std::stol(f);  // utime, stime
  return static_cast<double>(ticks) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// A loopback TCP port that was free a moment ago.
int free_tcp_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t n = sizeof a;
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  close(fd);
  return ntohs(a.sin_port);
}

// The value of one field of /proc/PID/status ("VmRSS:" ...), or "" if absent.
std::string proc_status(pid_t pid, const std::string& field) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field, 0) == 0) return line.substr(field.size());
  return "";
}

// Peak and current resident memory (VmHWM, VmRSS), kB; -1 if unknown.
long peak_rss_kb(pid_t pid) {
  const std::string v = proc_status(pid, "VmHWM:");
  return v.empty() ? -1 : std::stol(v);
}
long rss_kb(pid_t pid) {
  const std::string v = proc_status(pid, "VmRSS:");
  return v.empty() ? -1 : std::stol(v);
}

// Whether `pid` has installed a handler for `sig` (SigCgt in /proc/PID/status).
bool catches_signal(pid_t pid, int sig) {
  const std::string mask = proc_status(pid, "SigCgt:");
  return !mask.empty() && ((std::stoull(mask, nullptr, 16) >> (sig - 1)) & 1U);
}


// A subscriber that speaks ZMTP 3.0 over a raw TCP socket, as a hostile
// client would: unlike a ZeroMQ SUB socket it keeps no copy of what it
// subscribes to, so the test's own memory stays small whatever it sends.
class RawSubscriber {
 public:
  explicit RawSubscriber(int port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    if (fd_ < 0) throw std::runtime_error("socket failed");
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0)
      throw std::runtime_error("cannot connect to the output");
    // The handshake in turn, as ZeroMQ's own peers do it (libzmq 4.3 drops a
    // peer whose greeting, READY and messages arrive in one read).
    timeval timeout{5, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
    std::string greeting(64, '\0');  // signature, version 3.0, mechanism NULL, as-server 0
    greeting[0] = '\xff';
    greeting[9] = '\x7f';
    greeting[10] = 3;
    greeting.replace(12, 4, "NULL");
    send_all(greeting);
    std::string theirs;  // the daemon's greeting, then its READY command
    while (theirs.size() < 66 || theirs.size() < 66 + std::size_t{static_cast<std::uint8_t>(theirs[65])}) {
      char buffer[256];
      const ssize_t n = recv(fd_, buffer, sizeof buffer, 0);
      if (n <= 0) throw std::runtime_error("no ZMTP handshake from the output");
      theirs.append(buffer, static_cast<std::size_t>(n));
    }
    constexpr char kReady[] = "\x05READY\x0bSocket-Type\0\0\0\x03SUB";
    const std::string ready(kReady, sizeof kReady - 1);
    send_all(std::string{'\x04', static_cast<char>(ready.size())} + ready);
    fcntl(fd_, F_SETFL, fcntl(fd_, F_GETFL) | O_NONBLOCK);
  }
  ~RawSubscriber() { close(fd_); }
  RawSubscriber(const RawSubscriber&) = delete;
  RawSubscriber& operator=(const RawSubscriber&) = delete;

  void subscribe(std::string_view prefix, bool on = true) {
    const std::uint64_t size = prefix.size() + 1;
    if (size < 256) {
      out_ += std::string{'\0', static_cast<char>(size)};
    } else {
      out_ += '\x02';
      for (int shift = 56; shift >= 0; shift -= 8) out_ += static_cast<char>(size >> shift);
    }
    out_ += on ? '\x01' : '\0';
    out_ += prefix;
  }
  void send_all(const std::string& bytes) {
    if (send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size()))
      throw std::runtime_error("cannot send the ZMTP handshake");
  }
  // Writes what the socket takes without blocking; false once the daemon has closed it.
  bool flush() {
    while (sent_ < out_.size()) {
      const ssize_t n = send(fd_, out_.data() + sent_, out_.size() - sent_, MSG_NOSIGNAL);
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK;
      sent_ += static_cast<std::size_t>(n);
    }
    return !closed();
  }
  // Whether the daemon closed the connection (what it sent is read and dropped).
  bool closed() {
    char buffer[4096];
    for (;;) {
      const ssize_t n = recv(fd_, buffer, sizeof buffer, MSG_DONTWAIT);
      if (n == 0) return true;
      if (n < 0) return errno != EAGAIN && errno != EWOULDBLOCK;
    }
  }

 private:
  int fd_ = -1;
  std::string out_;
  std::size_t sent_ = 0;
};

}  // namespace

TEST_CASE("Unusable config and model files, numbers and addresses exit 2 within 2 s with the "
          "file, the pointer and the fix",
          "[fabrikd][files]") {
  struct Case {
    std::string what, path, expected;
  };
  std::vector<Case> cases;
  // The config file itself.
  for (const BadFile& b : bad_files()) {
    const std::string path = (temp_dir() / ("config-" + std::to_string(cases.size()))).string();
    remove_any(path);
    b.make(path);
    cases.push_back({"config is " + b.what, path, b.expected});
  }
  // The model file a valid config names.
  for (const BadFile& b : bad_files()) {
    const std::string model = (temp_dir() / ("model-" + std::to_string(cases.size()))).string();
    remove_any(model);
    b.make(model);
    json c = good_config("m" + std::to_string(cases.size()));
    c["model"] = model;
    const std::string path = write_file("model-case-" + std::to_string(cases.size()) + ".json",
                                        c.dump());
    cases.push_back({"model is " + b.what, path, "at /model: model file '" + model + "' "});
    cases.back().expected += "";  // plus the problem, checked below
  }
  json overflow = good_config("o");
  std::string overflow_text = overflow.dump();
  overflow_text.insert(overflow_text.size() - 1, R"(,"solver":{"tolerance_mm":1e400})");
  cases.push_back({"a number overflowing a double", write_file("overflow.json", overflow_text),
                   "at /solver/tolerance_mm: the number '1e400'"});
  json elsewhere = good_config("x");
  elsewhere["input"]["endpoint"] = "tcp://192.0.2.1:5555";  // TEST-NET-1: on no machine here
  cases.push_back({"a bind address not on this machine", write_file("elsewhere.json", elsewhere.dump()),
                   "at /input/endpoint: cannot bind the input socket to 'tcp://192.0.2.1:5555'"});
  const std::vector<BadFile> files = bad_files();
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const Case& c = cases[i];
    CAPTURE(c.what);
    const Clock::time_point t0 = Clock::now();
    Process p({kFabrikd, "--config", c.path});
    const std::optional<int> code = p.wait(2s);
    CHECK(code == 2);
    CHECK(Clock::now() - t0 < 2s);
    const std::string& err = p.stderr_text();
    CAPTURE(err);
    CHECK_THAT(err, Catch::Contains(c.path) && Catch::Contains(c.expected) &&
                        Catch::Contains("Fix:"));
    if (i >= files.size() && i < 2 * files.size())
      CHECK_THAT(err, Catch::Contains(files[i - files.size()].expected));
    if (i < files.size()) CHECK_THAT(err, Catch::Contains(": at /:"));
  }
  for (const Case& c : cases) remove_any(c.path);
}

TEST_CASE("A SIGHUP with an unusable config keeps answering frames throughout and keeps the old "
          "config, SIGTERM ends a reload in progress",
          "[fabrikd][files][reload]") {
  json c = good_config("hup2");
  c["output"]["units"] = "m";  // the running config: poses in metres
  const std::string path = write_file("hup2.json", c.dump());
  Running r(path, c);
  Process& p = r.process;
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;
  int poses = 0;
  auto answer = [&] {
    client.send_frame(++frame, {{"RASI", {10, 950, 120}}});
    const auto pose = client.receive("pose", 1s);
    REQUIRE(pose);
    REQUIRE((*pose)["frame"] == frame);
    CHECK((*pose)["units"] == "m");
    ++poses;
  };
  struct Reload {
    std::string what;
    std::function<void()> make;
    std::string expected;
  };
  std::vector<Reload> reloads;
  for (const BadFile& b : bad_files())
    reloads.push_back({"config is " + b.what, [&, b] {
                         remove_any(path);
                         b.make(path);
                       },
                       b.expected});
  const std::string model = (temp_dir() / "hup2-model").string();
  for (const BadFile& b : bad_files())
    reloads.push_back({"model is " + b.what, [&, b] {
                         remove_any(model);
                         b.make(model);
                         json bad = c;
                         bad["model"] = model;
                         remove_any(path);
                         write_file("hup2.json", bad.dump());
                       },
                       b.expected});
  reloads.push_back({"a number overflowing a double", [&] {
                       std::string text = c.dump();
                       text.insert(text.size() - 1, R"(,"stats_interval_s":-1e400)");
                       remove_any(path);
                       write_file("hup2.json", text);
                     },
                     "at /stats_interval_s: the number '-1e400'"});
  reloads.push_back({"a bind address not on this machine", [&] {
                       json bad = c;
                       bad["output"]["endpoint"] = "tcp://192.0.2.1:5556";
                       remove_any(path);
                       write_file("hup2.json", bad.dump());
                     },
                     "at /output/endpoint: cannot bind the output socket"});
  std::size_t failed = 0;
  for (const Reload& reload : reloads) {
    CAPTURE(reload.what);
    reload.make();
    p.signal(SIGHUP);
    ++failed;
    // Frames are answered, on the old config, while the reload is read and refused.
    const Clock::time_point deadline = Clock::now() + 2s;
    do {
      answer();
    } while (!p.wait_for_count("reload failed, keeping the running config", failed, 10ms) &&
             Clock::now() < deadline);
    REQUIRE(p.count("reload failed, keeping the running config") == failed);
    CHECK_THAT(p.stderr_text(), Catch::Contains(reload.expected));
    answer();
  }
  CHECK(poses >= static_cast<int>(2 * reloads.size()));
  // A valid file again is taken.
  remove_any(path);
  c["output"]["units"] = "mm";
  write_file("hup2.json", c.dump());
  p.signal(SIGHUP);
  REQUIRE(p.wait_for_output("config reloaded", 5s));
  client.send_frame(++frame, {{"RASI", {10, 950, 120}}});
  const auto pose = client.receive("pose");
  REQUIRE(pose);
  CHECK((*pose)["units"] == "mm");
  // A large valid config takes a while to read; SIGTERM right after SIGHUP
  // ends the daemon within a second all the same.
  c["description"] = std::string(15 << 20, 'd');
  remove_any(path);
  write_file("hup2.json", c.dump());
  p.signal(SIGHUP);
  p.signal(SIGTERM);
  const Clock::time_point t0 = Clock::now();
  CHECK(p.wait(1s) == 0);
  CHECK(Clock::now() - t0 < 1s);
  remove_any(path);
  remove_any(model);
}

TEST_CASE("One message cannot stop fabrikd: bytes that are not UTF-8 in the topic or a marker name",
          "[fabrikd][robustness]") {
  const json c = good_config("utf8");
  Running r(write_file("utf8.json", c.dump()), c);
  Process& p = r.process;
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;
  client.send(json{{"frame", ++frame}, {"markers", json::object()}}.dump(),
              std::string("markers\xff", 8));
  // MessagePack {"frame": 1, "markers": {"\xff\xfe": "x"}}: a raw string, not UTF-8.
  client.send(std::string("\x82\xa5"
                          "frame\x01\xa7"
                          "markers\x81\xa2\xff\xfe\xa1x",
                          21));
  client.send_frame(++frame);
  const auto pose = client.receive("pose");
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
  // Several stats intervals later it still runs and its stats are valid JSON.
  for (int i = 0; i < 5; ++i) {
    const auto stats = client.receive("stats", 2s);
    REQUIRE(stats);
    CHECK((*stats)["decode_errors"] == 2);
  }
  CHECK_FALSE(p.wait(10ms).has_value());
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
}

TEST_CASE("A 64 MiB message is refused by ZeroMQ before it is buffered", "[fabrikd][limits]") {
  const json c = good_config("big");  // ipc: ZeroMQ's stream engine, as for tcp
  Running r(write_file("big.json", c.dump()), c);
  Process& p = r.process;
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;
  const long before_kb = peak_rss_kb(p.pid());
  client.send(std::string(64 << 20, ' '));
  bool answered = false;
  for (int i = 0; i < 100 && !answered; ++i) {
    client.send_frame(++frame);
    while (const auto pose = client.receive("pose", 100ms))
      if ((answered = (*pose)["frame"] == frame)) break;
  }
  CHECK(answered);
  const long after_kb = peak_rss_kb(p.pid());
  WARN("fabrikd's peak RSS before and after a 64 MiB message: " << before_kb << " kB, "
                                                                << after_kb << " kB");
  CHECK(after_kb - before_kb < 16 * 1024);
  const auto stats = client.stats_until([](const json& s) { return s["input_disconnects"] >= 1; });
  CHECK(stats);
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
}

TEST_CASE("1100 connected sources under a 1024 open-files limit neither spin the daemon nor "
          "lock clients out, idle TCP connections are closed",
          "[fabrikd][limits]") {
  rlimit limit{};
  getrlimit(RLIMIT_NOFILE, &limit);
  if (limit.rlim_max < 4000) {
    WARN("skipped: the hard open-files limit (" << limit.rlim_max
                                                << ") leaves this test no room for its sockets");
    return;
  }
  limit.rlim_cur = limit.rlim_max;  // this test's own sockets
  REQUIRE(setrlimit(RLIMIT_NOFILE, &limit) == 0);
  json c = good_config("fds");
  const int port = free_tcp_port();
  c["input"]["endpoint"] = "tcp://127.0.0.1:" + std::to_string(port);
  const std::string path = write_file("fds.json", c.dump());
  // fabrikd starts with a soft limit of 1024, a common default.
  Process p({"/bin/sh", "-c", "ulimit -Sn 1024 && exec \"$0\" \"$@\"", kFabrikd, "--config", path});
  INFO(p.stderr_text());
  REQUIRE(p.wait_for_output("markers in on", 5s));
  zmq::context_t context;
  SocketClient client(context, c["input"]["endpoint"], c["output"]["endpoint"]);
  std::uint64_t frame = client.handshake();
  const auto open_fds = [&] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e :
         std::filesystem::directory_iterator("/proc/" + std::to_string(p.pid()) + "/fd"))
      ++n;
    return n;
  };
  const std::size_t fds_at_start = open_fds();
  // While the client is served, the daemon's CPU share is measured.
  int answered = 0;
  std::string phase = "alone";
  const auto serve_for = [&](std::chrono::milliseconds span) {
    CAPTURE(phase);
    const double cpu0 = cpu_seconds(p.pid());
    const Clock::time_point t0 = Clock::now();
    while (Clock::now() - t0 < span) {
      client.send_frame(++frame);
      const auto pose = client.receive("pose", 1s);
      REQUIRE(pose);
      answered += (*pose)["frame"] == frame;
    }
    return (cpu_seconds(p.pid()) - cpu0) / std::chrono::duration<double>(Clock::now() - t0).count();
  };

  const double cpu_share_alone = serve_for(1s);
  // 1100 sources that connect and complete ZeroMQ's handshake, and stay.
  phase = "1100 sources";
  zmq::context_t peers_context;
  peers_context.set(zmq::ctxopt::max_sockets, 1200);
  std::vector<zmq::socket_t> peers;
  for (int i = 0; i < 1100; ++i) {
    peers.emplace_back(peers_context, zmq::socket_type::pub);
    peers.back().set(zmq::sockopt::linger, 0);
    peers.back().connect(c["input"]["endpoint"].get<std::string>());
  }
  // Until the daemon has taken them (or no more arrive for 3 s).
  std::size_t fds = open_fds();
  for (Clock::time_point last_growth = Clock::now();
       fds < fds_at_start + 1100 && Clock::now() - last_growth < 3s;) {
    serve_for(50ms);
    if (const std::size_t now = open_fds(); now > fds) fds = now, last_growth = Clock::now();
  }
  const double cpu_share = serve_for(1s);
  SocketClient newcomer(context, c["input"]["endpoint"], c["output"]["endpoint"]);
  CHECK_NOTHROW(newcomer.handshake(5000000));
  WARN("1100 connected sources: fabrikd holds " << fds << " files (" << fds_at_start
                                                << " at start), used " << 100 * cpu_share
                                                << " % of a core while answering frames ("
                                                << 100 * cpu_share_alone << " % without them)");
  CHECK(fds >= fds_at_start + 1100);
  CHECK(cpu_share < cpu_share_alone + 0.25);  // ZeroMQ's accept() busy loop at the limit: +45 %
  peers.clear();
  phase = "idle TCP connections";

  // Raw TCP connections that never speak ZeroMQ are closed after its
  // handshake timeout (5 s), so they cannot pile up.
  std::vector<int> idle;
  for (int i = 0; i < 200; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    REQUIRE(fd >= 0);
    timeval timeout{5, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);  // bounds connect()
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    idle.push_back(fd);
    REQUIRE(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  }
  const Clock::time_point connected_at = Clock::now();
  bool closed = false;
  while (!closed && Clock::now() - connected_at < 15s) {
    serve_for(100ms);
    closed = open_fds() < fds_at_start + 20;
  }
  CHECK(closed);
  for (int fd : idle) close(fd);
  CHECK(answered > 100);
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
}

TEST_CASE("A subscriber can neither stall the daemon nor grow its memory: subscriptions to no "
          "topic it publishes are refused and their connections dropped",
          "[fabrikd][limits]") {
  // Unpatched, this left the loop silent for a second and more; ZeroMQ's own
  // work for what it reads from a subscriber before the loop can refuse it
  // (a few ms per hostile connection) remains.
  // Under ASan, beside another test on the second core, the first answer
  // after the burst took 2.2 s once, 14 s once and more than 30 s once
  // (ZeroMQ's I/O thread works through the 20 MB of subscriptions many times
  // slower): there the bound only catches a wedged daemon, on a smaller flood
  // (below); the release build measures the time.
  const auto answer_bound = time_bound(500ms, 30000ms);
  json c = good_config("subs");
  const int port = free_tcp_port();
  c["output"]["endpoint"] = "tcp://127.0.0.1:" + std::to_string(port);
#if defined(FABRIK_TEST_SANITIZED)
  // ASan keeps freed memory in a quarantine (256 MB by default) and pads
  // every block: the daemon's memory is bounded, but not at the same figure.
  const char* had = std::getenv("ASAN_OPTIONS");
  const std::string asan_options = had ? had : "";
  setenv("ASAN_OPTIONS", (asan_options + (had ? ":" : "") + "quarantine_size_mb=16").c_str(), 1);
  const long memory_bound_kb = 160 * 1024;
#else
  const long memory_bound_kb = 64 * 1024;
#endif
  Running r(write_file("subs.json", c.dump()), c);
#if defined(FABRIK_TEST_SANITIZED)
  if (had)
    setenv("ASAN_OPTIONS", asan_options.c_str(), 1);
  else
    unsetenv("ASAN_OPTIONS");
#endif
  Process& p = r.process;
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;
  const long peak_before_kb = peak_rss_kb(p.pid());
  // Unpatched, ZeroMQ stored each of these for its connection, on the pose
  // loop's thread: hundreds of MB.
  // Under the sanitizers the flood is a quarter as large: CI's ASan build
  // beside another test once took more than the 30 s bound for the first
  // answer (ZeroMQ's instrumented I/O thread, not the loop); the sanitized
  // run checks memory safety and the refusals, the release run the time.
#if defined(FABRIK_TEST_SANITIZED)
  constexpr int kFloodScale = 4;
#else
  constexpr int kFloodScale = 1;
#endif
  std::vector<std::unique_ptr<RawSubscriber>> hostile, busy;
  for (int i = 0; i < 40; ++i) {
    hostile.push_back(std::make_unique<RawSubscriber>(port));
    hostile.back()->subscribe(
        std::string((512 << 10) / kFloodScale, static_cast<char>('a' + i % 26)));
  }
  for (int i = 0; i < 40; ++i) {
    hostile.push_back(std::make_unique<RawSubscriber>(port));
    for (int k = 0; k < 1000 / kFloodScale; ++k)
      hostile.back()->subscribe("pose-" + std::to_string(i) + "-" + std::to_string(k) +
                                std::string(40, 'x'));
  }
  // Subscribers that keep changing their mind about topics we do publish.
  for (int i = 0; i < 10; ++i) {
    busy.push_back(std::make_unique<RawSubscriber>(port));
    for (int k = 0; k < 5000 / kFloodScale; ++k)
      busy.back()->subscribe(k % 2 ? "stats" : "pose", k % 4 < 2);
  }
  // A source at 100 Hz alongside, every frame answered promptly.
  Clock::duration slowest{};
  int answered = 0, sent = 0;
  const Clock::time_point start = Clock::now();
  std::size_t refused_closed = 0;
  while (Clock::now() - start < 1500ms) {
    for (auto& h : hostile) h->flush();
    for (auto& b : busy) b->flush();
    const Clock::time_point t0 = Clock::now();
    client.send_frame(++frame);
    ++sent;
    for (auto pose = client.receive("pose", 2 * answer_bound); pose;
         pose = client.receive("pose", 2 * answer_bound))
      if ((*pose)["frame"] == frame) {
        ++answered;
        break;
      }
    slowest = std::max(slowest, Clock::now() - t0);
    const Clock::time_point next = t0 + 10ms;
    while (Clock::now() < next) (void)client.receive("pose", 1ms);  // paced without sleeping
  }
  const auto closed_deadline = Clock::now() + 5s;
  do {
    refused_closed = 0;
    for (auto& h : hostile) refused_closed += h->closed() ? 1 : 0;
  } while (refused_closed < hostile.size() && Clock::now() < closed_deadline &&
           poll(nullptr, 0, 1) == 0);  // yields the core between rounds
  const long peak_after_kb = peak_rss_kb(p.pid());
  const auto ms = [](Clock::duration d) {
    return std::chrono::duration<double, std::milli>(d).count();
  };
  WARN("subscription flood: slowest answer " << ms(slowest) << " ms, " << answered << "/" << sent
                                             << " frames answered, peak RSS " << peak_before_kb
                                             << " -> " << peak_after_kb << " kB (now "
                                             << rss_kb(p.pid()) << " kB), " << refused_closed
                                             << "/" << hostile.size()
                                             << " hostile subscribers dropped");
  CHECK(answered == sent);
  CHECK(slowest < answer_bound);
  CHECK(peak_after_kb - peak_before_kb < memory_bound_kb);
  CHECK(refused_closed == hostile.size());
  json refused;
  const auto stats = client.stats_until([&](const json& s) {
    refused = s["subscriptions_refused"];
    return refused >= 40;
  });
  CAPTURE(refused);
  CHECK(stats);
  // The client subscribed to everything ("") is served throughout.
  client.send_frame(++frame);
  const auto pose = client.receive("pose", 2s);
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
  const Clock::time_point t0 = Clock::now();
  p.signal(SIGTERM);
  CHECK(p.wait(1s) == 0);
  WARN("SIGTERM to exit: " << ms(Clock::now() - t0) << " ms");
  // The operator is told what was refused, that the subscriber was dropped, and what is
  // published instead; the topic is cut short (each was 128-512 KiB).
  const std::string& log = p.stderr_text();
  const std::size_t said = log.find("refused a subscription to '");
  REQUIRE(said != std::string::npos);
  const std::string line = log.substr(said, log.find('\n', said) - said);
  CAPTURE(line);
  CHECK_THAT(line, Catch::Contains("on the output, subscriber disconnected: fabrikd publishes "
                                   "only the topics pose, stats and model") &&
                       Catch::EndsWith("(stats: subscriptions_refused)"));
  CHECK(line.size() < 400);
}

TEST_CASE("A raw peer's unsubscriptions of what others subscribed to do not stop their poses",
          "[fabrikd][limits]") {
  // Counted, three of them stopped every pose: the subscription count fell to 0
  // while the client (subscribed to "") was still there.
  json c = good_config("unsubs");
  const int port = free_tcp_port();
  c["output"]["endpoint"] = "tcp://127.0.0.1:" + std::to_string(port);
  Running r(write_file("unsubs.json", c.dump()), c);
  SocketClient& client = *r.client;
  std::uint64_t frame = r.frame;
  // Peers that send them and close at once: the loop may read their messages after
  // ZeroMQ has closed the descriptor (counted as ZeroMQ's own then, they did the same).
  // Whether it does is a race; the book's test ("A connection's unsubscription counts
  // only against what it subscribed to") holds the rule for it in any case.
  for (int i = 0; i < 10; ++i) {
    RawSubscriber closing(port);
    for (int k = 0; k < 3; ++k) {
      closing.subscribe("", false);
      closing.subscribe("pose", false);
    }
    REQUIRE(closing.flush());
  }
  RawSubscriber raw(port);
  for (int k = 0; k < 3; ++k) {
    raw.subscribe("", false);
    raw.subscribe("pose", false);
  }
  raw.subscribe("zz");  // refused: once counted, this peer's unsubscriptions were read
  REQUIRE(raw.flush());
  const auto stats = client.stats_until([](const json& s) { return s["subscriptions_refused"] >= 1; });
  REQUIRE(stats);
  CHECK((*stats)["pose_subscribers"] == 1);
  CHECK((*stats)["unsubscriptions_ignored"] >= 6);
  client.send_frame(++frame);
  const auto pose = client.pose_of(frame, 5000ms);
  REQUIRE(pose);
  CHECK((*pose)["frame"] == frame);
}

TEST_CASE("SIGTERM ends fabrikd within 100 ms at any moment: while it reads a large config, "
          "while it runs, and while it reads a reload",
          "[fabrikd][signals]") {
  const auto bound = time_bound(100ms, 500ms);
  json c = good_config("stop");
  const std::string path = write_file("stop.json", c.dump());
  // A million keys: about 1.5 s to read in a release build (it is refused
  // afterwards, as description must be a string: a stop comes first).
  std::string big = c.dump();
  big.pop_back();
  big += R"(,"description":{)";
  for (int k = 0; k < 1000000; ++k) big += (k ? ",\"k" : "\"k") + std::to_string(k) + "\":0";
  big += "}}";
  const std::string big_path = write_file("stop-big.json", big);
  const auto time_to_stop = [&](Process& p) {
    const Clock::time_point t0 = Clock::now();
    p.signal(SIGTERM);
    const std::optional<int> code = p.wait(5s);
    const auto took = Clock::now() - t0;
    CHECK(code == 0);
    const double took_ms = std::chrono::duration<double, std::milli>(took).count();
    WARN("SIGTERM to exit: " << took_ms << " ms");
    return took;
  };
  SECTION("reading a large config at startup") {
    Process p({kFabrikd, "--config", big_path});
    const Clock::time_point deadline = Clock::now() + 5s;
    while (!catches_signal(p.pid(), SIGTERM) && Clock::now() < deadline)
      poll(nullptr, 0, 1);  // not a synchronisation: the condition is; this only yields the core
    REQUIRE(catches_signal(p.pid(), SIGTERM));
    CHECK(time_to_stop(p) < bound);
    CHECK_THAT(p.stderr_text(), Catch::Contains("stopped during startup"));
  }
  SECTION("running") {
    Running r(path, c);
    CHECK(time_to_stop(r.process) < bound);
  }
  SECTION("reading a reload") {
    // The reload thread reads beside the loop on 2 cores shared with other
    // tests: measured 29 ms alone; the bound still catches the old 300 ms grace.
    const auto reload_bound = time_bound(200ms, 1000ms);
    Running r(path, c);
    std::filesystem::copy_file(big_path, path, std::filesystem::copy_options::overwrite_existing);
    r.process.signal(SIGHUP);
    REQUIRE(r.process.wait_for_output("reading the config again", 5s));
    CHECK(time_to_stop(r.process) < reload_bound);
  }
}

TEST_CASE("Empty --config, --input, --output and ports ZeroMQ would wrap exit 2 with the fix",
          "[fabrikd][cli]") {
  json wrapped = good_config("wrap");
  wrapped["output"]["endpoint"] = "tcp://127.0.0.1:70000";  // ZeroMQ would bind 4464
  const std::string wrapped_path = write_file("wrapped.json", wrapped.dump());
  json unbindable = good_config("unbindable");
  unbindable["output"]["endpoint"] = "tcp://192.0.2.1:22607";
  const std::string unbindable_path = write_file("unbindable.json", unbindable.dump());
  struct Case {
    std::vector<std::string> args;
    std::string expected;
  };
  const std::vector<Case> cases = {
      // Before: the embedded default ran, or the config's endpoint was used.
      {{"--config", ""}, "fabrikd: --config is empty. Fix: give the path of a daemon config"},
      {{"--input", ""}, "fabrikd: --input is empty. Fix: give an endpoint"},
      {{"--output", ""}, "fabrikd: --output is empty. Fix: give an endpoint"},
      // Before: bound 34463, 65535, 4464.
      {{"--input", "tcp://127.0.0.1:99999"},
       "fabrikd: --input: port '99999' of 'tcp://127.0.0.1:99999' is out of range"},
      {{"--input", "bind:tcp://127.0.0.1:-1"},
       "fabrikd: --input: port '-1' of 'tcp://127.0.0.1:-1' is not a port number"},
      {{"--output", "connect:tcp://127.0.0.1:*"}, "fabrikd: --output: port * of"},
      // Before: "Address already in use" (both bound), or taken (bound and connected).
      {{"--input", "tcp://127.0.0.1:22001", "--output", "tcp://127.0.0.1:22001"},
       "fabrikd: --output: 'tcp://127.0.0.1:22001' is also the input's endpoint"},
      {{"--input", "tcp://127.0.0.1:22604", "--output", "connect:tcp://127.0.0.1:22604"},
       "fabrikd: --output: 'tcp://127.0.0.1:22604' is also the input's endpoint"},
      {{"--input", "tcp://127.0.0.1:5556"},  // the embedded default's output
       "fabrikd: --input: 'tcp://127.0.0.1:5556' is also the output's endpoint"},
      // Written apart, one port: before, ZeroMQ's "Address already in use" (both bound).
      {{"--input", "tcp://*:22605", "--output", "tcp://127.0.0.1:22605"},
       "fabrikd: --output: 'tcp://127.0.0.1:22605' is also the input's endpoint "
       "('tcp://*:22605', one port of this machine)"},
      {{"--config", wrapped_path},
       wrapped_path + ": at /output/endpoint: port '70000' of 'tcp://127.0.0.1:70000' is out of "
                      "range"},
      // An address of no interface here (TEST-NET-1): the option's fault, not the config's.
      // Before: "config error: <embedded>/default.json: at /input/endpoint: cannot bind".
      {{"--input", "tcp://192.0.2.1:22606"},
       "fabrikd: --input: cannot bind the input socket to 'tcp://192.0.2.1:22606'"},
      {{"--config", unbindable_path},
       unbindable_path + ": at /output/endpoint: cannot bind the output socket to "
                         "'tcp://192.0.2.1:22607'"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> args = {kFabrikd};
    args.insert(args.end(), c.args.begin(), c.args.end());
    Process p(args);
    CAPTURE(c.args);
    CHECK(p.wait(5s) == 2);
    CHECK_THAT(p.stderr_text(), Catch::Contains(c.expected) && Catch::Contains("Fix: "));
  }
}

TEST_CASE("A taken port names the fix of a second fabrikd and of a program to connect to",
          "[fabrikd][cli]") {
  // Said only "choose another port": a daemon meant to connect to a source that binds (a
  // bridge, `fabrik replay --bind`) was not told so.
  const int holder = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  REQUIRE(holder >= 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t n = sizeof a;
  REQUIRE(bind(holder, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  REQUIRE(listen(holder, 1) == 0);
  REQUIRE(getsockname(holder, reinterpret_cast<sockaddr*>(&a), &n) == 0);
  const std::string taken = "tcp://127.0.0.1:" + std::to_string(ntohs(a.sin_port));
  json c = good_config("taken");
  c["output"]["endpoint"] = taken;
  const std::string config_path = write_file("taken.json", c.dump());
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{kFabrikd, "--input", taken},
       "choose another port here or with --input, or if the program that sends the markers "
       "binds it, connect to it: write connect: before it"},
      {{kFabrikd, "--input", "tcp://*:" + std::to_string(ntohs(a.sin_port))},
       "connect to it: write connect: before it, with its host's address for the wildcard"},
      {{kFabrikd, "--output", "ws://*:" + std::to_string(ntohs(a.sin_port)) + "/poses"},
       "connect to it: write connect: before it, with its host's address for the wildcard"},
      {{kFabrikd, "--config", config_path},
       "choose another port here or with --output, or if the program that takes the poses "
       "binds it, connect to it: use \"mode\": \"connect\""}};
  for (const auto& [args, fix] : cases) {
    Process p(args);
    CAPTURE(args);
    CHECK(p.wait(5s) == 2);
    CHECK_THAT(p.stderr_text(), Catch::Contains("the port is taken") && Catch::Contains(fix));
  }
  close(holder);
}

TEST_CASE("Bytes that are not UTF-8 in arguments and config files reach stderr as escapes",
          "[fabrikd][cli][robustness]") {
  const std::string bad_json = write_file("bad\xfe.json", "{\"format\": \"\xff");
  const std::vector<std::vector<std::string>> cases = {
      {"--input", "tcp://127.0.0.1:\xff"},
      {"--config", bad_json},
      {"--config", "/nonexistent/\xff.json"},
      {"--log-level", "\xff"},  // CLI11's own message quotes it
  };
  for (const std::vector<std::string>& c : cases) {
    std::vector<std::string> args = {kFabrikd};
    args.insert(args.end(), c.begin(), c.end());
    Process p(args);
    CAPTURE(c);
    const std::optional<int> code = p.wait(5s);
    CHECK(code.has_value());
    if (!code) continue;
    const std::string& err = p.stderr_text();
    CAPTURE(err);
    CHECK_THAT(err, Catch::Contains("\\xff"));
    for (const char raw : {'\xff', '\xfe', '\x1b'}) CHECK(err.find(raw) == std::string::npos);
  }
  // An ipc path is ZeroMQ's business and binds: the log line that names it is escaped.
  const std::string ipc = "ipc://" + (temp_dir() / "in\xff\x1b[2J").string();
  Process running({kFabrikd, "--input", ipc, "--output", "ipc://" + (temp_dir() / "out").string()});
  REQUIRE(running.wait_for_output("markers in on", 5s));
  REQUIRE(running.wait_for_output("markers tracked", 1s));
  CHECK_THAT(running.stderr_text(), Catch::Contains("in\\xff\\x1b[2J"));
  for (const char raw : {'\xff', '\x1b'})
    CHECK(running.stderr_text().find(raw) == std::string::npos);
  running.signal(SIGTERM);
  CHECK(running.wait(1s) == 0);
}
