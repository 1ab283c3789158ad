#include "view_server.hpp"

#include <pthread.h>
#include <time.h>

#include <atomic>
#include <boost/asio.hpp>
#include <charconv>
#include <cstdio>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <fstream>
#include <future>
#include <iterator>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>
#include <zmq_addon.hpp>

#include "common/ascii_case.hpp"
#include "config/endpoint_check.hpp"
#include "stream_status.hpp"
#include "transport/open_socket.hpp"
#include "transport/payload_document.hpp"
#include "web_files.hpp"

namespace fabrik::view {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;
using Text = std::shared_ptr<const std::string>;
using nlohmann::json;

namespace {

// {"topic": TOPIC, "data": DATA} as text; strings that are not UTF-8 (a MessagePack peer can
// send any bytes) are written with U+FFFD instead of failing.
Text topic_message(const char* topic, const json& data) {
  return std::make_shared<const std::string>(
      std::string(R"({"topic":")") + topic + R"(","data":)" +
      data.dump(-1, ' ', false, json::error_handler_t::replace) + "}");
}

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// A Host header's (or an Origin's) host names this machine: localhost, or a loopback address
// (any of 127.0.0.0/8, as --listen may bind, or [::1]); a port after it is ignored.
bool is_loopback_name(std::string_view host) {
  if (host.size() > 1 && host.front() == '[') {
    const auto close = host.find(']');
    if (close == std::string_view::npos) return false;
    host = host.substr(1, close - 1);
  } else {
    host = host.substr(0, host.find(':'));
  }
  const std::string lower = ascii_lower(host);
  if (lower == "localhost") return true;
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(lower, ec);
  return !ec && address.is_loopback();
}

double thread_cpu_s(std::thread& t) {
  if (!t.joinable()) return 0.0;
  clockid_t id;
  timespec ts{};
  if (pthread_getcpuclockid(t.native_handle(), &id) != 0 || clock_gettime(id, &ts) != 0)
    return 0.0;
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// A pose payload checked without building it: well-formed JSON or MessagePack (the parser
// checks UTF-8 too), an object with an unsigned "frame" at its top level, nested at most
// kMaxDepth deep (so building and writing it later cannot exhaust the stack).
class PoseCheck : public json::json_sax_t {
 public:
  static constexpr int kMaxDepth = 32;
  std::optional<std::uint64_t> frame;
  std::string error;

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t v) override {
    if (frame_next_ && depth_ == 1 && v >= 0) frame = static_cast<std::uint64_t>(v);
    return value();
  }
  bool number_unsigned(number_unsigned_t v) override {
    if (frame_next_ && depth_ == 1) frame = v;
    return value();
  }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(); }
  bool key(string_t& k) override {
    frame_next_ = depth_ == 1 && k == "frame";
    return true;
  }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(); }
  bool end_array() override { return close(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    error = e.what();
    return false;
  }

 private:
  bool value() {
    frame_next_ = false;
    return true;
  }
  bool open() {
    frame_next_ = false;
    if (++depth_ > kMaxDepth) {
      error = "nested deeper than " + std::to_string(kMaxDepth);
      return false;
    }
    return true;
  }
  bool close() {
    --depth_;
    return true;
  }
  int depth_ = 0;
  bool frame_next_ = false;
};

// One TCP connection counted while this lives (moved from the HTTP session to the WebSocket
// session that takes its stream over).
class ConnectionSlot {
 public:
  explicit ConnectionSlot(int* count) : count_(count) { ++*count_; }
  ConnectionSlot(ConnectionSlot&& o) noexcept : count_(std::exchange(o.count_, nullptr)) {}
  ConnectionSlot& operator=(ConnectionSlot&&) = delete;
  ~ConnectionSlot() {
    if (count_) --*count_;
  }

