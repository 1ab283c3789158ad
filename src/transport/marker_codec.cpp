#include "marker_codec.hpp"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "json_sax_reader.hpp"
#include "marker_frame_fill.hpp"
#include "marker_json_fast.hpp"
#include "marker_msgpack_fast.hpp"
#include "wire_writer.hpp"

namespace fabrik::wire {

namespace {

using nlohmann::json;

// Deepest nesting a valid frame needs is 3 (frame > markers > [x, y, z]);
// extra top-level fields may nest a little, anything deeper is refused.
constexpr int kMaxDepth = 8;
constexpr std::size_t kMaxUnknownNames = 8;
constexpr std::size_t kMaxUnknownNameBytes = 64;  // longer names are cut in lists and messages

// SAX handler: a small state machine over the token stream. Final, so the
// JSON reader (a template on the handler) calls it without virtual dispatch.
class FrameSax final : public nlohmann::json_sax<json> {
 public:
  FrameSax(MarkerNameIndex& index, const MarkerNameIndex& sensor_index, MarkerFrame& out,
           std::string& error, std::string& name_scratch)
      : index_(index),
        sensor_index_(sensor_index),
        out_(out),
        error_(error),
        marker_name_(name_scratch) {}

  bool has_frame = false;
  double m_per_unit = 0.0;  // 0: not given

  bool null() override {
    if (state_ == State::marker_value) return end_marker_value();
    if (state_ == State::sensor_value) return to(State::sensor_key);  // occluded
    return scalar("null");
  }
  bool boolean(bool) override { return scalar("a boolean"); }
  bool number_integer(number_integer_t v) override {
    if (state_ == State::frame)
      return fail("\"frame\" must be an unsigned integer, got " + std::to_string(v));
    return number(static_cast<double>(v));
  }
  bool number_unsigned(number_unsigned_t v) override {
    if (state_ == State::frame) {
      out_.frame = v;
      has_frame = true;
      return top_value_done();
    }
    return number(static_cast<double>(v));
  }
  bool number_float(number_float_t v, const string_t& text) override {
    if (state_ == State::frame)
      // The parser gives an integer past 2^64 - 1 as a float: too large, not a fraction.
      return fail(!text.empty() && text.find_first_not_of("0123456789") == string_t::npos
                      ? "\"frame\" must be an unsigned integer below 2^64, got a larger one"
                      : "\"frame\" must be an unsigned integer, got a float");
    return number(v);
  }
  bool string(string_t& s) override {
    if (state_ == State::units) {
      m_per_unit = metres_per_unit(s);
      if (m_per_unit == 0.0) return fail("\"units\" must be \"mm\" or \"m\", got \"" + s + "\"");
      return top_value_done();
    }
    if (state_ == State::subject) {
      set_frame_subject(out_, s);
      return top_value_done();
    }
    return scalar("a string");
  }
  bool binary(binary_t&) override { return scalar("binary data"); }

