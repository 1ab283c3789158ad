#include "wire.hpp"

#include <cerrno>
#include <cmath>
#include <stdexcept>

#include "config/endpoint_check.hpp"
#include "transport/open_socket.hpp"
#include "transport/payload_document.hpp"

namespace fabrik::tools {

WireEncoding parse_wire_encoding(const std::string& name) {
  if (name == "json") return WireEncoding::json;
  if (name == "msgpack") return WireEncoding::msgpack;
  throw std::invalid_argument("unknown encoding '" + name + "': use json or msgpack");
}

const char* wire_encoding_name(WireEncoding encoding) {
  return encoding == WireEncoding::json ? "json" : "msgpack";
}

WireEncoding detect_encoding(std::string_view payload) {
  return wire::document_encoding(payload) == wire::PayloadEncoding::json ? WireEncoding::json
                                                                         : WireEncoding::msgpack;
}

nlohmann::json decode_payload(std::string_view payload) { return wire::decode_document(payload); }

std::string encode_payload(const nlohmann::json& doc, WireEncoding encoding) {
  if (encoding == WireEncoding::json) return doc.dump();
  std::string out;
  nlohmann::json::to_msgpack(doc, out);
  return out;
}

Endpoint tool_endpoint(const std::string& spec, bool bind, const char* option) {
  return endpoint_option(spec, bind ? SocketMode::bind : SocketMode::connect, option,
                         bind ? "--bind" : "");
}

void open_endpoint(zmq::socket_t& socket, const std::string& spec, bool bind, const char* option) {
  const Endpoint e = tool_endpoint(spec, bind, option);
  const auto failure =
      wire::open_socket(socket, e.address, e.mode,
                        {"", std::string("with ") + option, "leave out --bind",
                         "leave out --bind if the program holding it is the one to reach"});
  if (failure) throw std::invalid_argument(failure->message(option));
}

bool wait_readable(zmq::socket_t& socket, std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
  try {
    zmq::poll(&item, 1, timeout);
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    return false;
  }
  return (item.revents & ZMQ_POLLIN) != 0;
}

void receive_part(zmq::socket_t& socket, zmq::message_t& part) {
  for (;;) {
    try {
      if (socket.recv(part, zmq::recv_flags::none)) return;
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) throw;
    }
  }
}

void send_part(zmq::socket_t& socket, zmq::const_buffer part, zmq::send_flags flags) {
  for (;;) {
    try {
      if (socket.send(part, flags)) return;
      throw std::runtime_error("a message part could not be sent");  // dontwait, would block
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) throw;
    }
  }
}

bool receive_waiting(zmq::socket_t& socket, zmq::message_t& message) {
  try {
    return socket.recv(message, zmq::recv_flags::dontwait).has_value();
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
    return false;
  }
}

}  // namespace fabrik::tools