 private:
  int* count_;
};

}  // namespace

class WsSession;
class HttpSession;

// The full check (PoseCheck) of a pose; throws std::runtime_error with the reason.
std::optional<std::uint64_t> check_pose(std::string_view payload, bool msgpack);
// The same check of any document, frame or not.
void check_document(std::string_view payload, bool msgpack);

// The newest pose as it came (checked, not decoded): made into a message only when a client
// is due one.
struct PosePayload {
  std::string bytes;
  bool msgpack = false;
  bool checked = false;  // fully (PoseCheck); JSON only at its first send
  double view_unix_ms = 0;  // when it arrived here (wall clock): the page measures view -> paint
};

// The pose's message: its envelope carries view_ms, the arrival time at the view.
std::string pose_envelope(const std::string& data, double view_unix_ms) {
  char stamp[48];
  const int n = std::clamp(std::snprintf(stamp, sizeof stamp, R"(,"view_ms":%.3f})", view_unix_ms), 0,
                           static_cast<int>(sizeof stamp) - 1);
  std::string message = R"({"topic":"pose","data":)";
  message.reserve(message.size() + data.size() + static_cast<std::size_t>(n));
  return message.append(data).append(stamp, static_cast<std::size_t>(n));
}

// The cheap check of a JSON pose on arrival (a full parse of every pose at 1 kHz would be most
// of the view's CPU): an object that ends where it should, with a "frame" number.
std::optional<std::uint64_t> quick_json_frame(std::string_view p) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!p.empty() && is_space(p.back())) p.remove_suffix(1);
  if (p.empty() || p.back() != '}') return std::nullopt;
  const auto key = p.find("\"frame\"");
  if (key == std::string_view::npos) return std::nullopt;
  std::size_t i = key + 7;
  while (i < p.size() && is_space(p[i])) ++i;
  if (i >= p.size() || p[i] != ':') return std::nullopt;
  ++i;
  while (i < p.size() && is_space(p[i])) ++i;
  std::uint64_t frame = 0;
  if (std::from_chars(p.data() + i, p.data() + p.size(), frame).ec != std::errc()) return std::nullopt;
  return frame;
}

struct ViewServer::Impl {
  explicit Impl(ViewOptions options)
      : o(std::move(options)),
        files(o.web_root, o.three_root),
        stream_status(o.stall_after_s, o.trial_message ? "the trial" : source_name()),
        pose_topic_text(pose_topic()),
        model_topic_text(model_topic()) {}

  std::string source_name() const {
    return o.subject.empty() ? o.pose_endpoint : o.pose_endpoint + " on topic " + pose_topic();
  }
  std::string pose_topic() const { return o.subject.empty() ? "pose" : "pose/" + o.subject; }
  std::string model_topic() const { return o.subject.empty() ? "model" : "model/" + o.subject; }

  ViewOptions o;
  WebFiles files;
  bool loopback = true;

  // Shared between the SUB thread and the Asio thread (under `m`): the newest of each topic.
  std::mutex m;
  std::shared_ptr<const PosePayload> pose;
  std::uint64_t pose_seq = 0, stats_seq = 0, model_seq = 0;
  Text stats, model;
  StreamStatus stream_status;
  const std::string pose_topic_text, model_topic_text;  // what receive() compares with
  std::atomic<bool> notify_pending{false}, stopping{false};
  bool subjects_noticed = false;  // the SUB thread's: on_notice called
  // Sessions that wait for a new pose with their rate window open, and sessions with a write
  // in flight (whose drops are counted): a pose wakes the Asio thread only when one of them
  // exists. A session waiting for its rate window pulls the newest pose when its timer fires.
  std::atomic<int> hungry{0}, writing{0};

  // The Asio thread's own (declared before the io_context: sessions outlive its handlers).
  int connections = 0;
  int ws_clients = 0;  // WebSocket sessions, upgrading ones included (the --max-clients count)
  std::set<WsSession*> sessions;
  std::uint64_t rejected_clients = 0;
  // What the sessions send, as last copied from the shared state.
  std::shared_ptr<const PosePayload> io_pose;
  std::uint64_t io_pose_seq = 0, io_stats_seq = 0, io_model_seq = 0, io_status_seq = 0;
  Text io_stats, io_model, io_status;
  json io_status_data;
  Text pose_text;  // io_pose as a message, made once, when a client first needs it
  std::uint64_t pose_text_seq = 0;
  std::string last_stream;
  Clock::time_point last_status_sent{};

  net::io_context ioc{1};
  tcp::acceptor acceptor{ioc};
  net::steady_timer status_timer{ioc}, accept_retry{ioc};
  std::optional<zmq::socket_t> sub;
  std::thread io_thread, sub_thread;

  void notify();
  void refresh();
  bool pose_waiting();  // a pose newer than the Asio thread's copy
  void on_news();
  void tick_status();    // update_status, then again on a timer
  void update_status();  // a new status to every client if it changed or is due
  void do_accept();
  void sub_loop();
  void receive(std::vector<zmq::message_t>& parts);
  bool host_allowed(const http::request<http::empty_body>& req) const;
  Text pose_message(std::uint64_t& seq);
};

