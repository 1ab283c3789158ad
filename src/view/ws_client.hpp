// Clients of `fabrik view` for its tests and `fabrik bench view`:
// raw HTTP requests and a WebSocket client, every wait bounded (Asio's run_for).
#pragma once

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <optional>
#include <string>

namespace fabrik::view::client {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

struct HttpAnswer {
  int status = 0;  // 0: no answer (closed or timed out)
  std::string content_type, cache_control, content_length, body;
};

// Sends `raw` (a whole request, as bytes) and reads one response.
inline HttpAnswer raw_request(unsigned short port, const std::string& raw, bool head = false,
                              std::chrono::milliseconds timeout = std::chrono::milliseconds(3000)) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  HttpAnswer answer;
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.skip(head);
  parser.body_limit(64 << 20);
  stream.expires_after(timeout);
  stream.async_connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port),
                       [&](beast::error_code ec) {
                         if (ec) return;
                         net::async_write(stream, net::buffer(raw),
                                          [&](beast::error_code e, std::size_t) {
                                            if (e) return;
                                            http::async_read(stream, buffer, parser,
                                                             [&](beast::error_code r, std::size_t) {
                                                               if (r) return;
                                                               const auto& res = parser.get();
                                                               answer.status = res.result_int();
                                                               answer.content_type = std::string(res[http::field::content_type]);
                                                               answer.cache_control = std::string(res[http::field::cache_control]);
                                                               answer.content_length = std::string(res[http::field::content_length]);
                                                               answer.body = res.body();
                                                             });
                                          });
                       });
  ioc.run_for(timeout + std::chrono::milliseconds(500));
  return answer;
}

inline HttpAnswer get(unsigned short port, const std::string& target,
                      const std::string& method = "GET") {
  return raw_request(port,
                     method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
                     method == "HEAD");
}

// A WebSocket client of /ws with bounded reads.
class WsClient {
 public:
  // `receive_buffer`: SO_RCVBUF before connecting (small: a client that fills up at once).
  explicit WsClient(unsigned short port, std::string origin = "",
                    int receive_buffer = 0)
      : ws_(ioc_) {
    auto& socket = beast::get_lowest_layer(ws_).socket();
    socket.open(tcp::v4());
    if (receive_buffer > 0) socket.set_option(net::socket_base::receive_buffer_size(receive_buffer));
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(3));
    beast::error_code ec;
    bool done = false;
    beast::get_lowest_layer(ws_).async_connect(
        tcp::endpoint(net::ip::make_address("127.0.0.1"), port), [&](beast::error_code e) {
          if (e) {
            ec = e;
            done = true;
            return;
          }
          ws_.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
            if (!origin.empty()) req.set(http::field::origin, origin);
          }));
          ws_.async_handshake(response_, "127.0.0.1:" + std::to_string(port), "/ws",
                              [&](beast::error_code h) {
                                ec = h;
                                done = true;
                              });
        });
    ioc_.run_for(std::chrono::seconds(4));
    connected_ = done && !ec;
    status_ = response_.result_int();
    beast::get_lowest_layer(ws_).expires_never();
  }

  bool connected() const { return connected_; }
  int handshake_status() const { return status_; }  // 101 when accepted

  // The next message, or nothing (closed, error or timeout: the client is then unusable).
  std::optional<std::string> read(std::chrono::milliseconds timeout = std::chrono::milliseconds(3000)) {
    if (!connected_) return std::nullopt;
    beast::error_code ec;
    bool done = false;
    buffer_.clear();
    ws_.async_read(buffer_, [&](beast::error_code e, std::size_t) {
      ec = e;
      done = true;
    });
    ioc_.restart();
    ioc_.run_for(timeout);
    if (!done || ec) {
      last_error_ = done ? ec : beast::error::timeout;
      connected_ = false;
      beast::error_code ignored;
      beast::get_lowest_layer(ws_).socket().close(ignored);
      for (int i = 0; i < 50 && !done; ++i) {  // the handler holds this frame's locals
        ioc_.restart();
        ioc_.run_for(std::chrono::milliseconds(100));
      }
      return std::nullopt;
    }
    return beast::buffers_to_string(buffer_.data());
  }

  bool write(const std::string& text) {
    beast::error_code ec;
    bool done = false;
    ws_.text(true);
    ws_.async_write(net::buffer(text), [&](beast::error_code e, std::size_t) {
      ec = e;
      done = true;
    });
    ioc_.restart();
    ioc_.run_for(std::chrono::seconds(3));
    if (!done) {  // the handler holds this frame's locals: close, and let it run before returning
      last_error_ = beast::error::timeout;
      connected_ = false;
      beast::error_code ignored;
      beast::get_lowest_layer(ws_).socket().close(ignored);
      for (int i = 0; i < 50 && !done; ++i) {
        ioc_.restart();
        ioc_.run_for(std::chrono::milliseconds(100));
      }
    }
    return done && !ec;
  }

  void close() {
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
    connected_ = false;
  }

  beast::error_code last_error() const { return last_error_; }

 private:
  net::io_context ioc_;
  websocket::stream<beast::tcp_stream> ws_;
  websocket::response_type response_;
  beast::flat_buffer buffer_;
  bool connected_ = false;
  int status_ = 0;
  beast::error_code last_error_;
};

}  // namespace fabrik::view::client