  bool start_object(std::size_t) override {
    if (!enter()) return false;
    if (state_ == State::start) return to(State::top_key);
    if (state_ == State::markers) {
      marker_position_ = 0;  // the name hints count positions from each map's start
      return to(State::marker_key);
    }
    if (state_ == State::orientations) return to(State::sensor_key);
    return skipping() || scalar("an object");
  }
  bool end_object() override {
    --depth_;
    if (state_ == State::skip) return end_skip();
    if (state_ == State::marker_key || state_ == State::sensor_key) {
      state_ = State::top_key;
      return true;
    }
    if (state_ == State::top_key) {
      state_ = State::done;
      return true;
    }
    return true;
  }
  bool start_array(std::size_t) override {
    if (!enter()) return false;
    if (state_ == State::marker_value) {
      coord_ = 0;
      return to(State::coords);
    }
    if (state_ == State::sensor_value) {
      coord_ = 0;
      return to(State::quat);
    }
    return skipping() || scalar("an array");
  }
  bool end_array() override {
    --depth_;
    if (state_ == State::skip) return end_skip();
    if (state_ == State::coords) {
      if (coord_ != 3 && coord_ != 4)
        return fail("marker \"" + marker_name_ + "\": expected [x, y, z] or [x, y, z, confidence], got " +
                    std::to_string(coord_) + " numbers");
      if (marker_ >= 0) set_marker(out_, marker_, p_, coord_ == 4 ? &c_ : nullptr);
      state_ = State::marker_key;
    }
    if (state_ == State::quat) {
      if (sensor_ >= 0) end_quaternion();
      state_ = State::sensor_key;
    }
    return true;
  }
  bool key(string_t& k) override {
    if (state_ == State::top_key) {
      if (k == "frame")
        state_ = State::frame;
      else if (k == "time")
        state_ = State::time;
      else if (k == "units")
        state_ = State::units;
      else if (k == "stamp_us")
        state_ = State::stamp;
      else if (k == "markers")
        state_ = State::markers;
      else if (k == "orientations")
        state_ = State::orientations;
      else if (k == "subject")
        state_ = State::subject;
      else
        state_ = State::top_skip_value;  // additions to the contract are allowed
      return true;
    }
    if (state_ == State::marker_key) {
      marker_ = count_marker(index_, marker_position_++, k, out_);
      // Kept for messages only, cut to its reserved capacity: no allocation.
      marker_name_.assign(k, 0, std::min(k.size(), marker_name_.capacity()));
      state_ = State::marker_value;
      return true;
    }
    if (state_ == State::sensor_key) {
      sensor_ = sensor_index_.find(k);
      if (sensor_ < 0) {
        ++out_.unknown_sensor_count;
        list_unknown_name(out_.unknown_sensor_names, out_.unknown_sensors_listed, k);
      } else {
        out_.sensor_visible[sensor_] = 0;  // until a usable quaternion arrives
      }
      marker_name_.assign(k, 0, std::min(k.size(), marker_name_.capacity()));
      state_ = State::sensor_value;
      return true;
    }
    return true;  // keys inside skipped values
  }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::detail::exception& e) override {
    if (error_.empty()) {
      // The library's own reason, without its "[json.exception.parse_error.N] parse error at
      // byte N: " prefix (the byte is said once, here).
      std::string_view why = e.what();
      if (why.starts_with("[json.exception"))
        if (const std::size_t close = why.find("] "); close != std::string_view::npos)
          why.remove_prefix(close + 2);
      if (why.starts_with("parse error"))
        if (const std::size_t colon = why.find(": "); colon != std::string_view::npos)
          why.remove_prefix(colon + 2);
      error_ = "not valid " + std::string(format_) + " at byte " + std::to_string(position) + ": " +
               std::string(why);
    }
    return false;
  }
  const char* format_ = "JSON";
  double quaternion_tolerance_ = 0.01;

 private:
  enum class State {
    start,
    top_key,
    frame,
    stamp,
    time,
    units,
    markers,
    marker_key,
    marker_value,
    coords,
    orientations,
    subject,
    sensor_key,
    sensor_value,
    quat,
    top_skip_value,
    skip,
    done
  };