// A WebSocket client: model, status, stats and the newest pose, one write at a time.
class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  // `rejected`: one client too many, told so (a status the page shows) and closed; it is not
  // counted among the clients.
  WsSession(ViewServer::Impl& impl, beast::tcp_stream&& stream, ConnectionSlot&& slot,
            bool rejected = false)
      : impl_(impl),
        ws_(std::move(stream)),
        timer_(ws_.get_executor()),
        slot_(std::move(slot)),
        rejected_(rejected) {
    if (!rejected_) ++impl_.ws_clients;
  }
  ~WsSession() {
    if (!rejected_) --impl_.ws_clients;
    impl_.sessions.erase(this);
    if (hungry_) impl_.hungry.fetch_sub(1);
    if (writing_) impl_.writing.fetch_sub(1);
  }

  void start(http::request<http::empty_body> req) {
    beast::get_lowest_layer(ws_).expires_never();  // the stream's own timeouts from here
    websocket::stream_base::timeout t{};
    t.handshake_timeout = seconds(impl_.o.request_timeout_s);
    t.idle_timeout = seconds(impl_.o.ws_idle_timeout_s);
    t.keep_alive_pings = true;
    ws_.set_option(t);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "fabrik-view"); }));
    ws_.read_message_max(impl_.o.max_ws_message_bytes);
    ws_.text(true);
    ws_.async_accept(req, beast::bind_front_handler(&WsSession::on_accept, shared_from_this()));
  }

  void on_news() {
    if (hungry_) {
      hungry_ = false;
      impl_.hungry.fetch_sub(1);
    }
    if (!open_) return;
    const std::uint64_t fresh = impl_.io_pose_seq - seen_;
    seen_ = impl_.io_pose_seq;
    // Only what it would have been sent, but for the write in flight, counts as dropped.
    if (writing_ && Clock::now() >= next_allowed_) busy_ += fresh;
    pump();
  }

  void close_now() {
    open_ = false;
    timer_.cancel();
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(ws_).socket().close(ec);
  }

  ClientCounters counters() const {
    return {sent_, dropped_ + (writing_ ? busy_ : 0), out_ ? out_->size() : 0};
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) return;
    if (rejected_) return reject();
    open_ = true;
    impl_.sessions.insert(this);
    impl_.refresh();
    seen_ = impl_.io_pose_seq;
    pose_sent_ = impl_.io_pose_seq > 0 ? impl_.io_pose_seq - 1 : 0;  // the newest one is due
    next_allowed_ = Clock::now();
    do_read();
    impl_.update_status();  // its first status counts it among the clients
    pump();
  }

  // A 503 on the upgrade is invisible to a page's script: the page is told why in a status,
  // then the view closes ("try again later": the page retries as after any close).
  void reject() {
    const int max = impl_.o.max_clients;
    out_ = topic_message("status", json{{"stream", "rejected"},
                                        {"message", "too many viewers (max " + std::to_string(max) +
                                                        "): close another page of this fabrik "
                                                        "view (or start it with a higher "
                                                        "--max-clients); retrying"},
                                        {"clients", impl_.ws_clients},
                                        {"max_clients", max}});
    ws_.async_write(net::buffer(*out_), [self = shared_from_this()](beast::error_code ec,
                                                                    std::size_t) {
      if (ec) return self->close_now();
      self->ws_.async_close(websocket::close_code::try_again_later, [self](beast::error_code) {});
    });
  }

  // The page sends nothing the view needs; reading keeps pings, pongs and close working and
  // a message above read_message_max fails (and closes) the connection.
  void do_read() {
    ws_.async_read(in_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->open_ = false;
        self->timer_.cancel();
        return;
      }
      self->in_.consume(self->in_.size());
      self->do_read();
    });
  }

  void pump() {
    if (!open_ || writing_) return;
    Text msg;
    if (impl_.o.trial_message && !trial_sent_) {
      msg = impl_.o.trial_message;
      trial_sent_ = true;
    } else if (impl_.io_model_seq > model_sent_) {
      msg = impl_.io_model;
      model_sent_ = impl_.io_model_seq;
    } else if (impl_.io_status_seq > status_sent_) {
      msg = impl_.io_status;
      status_sent_ = impl_.io_status_seq;
    } else if (impl_.io_stats_seq > stats_sent_) {
      msg = impl_.io_stats;
      stats_sent_ = impl_.io_stats_seq;
    } else if (impl_.io_pose_seq > pose_sent_) {
      const Clock::time_point now = Clock::now();
      if (now < next_allowed_) {
        arm_timer();
        return;
      }
      // On time: keep the grid (no drift below the rate); late by a period or more: restart
      // it, so a late send is never followed by a burst.
      const Clock::duration period = seconds(1.0 / impl_.o.rate_hz);
      const Clock::time_point window = next_allowed_;
      next_allowed_ = now - next_allowed_ < period ? next_allowed_ + period : now + period;
      std::uint64_t seq = 0;
      msg = impl_.pose_message(seq);
      pose_sent_ = seq;
      if (!msg) {  // garbage found at its first send: counted; wait for the next pose
        next_allowed_ = window;
        return pump();
      }
      ++sent_;
      if (busy_ > 0) dropped_ += busy_ - 1;  // the newest of them is this one
      busy_ = 0;
    } else if (Clock::now() < next_allowed_) {
      arm_timer();  // it pulls the newest pose when the window opens
    } else if (!hungry_) {
      hungry_ = true;  // due, and nothing new: the next pose wakes this thread
      impl_.hungry.fetch_add(1);
      // A pose that landed before the count rose woke nobody: look again.
      if (impl_.pose_waiting()) impl_.notify();
    }
    if (!msg) return;
    write(std::move(msg));
  }

  void arm_timer() {
    if (timer_armed_) return;
    timer_armed_ = true;
    timer_.expires_at(next_allowed_);
    timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      self->timer_armed_ = false;
      if (ec) return;
      self->impl_.refresh();
      self->pump();
    });
  }

  void write(Text msg) {
    writing_ = true;
    impl_.writing.fetch_add(1);
    seen_ = impl_.io_pose_seq;
    out_ = std::move(msg);
    ws_.async_write(net::buffer(*out_),
                    [self = shared_from_this()](beast::error_code ec, std::size_t) {
                      self->writing_ = false;
                      self->impl_.writing.fetch_sub(1);
                      self->out_.reset();
                      if (ec) {
                        self->close_now();
                        return;
                      }
                      self->pump();
                    });
  }

  ViewServer::Impl& impl_;
  websocket::stream<beast::tcp_stream> ws_;
  net::steady_timer timer_;
  ConnectionSlot slot_;
  beast::flat_buffer in_;
  Text out_;
  bool open_ = false, writing_ = false, timer_armed_ = false, trial_sent_ = false, hungry_ = false;
  bool rejected_ = false;
  std::uint64_t seen_ = 0, pose_sent_ = 0, model_sent_ = 0, status_sent_ = 0, stats_sent_ = 0;
  std::uint64_t sent_ = 0, dropped_ = 0, busy_ = 0;
  Clock::time_point next_allowed_{};
};

