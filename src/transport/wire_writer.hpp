// Two writers with the same calls, one for JSON text and one for
// MessagePack, so a payload is described once (a template over the writer)
// and comes out in either encoding. They append to a caller-owned buffer that
// keeps its capacity between frames: after the first few frames, encoding
// does not allocate.
#pragma once

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "fixed_decimals.hpp"

namespace fabrik::wire {

// JSON: maps and arrays need separators, so it tracks nesting; sizes given
// to begin_map/begin_array are ignored. It writes through a cursor into the
// buffer, grown a chunk at a time, and cuts the buffer to what it wrote when
// it goes out of scope: read the buffer after the writer's scope ends.
// (So a number is formatted in place, with no room zero-filled and cut back
// for each of a pose's few hundred values.)
class JsonWriter {
 public:
  explicit JsonWriter(std::string& out, int decimals) : out_(out), decimals_(decimals) {
    out_.clear();
    grow(0);
  }
  ~JsonWriter() { out_.resize(static_cast<std::size_t>(p_ - out_.data())); }
  JsonWriter(const JsonWriter&) = delete;
  JsonWriter& operator=(const JsonWriter&) = delete;

  void begin_map(std::size_t) { open('{'); }
  void end_map() { close('}'); }
  void begin_array(std::size_t) { open('['); }
  void end_array() { close(']'); }
  // A key whose JSON form ("name":) was made once, at setup, by json_key().
  void named_key(std::string_view, std::string_view quoted_key_colon) {
    separate();
    put(quoted_key_colon);
    after_key_ = true;
  }
  void key(std::string_view k) {
    separate();
    quoted(k);
    put(':');
    after_key_ = true;
  }
  void string(std::string_view s) {
    separate();
    quoted(s);
  }
  void null() {
    separate();
    put("null");
  }
  void boolean(bool b) {
    separate();
    put(b ? std::string_view("true") : std::string_view("false"));
  }
  void uint(std::uint64_t v) {
    separate();
    room(24);
    p_ = std::to_chars(p_, p_ + 24, v).ptr;
  }
  // Fixed decimals; JSON has no NaN or infinity, so those become null.
  void number(double v) { number(v, decimals_); }
  void number(double v, int decimals) {
    separate();
    if (!std::isfinite(v)) {
      put("null");
      return;
    }
    room(kNumberRoom);
    p_ = format(p_, v, decimals);
  }
  // The shortest text that reads back as exactly `v`: for values copied through (a frame's
  // time and stamp), where fixed decimals would round what the sender gave.
  void number_exact(double v) {
    separate();
    if (!std::isfinite(v)) {
      put("null");
      return;
    }
    room(kNumberRoom);
    p_ = std::to_chars(p_, p_ + kNumberRoom, v).ptr;
  }
  // [a, b, c] with the writer's decimals: a point, in one step (most of a pose's numbers).
  void number_triple(double a, double b, double c) {
    if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c)) {
      begin_array(3);
      number(a);
      number(b);
      number(c);
      end_array();
      return;
    }
    separate();
    room(3 * (kNumberRoom + 1) + 1);
    *p_++ = '[';
    for (const double v : {a, b, c}) {
      p_ = format(p_, v, decimals_);
      *p_++ = ',';
    }
    p_[-1] = ']';
    first_ = false;
  }
  // The JSON form of a key, for named_key(): "name": with JSON escaping.
  static std::string json_key(std::string_view k) {
    std::string s;
    {
      JsonWriter w(s, 0);
      w.key(k);
    }
    return s;
  }

 private:
  void open(char c) {
    separate();
    put(c);
    first_ = true;
  }
  void close(char c) {
    put(c);
    first_ = false;
  }
  void separate() {
    if (after_key_) {
      after_key_ = false;
      return;
    }
    if (!first_) put(',');
    first_ = false;
  }
  void quoted(std::string_view s) {
    room(2 + 6 * s.size());  // each character escaped as \u00XX at most
    *p_++ = '"';
    for (char ch : s) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '"' || c == '\\') {
        *p_++ = '\\';
        *p_++ = ch;
      } else if (c < 0x20) {
        static constexpr char hex[] = "0123456789abcdef";
        std::memcpy(p_, "\\u00", 4);
        p_[4] = hex[c >> 4];
        p_[5] = hex[c & 15];
        p_ += 6;
      } else {
        *p_++ = ch;
      }
    }
    *p_++ = '"';
  }
  void put(char c) {
    room(1);
    *p_++ = c;
  }
  void put(std::string_view s) {
    room(s.size());
    std::memcpy(p_, s.data(), s.size());
    p_ += s.size();
  }
  // At least n characters writable at the cursor.
  void room(std::size_t n) {
    if (static_cast<std::size_t>(end_ - p_) < n) grow(n);
  }
  // The buffer's size is what may be written; only the new part is zero-filled, and
  // within its capacity (kept between payloads) nothing is allocated.
  void grow(std::size_t n) {
    const std::size_t used = out_.empty() ? 0 : static_cast<std::size_t>(p_ - out_.data());
    out_.resize(out_.size() + std::max(n, kChunk));
    p_ = out_.data() + used;
    end_ = out_.data() + out_.size();
  }

  // A finite number with `decimals` at p (kNumberRoom there); returns its end.
  static char* format(char* p, double v, int decimals) {
    auto r = to_fixed_chars(p, p + kNumberRoom, v, decimals);
    if (r.ec != std::errc()) r = std::to_chars(p, p + kNumberRoom, v);
    return r.ptr;
  }
  // What one number may take: to_fixed_chars needs 32; to_chars with fixed decimals writes up
  // to 64 here before it gives way to the shortest form (as the writer always did).
  static constexpr std::size_t kNumberRoom = 64;
  static constexpr std::size_t kChunk = 1024;
  std::string& out_;
  char* p_ = nullptr;
  char* end_ = nullptr;
  int decimals_;
  bool first_ = true;
  bool after_key_ = false;
};