  bool to(State next) {
    state_ = next;
    return true;
  }
  bool enter() {  // an object or array begins
    if (++depth_ > kMaxDepth) return fail("nesting deeper than " + std::to_string(kMaxDepth));
    return true;
  }
  // Inside an unknown top-level value (additions to the contract): skipped whole.
  bool skipping() {
    if (state_ == State::skip) return true;
    if (state_ != State::top_skip_value) return false;
    skip_depth_ = depth_;
    return to(State::skip);
  }
  bool number(double v) {
    switch (state_) {
      case State::time:
        if (!std::isfinite(v)) return fail("\"time\" must be a finite number");
        out_.time_s = v;
        out_.has_time = true;
        return top_value_done();
      case State::stamp:
        if (!std::isfinite(v)) return fail("\"stamp_us\" must be a finite number");
        out_.stamp_us = v;
        out_.has_stamp = true;
        return top_value_done();
      case State::coords:
        if (coord_ >= 4)
          return fail("marker \"" + marker_name_ + "\": more than 4 values (x, y, z, confidence)");
        if (coord_ == 3)
          c_ = v;
        else
          p_[coord_] = v;
        ++coord_;
        return true;
      case State::quat:  // a wrong length is an occlusion (end_quaternion), not an error
        if (coord_ < 4) q_[coord_] = v;
        ++coord_;
        return true;
      case State::skip:
        return true;
      case State::top_skip_value:
        return top_value_done();
      default:
        return scalar("a number");
    }
  }
  // A known sensor's [w, x, y, z]: usable (four finite numbers, unit within
  // the tolerance) or an occlusion, counted.
  void end_quaternion() {
    const Eigen::Quaterniond q(q_[0], q_[1], q_[2], q_[3]);
    if (coord_ == 4 && q.coeffs().allFinite() &&
        std::abs(q.norm() - 1.0) <= quaternion_tolerance_) {
      out_.q_sensor[sensor_] = q.normalized();
      out_.sensor_visible[sensor_] = 1;
    } else {
      ++out_.rejected_orientations;
    }
  }
  bool end_marker_value() {  // null: occluded
    if (marker_ >= 0) out_.visible[marker_] = 0;
    state_ = State::marker_key;
    return true;
  }
  bool top_value_done() {
    state_ = State::top_key;
    return true;
  }
  bool end_skip() {
    if (depth_ < skip_depth_) state_ = State::top_key;
    return true;
  }
  // A scalar where it does not belong, or an allowed one in skipped content.
  bool scalar(const char* what) {
    if (state_ == State::skip) return true;
    if (state_ == State::top_skip_value) return top_value_done();
    switch (state_) {
      case State::start:
        return fail(std::string("a marker frame must be an object, got ") + what);
      case State::frame:
        return fail(std::string("\"frame\" must be an unsigned integer, got ") + what);
      case State::time:
        return fail(std::string("\"time\" must be a number, got ") + what);
      case State::stamp:
        return fail(std::string("\"stamp_us\" must be a number, got ") + what);
      case State::units:
        return fail(std::string("\"units\" must be \"mm\" or \"m\", got ") + what);
      case State::markers:
        return fail(std::string("\"markers\" must be an object, got ") + what);
      case State::orientations:
        return fail(std::string("\"orientations\" must be an object, got ") + what);
      case State::subject:
        return fail(std::string("\"subject\" must be a string, got ") + what);
      case State::sensor_value:
        return fail("orientation \"" + marker_name_ + "\" must be [w, x, y, z] or null, got " +
                    what);
      case State::quat:
        return fail("orientation \"" + marker_name_ + "\": components must be numbers, got " +
                    what);
      case State::marker_value:
        return fail("marker \"" + marker_name_ + "\" must be [x, y, z] or null, got " + what);
      case State::coords:
        return fail("marker \"" + marker_name_ + "\": coordinates must be numbers, got " + what);
      default:
        return fail(std::string("unexpected ") + what);
    }
  }
  bool fail(std::string message) {
    if (error_.empty()) error_ = std::move(message);
    return false;
  }

  MarkerNameIndex& index_;
  const MarkerNameIndex& sensor_index_;
  MarkerFrame& out_;
  std::string& error_;
  State state_ = State::start;
  int depth_ = 0, skip_depth_ = 0;
  int marker_ = -1, sensor_ = -1;
  std::size_t marker_position_ = 0;  // of the marker being read, among the frame's names
  std::string& marker_name_;  // the decoder's, so its buffer is reused (also sensor names)
  int coord_ = 0;
  Eigen::Vector3d p_{0, 0, 0};
  double c_ = 1.0;  // a marker's confidence, its 4th value
  double q_[4] = {0, 0, 0, 0};
};

// What a frame holds before its payload is read: nothing seen.
void start_frame(MarkerFrame& out) {
  out.frame = 0;
  out.has_time = false;
  out.time_s = 0.0;
  out.has_stamp = false;
  out.known_count = 0;
  out.unknown_count = 0;
  out.unknown_listed = 0;
  out.unknown_foreign = 0;
  out.rejected_count = 0;
  out.zero_count = 0;
  out.rejected_orientations = 0;
  out.unknown_sensor_count = 0;
  out.unknown_sensors_listed = 0;
  out.has_subject = false;
  out.subject.clear();
  std::fill(out.visible.begin(), out.visible.end(), 0);  // absent markers are occluded
  std::fill(out.confidence.begin(), out.confidence.end(), 1.0f);
  out.confidence_count = 0;
  std::fill(out.sensor_visible.begin(), out.sensor_visible.end(), 0);
}

}  // namespace