// One HTTP connection: GET/HEAD of the file table, or the upgrade to /ws.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(ViewServer::Impl& impl, tcp::socket&& socket)
      : impl_(impl), stream_(std::move(socket)), slot_(&impl.connections) {}

  void run() { do_read(); }

 private:
  void do_read() {
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(impl_.o.max_header_bytes));
    stream_.expires_after(seconds(impl_.o.request_timeout_s));
    http::async_read(stream_, buffer_, *parser_,
                     beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec == http::error::end_of_stream || ec == beast::error::timeout ||
        ec == net::error::operation_aborted)
      return shut();
    if (ec == http::error::header_limit)
      return reply(http::status::request_header_fields_too_large, "request header too large\n",
                   true);
    if (ec == http::error::unexpected_body || ec == http::error::body_limit) {
      // A POST or PUT with its body: refused for its method, the body left unread.
      const http::verb method = parser_->is_header_done() ? parser_->get().method() : http::verb::get;
      if (method != http::verb::get && method != http::verb::head)
        return reply(http::status::method_not_allowed, "GET or HEAD only\n", true);
      return reply(http::status::payload_too_large, "no request body expected\n", true);
    }
    if (ec) {
      if (ec.category() == http::make_error_code(http::error::bad_target).category()) {
        return reply(http::status::bad_request, "bad request\n", true);
      }
      return shut();
    }
    const http::request<http::empty_body>& req = parser_->get();
    head_ = req.method() == http::verb::head;
    version_ = req.version();
    keep_alive_ = req.keep_alive();
    if (req.method() != http::verb::get && !head_)
      return reply(http::status::method_not_allowed, "GET or HEAD only\n", true);
    if (!impl_.host_allowed(req))
      return reply(http::status::forbidden, "not from this machine's page\n", true);
    if (websocket::is_upgrade(req)) {
      if (req.target() != "/ws" || head_) return reply(http::status::not_found, "not found\n", true);
      const bool full = impl_.ws_clients >= impl_.o.max_clients;
      if (full) ++impl_.rejected_clients;
      std::make_shared<WsSession>(impl_, std::move(stream_), std::move(slot_), full)
          ->start(parser_->release());
      return;
    }
    if (req.target() == "/ws")
      return reply(http::status::upgrade_required, "a WebSocket upgrade is expected\n", false);
    const auto file = impl_.files.resolve(std::string_view(req.target().data(), req.target().size()));
    std::string body;
    if (file) {
      std::ifstream in(file->path, std::ios::binary);
      body.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      if (!in.good() && !in.eof()) return reply(http::status::not_found, "not found\n", false);
    }
    if (!file) return reply(http::status::not_found, "not found\n", false);
    res_ = {};
    res_.result(http::status::ok);
    res_.set(http::field::content_type, file->content_type);
    res_.set(http::field::cache_control, file->cache_control);
    send(std::move(body), false);
  }

  void reply(http::status status, const char* text, bool close) {
    res_ = {};
    res_.result(status);
    res_.set(http::field::content_type, "text/plain; charset=utf-8");
    res_.set(http::field::cache_control, "no-store");
    if (status == http::status::method_not_allowed) res_.set(http::field::allow, "GET, HEAD");
    if (status == http::status::upgrade_required)  // RFC 9110: a 426 names the protocol
      res_.set(http::field::upgrade, "websocket");
    send(text, close);
  }

  void send(std::string body, bool close) {
    res_.version(version_ ? version_ : 11);
    res_.set(http::field::server, "fabrik-view");
    res_.set("X-Content-Type-Options", "nosniff");
    close_after_ = close || !keep_alive_;
    res_.keep_alive(!close_after_);
    const std::size_t n = body.size();
    if (head_) {
      res_.body().clear();
      res_.content_length(n);
    } else {
      res_.body() = std::move(body);
      res_.prepare_payload();
    }
    stream_.expires_after(seconds(impl_.o.request_timeout_s));
    http::async_write(stream_, res_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec || self->close_after_) return self->shut();
      self->do_read();
    });
  }

  void shut() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
  }

  ViewServer::Impl& impl_;
  beast::tcp_stream stream_;
  ConnectionSlot slot_;
  beast::flat_buffer buffer_{16 * 1024};
  std::optional<http::request_parser<http::empty_body>> parser_;
  http::response<http::string_body> res_;
  bool head_ = false, keep_alive_ = false, close_after_ = false;
  unsigned version_ = 11;
};