// MessagePack: sizes are part of the header, so begin_map/begin_array must
// be given the exact element count.
class MsgpackWriter {
 public:
  explicit MsgpackWriter(std::string& out, int = 0) : out_(out) { out_.clear(); }
  void begin_map(std::size_t n) {
    if (n < 16)
      byte(static_cast<std::uint8_t>(0x80 | n));
    else if (n < 65536)
      byte(0xde), be16(n);
    else
      byte(0xdf), be32(n);
  }
  void end_map() {}
  void begin_array(std::size_t n) {
    if (n < 16)
      byte(static_cast<std::uint8_t>(0x90 | n));
    else if (n < 65536)
      byte(0xdc), be16(n);
    else
      byte(0xdd), be32(n);
  }
  void end_array() {}
  void named_key(std::string_view k, std::string_view) { string(k); }
  void key(std::string_view k) { string(k); }
  void string(std::string_view s) {
    const std::size_t n = s.size();
    if (n < 32)
      byte(static_cast<std::uint8_t>(0xa0 | n));
    else if (n < 256)
      byte(0xd9), byte(static_cast<std::uint8_t>(n));
    else if (n < 65536)
      byte(0xda), be16(n);
    else
      byte(0xdb), be32(n);
    out_.append(s);
  }
  void null() { byte(0xc0); }
  void boolean(bool b) { byte(b ? 0xc3 : 0xc2); }
  void uint(std::uint64_t v) {
    if (v < 128) return byte(static_cast<std::uint8_t>(v));
    tagged_be64(0xcf, v);
  }
  void number_exact(double v) { number(v, 0); }  // a double is exact already
  void number(double v) { number(v, 0); }
  void number(double v, int) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    tagged_be64(0xcb, bits);
  }
  // [a, b, c] in one append: a point (most of a pose's numbers).
  void number_triple(double a, double b, double c) {
    char t[1 + 3 * 9];
    t[0] = static_cast<char>(0x93);
    put_tagged_be64(t + 1, 0xcb, std::bit_cast<std::uint64_t>(a));
    put_tagged_be64(t + 10, 0xcb, std::bit_cast<std::uint64_t>(b));
    put_tagged_be64(t + 19, 0xcb, std::bit_cast<std::uint64_t>(c));
    out_.append(t, sizeof t);
  }

 private:
  void byte(std::uint8_t b) { out_ += static_cast<char>(b); }
  // One append for the 9 bytes: byte by byte, they were most of a pose's encoding.
  void tagged_be64(std::uint8_t tag, std::uint64_t v) {
    char b[9];
    put_tagged_be64(b, tag, v);
    out_.append(b, sizeof b);
  }
  static void put_tagged_be64(char* b, std::uint8_t tag, std::uint64_t v) {
    b[0] = static_cast<char>(tag);
    for (int i = 0; i < 8; ++i) b[1 + i] = static_cast<char>(v >> (8 * (7 - i)));
  }
  void be16(std::size_t n) {
    byte(static_cast<std::uint8_t>(n >> 8)), byte(static_cast<std::uint8_t>(n));
  }
  void be32(std::size_t n) {
    for (int i = 3; i >= 0; --i) byte(static_cast<std::uint8_t>(n >> (8 * i)));
  }
  std::string& out_;
};

}  // namespace fabrik::wire
