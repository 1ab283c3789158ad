// `fabrik view`: fabrikd's `pose`, `stats` and `model` topics pushed to browsers over a
// WebSocket, and the page's files over HTTP (Boost.Beast). Two threads: one ZeroMQ SUB thread
// that checks each payload once (a pose is decoded only when a client is due one) and keeps
// only the newest of each topic, and one Asio thread for every HTTP and WebSocket connection. Per client: newest pose wins, at most `rate_hz`
// poses a second, one write in flight; what arrives while a write is in flight is dropped
// for that client (counted), so a slow browser costs nothing but its own frames.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>
#include <zmq.hpp>

namespace fabrik::view {

struct ViewOptions {
  std::string pose_endpoint = "tcp://127.0.0.1:5556";  // connected, as `fabrik watch` does
  bool pose_bind =
      false;  // bound instead (fabrikd's output connects to the view: `--pose bind:EP`)
  // A multi-subject fabrikd's subject: its poses on `pose/NAME`, its model on `model/NAME`
  // (empty: plain `pose` and `model`).
  std::string subject;
  std::string listen_host = "127.0.0.1";
  unsigned short listen_port = 8080;  // 0: any free port (see ViewServer::port)
  double rate_hz = 60.0;              // poses per second per client, at most
  int max_clients = 16;  // WebSocket clients; one more is sent a status "rejected" and closed
  int max_connections = 64;           // TCP connections in all (HTTP ones included)
  std::string web_root;               // the page's files (src/view/web)
  std::string three_root = "/usr/share/javascript/three";
  double stall_after_s = 2.0;         // no pose this long: "stalled"
  double status_period_s = 1.0;       // a status message at least this often
  std::size_t max_header_bytes = 8192;
  std::size_t max_ws_message_bytes = 4096;  // inbound; a larger message closes the client
  double request_timeout_s = 10.0;   // an HTTP request (or the WebSocket handshake) within this
  double ws_idle_timeout_s = 30.0;   // no frame (nor pong) from a client this long: closed
  std::size_t max_payload_bytes = 1 << 20;  // larger ZeroMQ messages are dropped by ZeroMQ
  // Offline: serve this `trial` message (and no subscription) instead.
  std::shared_ptr<const std::string> trial_message;
  std::string trial_note;  // the status message's text in trial mode
  // Called on the SUB thread with each pose's frame number as it arrives (benchmarks); may be
  // empty.
  std::function<void(std::uint64_t frame)> on_pose;
  // Called once on the SUB thread with what the terminal should hear (poses arrive for
  // subjects while the view waits on plain `pose`); may be empty.
  std::function<void(const std::string& text)> on_notice;
};

// Per WebSocket client, as the Asio thread last saw it.
struct ClientCounters {
  std::uint64_t poses_sent = 0;
  std::uint64_t dropped = 0;  // poses that arrived while a write to it was in flight, not sent
  std::size_t in_flight_bytes = 0;  // the one message being written, if any
};

struct ViewCounters {
  std::uint64_t poses = 0, undecodable = 0;
  std::uint64_t rejected_clients = 0;  // WebSocket clients beyond max_clients, told and closed
  std::vector<ClientCounters> clients;
  nlohmann::json status;  // the last status message's data
};

class ViewServer {
 public:
  // Binds the listening socket and connects the subscriber; throws std::runtime_error (an
  // address in use, a bad endpoint) before any thread starts.
  ViewServer(zmq::context_t& context, ViewOptions options);
  ~ViewServer();  // stops
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  void start();
  void stop();
  unsigned short port() const;
  std::string url() const;  // http://HOST:PORT/
  bool loopback_only() const;  // listening on a loopback address: this machine only
  // --pose as given, or where it was bound (the port a wildcard chose).
  const std::string& pose_endpoint() const;
  // A snapshot taken on the Asio thread (waits at most `timeout`); empty clients on timeout.
  ViewCounters counters(std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));
  // CPU time of the server's own threads (SUB and Asio), seconds.
  double cpu_seconds() const;

  struct Impl;  // view_server.cpp's (its sessions reach it)

 private:
  std::shared_ptr<Impl> impl_;
};

// The address to open in a browser: http://HOST:PORT/, but for a wildcard --listen (0.0.0.0,
// ::), which no browser can open, `this_host` (the machine's name; empty: 127.0.0.1).
std::string url_to_open(const std::string& listen_host, unsigned short port,
                        const std::string& this_host);
bool is_wildcard_host(const std::string& listen_host);

// "HOST:PORT" (or "[v6]:PORT") -> host and port; std::invalid_argument otherwise.
std::pair<std::string, unsigned short> parse_listen(const std::string& text);

}  // namespace fabrik::view