bool ViewServer::Impl::host_allowed(const http::request<http::empty_body>& req) const {
  if (!loopback) return true;
  // Bound to this machine only: a page from elsewhere (DNS rebinding, a cross-site WebSocket)
  // names another host or origin.
  const auto host = req.find(http::field::host);
  if (host != req.end() && !is_loopback_name(std::string_view(host->value().data(), host->value().size())))
    return false;
  const auto origin = req.find(http::field::origin);
  if (origin != req.end()) {
    const std::string_view value(origin->value().data(), origin->value().size());
    const auto scheme = value.find("://");
    if (scheme == std::string_view::npos || !is_loopback_name(value.substr(scheme + 3)))
      return false;
  }
  return true;
}

Text ViewServer::Impl::pose_message(std::uint64_t& seq) {
  seq = io_pose_seq;
  if (pose_text_seq == io_pose_seq) return pose_text;  // null: that pose was garbage
  pose_text_seq = io_pose_seq;
  pose_text.reset();
  try {
    if (!io_pose->checked) check_pose(io_pose->bytes, false);
    if (io_pose->msgpack)  // checked: decodes
      pose_text = std::make_shared<const std::string>(pose_envelope(
          json::from_msgpack(io_pose->bytes).dump(-1, ' ', false, json::error_handler_t::replace),
          io_pose->view_unix_ms));
    else  // well-formed JSON, valid UTF-8: spliced in as it came
      pose_text = std::make_shared<const std::string>(pose_envelope(io_pose->bytes, io_pose->view_unix_ms));
  } catch (const std::exception& e) {
    const double t_s = std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
    std::lock_guard lock(m);
    stream_status.add_undecodable(t_s, "pose", e.what());
  }
  return pose_text;
}