PayloadEncoding detect_encoding(std::span<const std::uint8_t> payload) {
  if (payload.empty()) return PayloadEncoding::json;
  const std::uint8_t b = payload[0];
  return (b >= 0x80 && b <= 0x8f) || b == 0xde || b == 0xdf ? PayloadEncoding::msgpack
                                                            : PayloadEncoding::json;
}

MarkerDecoder::MarkerDecoder(std::span<const std::string> names, double default_m_per_unit,
                             std::size_t max_payload_bytes, PlausibleMarkers plausible,
                             std::span<const std::string> sensor_names)
    : index_(names),
      sensor_index_(sensor_names),
      count_(static_cast<int>(names.size())),
      sensor_count_(static_cast<int>(sensor_names.size())),
      default_m_per_unit_(default_m_per_unit),
      max_payload_bytes_(max_payload_bytes),
      plausible_(plausible) {
  marker_name_.reserve(kMaxUnknownNameBytes);
  // Most frames take a fast path, so the full reader may first see
  // one when memory is short: its token buffer is grown here, not then.
  json_reader_.reserve(std::min<std::size_t>(max_payload_bytes_, 4096));
}

MarkerFrame MarkerDecoder::make_frame() const {
  MarkerFrame f;
  f.p_world_m.assign(count_, Eigen::Vector3d::Zero());
  f.visible.assign(count_, 0);
  f.confidence.assign(count_, 1.0f);
  f.unknown_names.resize(kMaxUnknownNames);
  for (std::string& name : f.unknown_names) name.reserve(kMaxUnknownNameBytes);
  f.q_sensor.assign(sensor_count_, Eigen::Quaterniond::Identity());
  f.sensor_visible.assign(sensor_count_, 0);
  f.unknown_sensor_names.resize(kMaxUnknownNames);
  for (std::string& name : f.unknown_sensor_names) name.reserve(kMaxUnknownNameBytes);
  f.subject.reserve(kMaxSubjectBytes);
  return f;
}

int MarkerDecoder::index_of(const std::string& name) const {
  return index_.find(name);
}

bool MarkerDecoder::decode(std::span<const std::uint8_t> payload, MarkerFrame& out,
                           std::string& error) const {
  error.clear();
  if (payload.empty()) {
    error = "empty payload";
    return false;
  }
  if (payload.size() > max_payload_bytes_) {
    error = "payload of " + std::to_string(payload.size()) + " bytes is over the limit of " +
            std::to_string(max_payload_bytes_);
    return false;
  }
  start_frame(out);
  const bool msgpack = detect_encoding(payload) == PayloadEncoding::msgpack;
  // JSON text starts with an ASCII byte (or a UTF-8 byte order mark): another byte is
  // MessagePack of something other than a map (0x93: an array), not "JSON at byte 0".
  if (const std::uint8_t first = payload[0]; !msgpack && first >= 0x80 && first != 0xEF) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02X", first);
    error = std::string(
                "a marker frame must be a JSON object or a MessagePack map; the first "
                "byte, ") +
            hex + ", starts neither";
    return false;
  }
  const std::string_view text(reinterpret_cast<const char*>(payload.data()), payload.size());
  FastFrameTop top;
  bool try_fast = fast_path_;
  if (try_fast && fast_skip_ > 0) {
    --fast_skip_;
    try_fast = false;
  }
  if (try_fast && (msgpack ? read_common_marker_msgpack(payload, index_, out, top)
                           : read_common_marker_json(text, index_, out, top))) {
    ++fast_frames_;
  } else {
    if (try_fast) {  // declined: the full reader, from scratch
      start_frame(out);
      fast_skip_ = kFastPathPause - 1;
    }
    FrameSax sax(index_, sensor_index_, out, error, marker_name_);
    sax.quaternion_tolerance_ = plausible_.quaternion_tolerance;
    sax.format_ = msgpack ? "MessagePack" : "JSON";
    bool ok;
    if (msgpack) {
      ok = json::sax_parse(payload.begin(), payload.end(), &sax, json::input_format_t::msgpack);
    } else {
      ok = json_reader_.parse(text, sax);
      if (!ok && error.empty()) error = json_reader_.error();
    }
    if (!ok) {
      if (error.empty()) error = std::string("not a valid ") + sax.format_ + " marker frame";
      return false;
    }
    top = {sax.has_frame, sax.m_per_unit};
  }
  if (!top.has_frame) {
    error = "\"frame\" is missing";
    return false;
  }
  const double scale = top.m_per_unit > 0.0 ? top.m_per_unit : default_m_per_unit_;
  for (int i = 0; i < count_; ++i) {
    if (!out.visible[i]) continue;
    Eigen::Vector3d& p = out.p_world_m[i];
    p *= scale;  // units converted once, here
    if (plausible_.zero_is_missing && p.x() == 0.0 && p.y() == 0.0 && p.z() == 0.0) {
      out.visible[i] = 0;
      ++out.zero_count;
    } else if (!(p.cwiseAbs().maxCoeff() <= plausible_.max_abs_coordinate_m)) {
      out.visible[i] = 0;
      ++out.rejected_count;
    }
  }
  return true;
}