// The depth-bounded SAX pass both checks share; throws with the reason.
PoseCheck checked_document(std::string_view payload, bool msgpack) {
  PoseCheck check;
  if (!json::sax_parse(payload.begin(), payload.end(), &check,
                       msgpack ? json::input_format_t::msgpack : json::input_format_t::json))
    throw std::runtime_error(std::string("bad ") + (msgpack ? "msgpack" : "json") +
                             " payload: " + check.error);
  return check;
}

void check_document(std::string_view payload, bool msgpack) {
  (void)checked_document(payload, msgpack);
}

std::optional<std::uint64_t> check_pose(std::string_view payload, bool msgpack) {
  const PoseCheck check = checked_document(payload, msgpack);
  if (!check.frame) throw std::runtime_error("a pose without a frame number");
  return check.frame;
}

void ViewServer::Impl::notify() {
  if (!notify_pending.exchange(true))
    net::post(ioc, [this] {
      notify_pending.store(false);
      on_news();
    });
}

bool ViewServer::Impl::pose_waiting() {
  std::lock_guard lock(m);
  return pose_seq != io_pose_seq;
}

void ViewServer::Impl::on_news() {
  refresh();
  for (WsSession* s : std::vector<WsSession*>(sessions.begin(), sessions.end())) s->on_news();
}

void ViewServer::Impl::refresh() {
  {
    std::lock_guard lock(m);
    io_pose = pose;
    io_pose_seq = pose_seq;
    if (stats_seq != io_stats_seq) io_stats = stats, io_stats_seq = stats_seq;
    if (model_seq != io_model_seq) io_model = model, io_model_seq = model_seq;
  }
}

void ViewServer::Impl::tick_status() {
  update_status();
  const double tick_s = std::clamp(std::min(o.status_period_s, o.stall_after_s) / 4, 0.01, 0.25);
  status_timer.expires_after(seconds(tick_s));
  status_timer.async_wait([this](beast::error_code ec) {
    if (!ec) tick_status();
  });
}

void ViewServer::Impl::update_status() {
  const Clock::time_point now = Clock::now();
  json data;
  {
    std::lock_guard lock(m);
    data = stream_status.status(std::chrono::duration<double>(now.time_since_epoch()).count(),
                                sessions.size());
  }
  if (o.trial_message) {
    data["stream"] = "ok";
    data["message"] = o.trial_note;
  }
  const std::string stream = data["stream"];
  // A new subject seen while waiting is news too: the page names it at once.
  const bool changed = stream != last_stream || data["clients"] != io_status_data["clients"] ||
                       data.value("subjects", json()) != io_status_data.value("subjects", json());
  if (changed || now - last_status_sent >= seconds(o.status_period_s) || !io_status) {
    io_status = topic_message("status", data);
    io_status_data = data;
    ++io_status_seq;
    last_stream = stream;
    last_status_sent = now;
    for (WsSession* s : std::vector<WsSession*>(sessions.begin(), sessions.end())) s->on_news();
  }
}

void ViewServer::Impl::do_accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (!acceptor.is_open()) return;
    if (ec) {  // out of file descriptors, say: try again shortly instead of spinning
      accept_retry.expires_after(std::chrono::milliseconds(50));
      accept_retry.async_wait([this](beast::error_code e) {
        if (!e) do_accept();
      });
      return;
    }
    if (connections >= o.max_connections) {
      beast::error_code ignored;
      socket.close(ignored);
    } else {
      std::make_shared<HttpSession>(*this, std::move(socket))->run();
    }
    do_accept();
  });
}

void ViewServer::Impl::receive(std::vector<zmq::message_t>& parts) {
  const double t_s =
      std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
  const std::string topic = parts.empty() ? std::string() : parts[0].to_string();
  if (parts.size() != 2) {
    std::lock_guard lock(m);
    stream_status.add_undecodable(t_s, topic, std::to_string(parts.size()) + " message parts, not 2");
  } else {
    try {
      const std::string_view payload = parts[1].to_string_view();
      if (topic == pose_topic_text) {
        const bool msgpack = wire::document_encoding(payload) == wire::PayloadEncoding::msgpack;
        const std::optional<std::uint64_t> frame =
            msgpack ? check_pose(payload, true) : quick_json_frame(payload);
        if (!frame) throw std::runtime_error("a pose without a frame number, or cut short");
        if (o.on_pose) o.on_pose(*frame);
        const double view_unix_ms = std::chrono::duration<double, std::milli>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count();
        auto p = std::make_shared<const PosePayload>(
            PosePayload{std::string(payload), msgpack, msgpack, view_unix_ms});
        {
          std::lock_guard lock(m);
          pose = std::move(p);
          ++pose_seq;
          stream_status.add_pose(t_s);
        }
        if (hungry.load() > 0 || writing.load() > 0) notify();
        return;
      } else if (topic == "stats" || topic == model_topic_text) {
        // Bounded nesting first: decoding and writing it back are recursive.
        check_document(payload,
                       wire::document_encoding(payload) == wire::PayloadEncoding::msgpack);
        const bool is_stats = topic == "stats";
        Text text = topic_message(is_stats ? "stats" : "model", wire::decode_document(payload));
        std::lock_guard lock(m);
        if (is_stats) {
          stats = std::move(text);
          ++stats_seq;
        } else if (!model || *model != *text) {
          model = std::move(text);
          ++model_seq;
        }
      } else if (o.subject.empty() && topic.starts_with("pose/")) {
        // A multi-subject fabrikd publishes no plain `pose`: say which subjects there are.
        std::string hint;
        {
          std::lock_guard lock(m);
          if (!stream_status.add_other_subject(topic.substr(5)) || subjects_noticed ||
              stream_status.poses() > 0)
            return;
          subjects_noticed = true;
          hint = stream_status.subjects_hint();
        }
        if (o.on_notice) o.on_notice(hint);
        return;
      } else {
        return;  // another topic under a subscribed prefix ("poses"): not ours
      }
    } catch (const std::exception& e) {
      std::lock_guard lock(m);
      stream_status.add_undecodable(t_s, topic, e.what());
    }
  }
  notify();
}

void ViewServer::Impl::sub_loop() {
  std::vector<zmq::message_t> parts;
  while (!stopping.load()) {
    try {
      parts.clear();  // a blocking receive (ZMQ_RCVTIMEO) looks at `stopping` between messages
      if (zmq::recv_multipart(*sub, std::back_inserter(parts))) receive(parts);
    } catch (const zmq::error_t&) {
      if (stopping.load()) break;  // the context is going away
    }
  }
}

ViewServer::ViewServer(zmq::context_t& context, ViewOptions options)
    : impl_(std::make_shared<Impl>(std::move(options))) {
  Impl& s = *impl_;
  if (!(s.o.rate_hz > 0.0)) throw std::invalid_argument("--rate-hz must be above 0");
  if (s.o.max_clients < 1) throw std::invalid_argument("--max-clients must be at least 1");
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(s.o.listen_host, ec);
  if (ec) throw std::invalid_argument("--listen: '" + s.o.listen_host + "' is not an IP address");
  s.loopback = address.is_loopback();
  const tcp::endpoint endpoint(address, s.o.listen_port);
  s.acceptor.open(endpoint.protocol(), ec);
  if (!ec) s.acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) s.acceptor.bind(endpoint, ec);
  if (!ec) s.acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec)
    throw std::runtime_error("cannot listen on " + s.o.listen_host + ":" +
                             std::to_string(s.o.listen_port) + ": " + ec.message());
  if (!s.o.trial_message) {
    require_usable_endpoint(s.o.pose_endpoint,
                            s.o.pose_bind ? SocketMode::bind : SocketMode::connect, "--pose");
    if (!s.o.pose_bind)
      if (const auto unknown = wire::unknown_host(s.o.pose_endpoint))
        throw std::invalid_argument(unknown->message("--pose"));
    s.sub.emplace(context, zmq::socket_type::sub);
    s.sub->set(zmq::sockopt::linger, 0);
    s.sub->set(zmq::sockopt::rcvtimeo, 50);
    s.sub->set(zmq::sockopt::rcvhwm, 100);  // 0.1 s at 1 kHz: newest wins, not a backlog
    s.sub->set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(s.o.max_payload_bytes));
    // Without --subject, `pose` also catches a multi-subject fabrikd's `pose/NAME` (named to
    // the user while no plain pose comes).
    for (const std::string& topic : {s.pose_topic(), std::string("stats"), s.model_topic()})
      s.sub->set(zmq::sockopt::subscribe, topic);
    const auto failure = wire::open_socket(
        *s.sub, s.o.pose_endpoint, s.o.pose_bind ? SocketMode::bind : SocketMode::connect,
        {"", "with --pose", "connect (leave out bind:)",
         "connect (leave out bind:) if fabrikd's output holds it"});
    if (failure) throw std::invalid_argument(failure->message("--pose"));
    if (s.o.pose_bind) {
      // A wildcard port ("tcp://127.0.0.1:*") is chosen by the system: name the port bound.
      s.o.pose_endpoint = s.sub->get(zmq::sockopt::last_endpoint);
      s.stream_status = StreamStatus(s.o.stall_after_s, s.source_name());
    }
  }
}