namespace {
template <class Writer>
void write_marker_frame(Writer& w, std::uint64_t frame, const double* time_s,
                        const double* stamp_us, std::span<const std::string> names,
                        std::span<const Eigen::Vector3d> p_world_m,
                        std::span<const std::uint8_t> visible, std::string_view units,
                        const SensorSamples* sensors, std::span<const float> confidence) {
  const double scale = units == "mm" ? 1e3 : 1.0;
  w.begin_map(3 + (time_s ? 1 : 0) + (stamp_us ? 1 : 0) + (sensors ? 1 : 0));
  w.key("frame");
  w.uint(frame);
  if (time_s) {
    w.key("time");
    w.number_exact(*time_s);
  }
  if (stamp_us) {
    w.key("stamp_us");
    w.number_exact(*stamp_us);
  }
  w.key("units");
  w.string(units);
  w.key("markers");
  w.begin_map(names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    w.key(names[i]);
    if (!visible[i] || !p_world_m[i].allFinite()) {
      w.null();
      continue;
    }
    const bool with_confidence = i < confidence.size();
    w.begin_array(with_confidence ? 4 : 3);
    for (int k = 0; k < 3; ++k) w.number(p_world_m[i][k] * scale);
    if (with_confidence) w.number(confidence[i], 3);
    w.end_array();
  }
  w.end_map();
  if (sensors) {
    w.key("orientations");
    w.begin_map(sensors->names.size());
    for (std::size_t k = 0; k < sensors->names.size(); ++k) {
      w.key(sensors->names[k]);
      const Eigen::Quaterniond& q = sensors->q[k];
      if (!sensors->visible[k] || !q.coeffs().allFinite()) {
        w.null();
        continue;
      }
      w.begin_array(4);
      for (const double v : {q.w(), q.x(), q.y(), q.z()}) w.number(v, 9);
      w.end_array();
    }
    w.end_map();
  }
  w.end_map();
}
}  // namespace

void encode_marker_frame(std::uint64_t frame, const double* time_s,
                         std::span<const std::string> names,
                         std::span<const Eigen::Vector3d> p_world_m,
                         std::span<const std::uint8_t> visible, std::string_view units,
                         PayloadEncoding encoding, std::string& out, const double* stamp_us,
                         const SensorSamples* sensors, std::span<const float> confidence) {
  if (encoding == PayloadEncoding::json) {
    JsonWriter w(out, units == "mm" ? 4 : 7);
    write_marker_frame(w, frame, time_s, stamp_us, names, p_world_m, visible, units, sensors,
                       confidence);
  } else {
    MsgpackWriter w(out);
    write_marker_frame(w, frame, time_s, stamp_us, names, p_world_m, visible, units, sensors,
                       confidence);
  }
}

}  // namespace fabrik::wire