ViewServer::~ViewServer() { stop(); }

void ViewServer::start() {
  Impl& s = *impl_;
  if (s.io_thread.joinable()) return;
  s.do_accept();
  s.tick_status();
  s.io_thread = std::thread([&s] { s.ioc.run(); });
  if (s.sub) s.sub_thread = std::thread([&s] { s.sub_loop(); });
}

void ViewServer::stop() {
  Impl& s = *impl_;
  if (s.stopping.exchange(true)) return;
  if (s.sub_thread.joinable()) s.sub_thread.join();
  net::post(s.ioc, [&s] {
    beast::error_code ec;
    s.acceptor.close(ec);
    s.status_timer.cancel();
    s.accept_retry.cancel();
    for (WsSession* w : std::vector<WsSession*>(s.sessions.begin(), s.sessions.end()))
      w->close_now();
    s.ioc.stop();
  });
  if (s.io_thread.joinable()) s.io_thread.join();
  s.sub.reset();
}

unsigned short ViewServer::port() const { return impl_->acceptor.local_endpoint().port(); }

const std::string& ViewServer::pose_endpoint() const {
  return impl_->o.pose_endpoint;
}

bool ViewServer::loopback_only() const {
  return impl_->loopback;
}

std::string ViewServer::url() const {
  const std::string& h = impl_->o.listen_host;
  const bool v6 = h.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + h + "]" : h) + ":" + std::to_string(port()) + "/";
}

ViewCounters ViewServer::counters(std::chrono::milliseconds timeout) {
  Impl& s = *impl_;
  auto done = std::make_shared<std::promise<ViewCounters>>();
  auto result = done->get_future();
  net::post(s.ioc, [&s, done] {
    ViewCounters c;
    {
      std::lock_guard lock(s.m);
      c.poses = s.stream_status.poses();
      c.undecodable = s.stream_status.undecodable();
    }
    c.rejected_clients = s.rejected_clients;
    for (const WsSession* w : s.sessions) c.clients.push_back(w->counters());
    c.status = s.io_status_data;
    done->set_value(std::move(c));
  });
  if (result.wait_for(timeout) != std::future_status::ready) return {};
  return result.get();
}

double ViewServer::cpu_seconds() const {
  return thread_cpu_s(impl_->io_thread) + thread_cpu_s(impl_->sub_thread);
}

bool is_wildcard_host(const std::string& listen_host) {
  beast::error_code ec;
  const net::ip::address a = net::ip::make_address(listen_host, ec);
  return !ec && a.is_unspecified();
}

std::string url_to_open(const std::string& listen_host, unsigned short port,
                        const std::string& this_host) {
  const std::string h = !is_wildcard_host(listen_host) ? listen_host
                        : this_host.empty()            ? "127.0.0.1"
                                                       : this_host;
  const bool v6 = h.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + h + "]" : h) + ":" + std::to_string(port) + "/";
}

std::pair<std::string, unsigned short> parse_listen(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon + 1 == text.size())
    throw std::invalid_argument("--listen: '" + text + "' is not HOST:PORT");
  std::string host = text.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  if (iequals(host, "localhost")) host = "127.0.0.1";  // the name every browser knows
  const std::string port = text.substr(colon + 1);
  unsigned long value = 0;
  std::size_t used = 0;
  try {
    value = std::stoul(port, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != port.size() || value > 65535 || host.empty())
    throw std::invalid_argument("--listen: '" + text + "' is not HOST:PORT (port 0-65535)");
  return {host, static_cast<unsigned short>(value)};
}

}  // namespace fabrik::view
