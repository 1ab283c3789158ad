#include "marker_msgpack_fast.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <string_view>
#include <type_traits>

namespace fabrik::wire {

namespace {

class MsgpackShapeReader {
 public:
  MsgpackShapeReader(std::span<const std::uint8_t> payload, MarkerNameIndex& names,
                    MarkerFrame& out, FastFrameTop& top)
      : p_(payload.data()), end_(payload.data() + payload.size()), names_(names), out_(out),
        top_(top) {}

  bool frame() {
    std::uint32_t members;
    if (!map_header(members)) return false;
    for (std::uint32_t k = 0; k < members; ++k) {
      std::string_view key;
      if (!string(key) || !top_value(key)) return false;
    }
    return p_ == end_;  // bytes after the frame: the full reader's error (strict), so decline
  }

 private:
  bool top_value(std::string_view key) {
    if (key == "markers") return markers();
    if (key == "frame") {
      if (!unsigned_integer(out_.frame)) return false;  // signed or float: the full reader's error
      top_.has_frame = true;
      return true;
    }
    if (key == "time") return out_.has_time = finite_number(out_.time_s);
    if (key == "stamp_us") return out_.has_stamp = finite_number(out_.stamp_us);
    if (key == "units" || key == "subject") {
      std::string_view value;
      return string(value) && set_units_or_subject(key, value, out_, top_);
    }
    return false;  // other keys, "orientations" included: the full reader
  }

  bool markers() {
    std::uint32_t count;
    if (!map_header(count)) return false;
    for (std::uint32_t position = 0; position < count; ++position) {
      std::string_view name;
      if (!string(name)) return false;
      if (!marker_value(count_marker(names_, position, name, out_))) return false;
    }
    return true;
  }

  // [x, y, z], [x, y, z, confidence] or nil, for marker i (-1: unknown, read and dropped).
  bool marker_value(int i) {
    if (p_ < end_ && *p_ == 0xc0) {
      ++p_;
      if (i >= 0) out_.visible[i] = 0;
      return true;
    }
    std::uint32_t n;
    if (!array_header(n) || (n != 3 && n != 4)) return false;
    double v[4];
    for (std::uint32_t k = 0; k < n; ++k)
      if (!number(v[k])) return false;
    if (i >= 0) set_marker(out_, i, {v[0], v[1], v[2]}, n == 4 ? &v[3] : nullptr);
    return true;
  }

  bool finite_number(double& v) { return number(v) && std::isfinite(v); }

  // Any integer or float, as the full reader converts it to double.
  bool number(double& v) {
    if (p_ >= end_) return false;
    const std::uint8_t b = *p_;
    if (b <= 0x7f) return ++p_, v = b, true;                                   // positive fixint
    if (b >= 0xe0) return ++p_, v = static_cast<std::int8_t>(b), true;         // negative fixint
    switch (b) {
      case 0xca: {
        std::uint32_t bits;
        if (!big_endian(bits, 1)) return false;
        v = std::bit_cast<float>(bits);
        return true;
      }
      case 0xcb: {
        std::uint64_t bits;
        if (!big_endian(bits, 1)) return false;
        v = std::bit_cast<double>(bits);
        return true;
      }
      case 0xd0: case 0xd1: case 0xd2: case 0xd3: {
        std::int64_t i;
        if (!signed_integer(i)) return false;
        v = static_cast<double>(i);
        return true;
      }
      default: {
        std::uint64_t u;
        if (!unsigned_integer(u)) return false;
        v = static_cast<double>(u);
        return true;
      }
    }
  }
  bool unsigned_integer(std::uint64_t& u) {
    if (p_ >= end_) return false;
    const std::uint8_t b = *p_;
    if (b <= 0x7f) return ++p_, u = b, true;
    switch (b) {
      case 0xcc: return value_after_tag<std::uint8_t>(u);
      case 0xcd: return value_after_tag<std::uint16_t>(u);
      case 0xce: return value_after_tag<std::uint32_t>(u);
      case 0xcf: return value_after_tag<std::uint64_t>(u);
      default: return false;
    }
  }
  bool signed_integer(std::int64_t& i) {
    switch (*p_) {
      case 0xd0: return value_after_tag<std::int8_t>(i);
      case 0xd1: return value_after_tag<std::int16_t>(i);
      case 0xd2: return value_after_tag<std::int32_t>(i);
      default: return value_after_tag<std::int64_t>(i);
    }
  }
  // The value of type Wire after a one-byte tag, widened to Out.
  template <class Wire, class Out>
  bool value_after_tag(Out& out) {
    std::make_unsigned_t<Wire> bits;
    if (!big_endian(bits, 1)) return false;
    out = static_cast<Out>(static_cast<Wire>(bits));
    return true;
  }

  // fixstr, str8, str16 or str32: a view of its bytes in the payload.
  bool string(std::string_view& s) {
    if (p_ >= end_) return false;
    const std::uint8_t b = *p_;
    std::uint32_t n;
    if (b >= 0xa0 && b <= 0xbf) {
      n = b & 0x1fu;
      ++p_;
    } else if (b == 0xd9) {
      std::uint8_t x;
      if (!big_endian(x, 1)) return false;
      n = x;
    } else if (b == 0xda) {
      std::uint16_t x;
      if (!big_endian(x, 1)) return false;
      n = x;
    } else if (b == 0xdb) {
      if (!big_endian(n, 1)) return false;
    } else {
      return false;
    }
    if (static_cast<std::size_t>(end_ - p_) < n) return false;
    s = {reinterpret_cast<const char*>(p_), n};
    p_ += n;
    return true;
  }
  bool map_header(std::uint32_t& n) { return header(n, 0x80, 0xde); }
  bool array_header(std::uint32_t& n) { return header(n, 0x90, 0xdc); }
  // fix form (first..first+15), 16-bit (tag16) or 32-bit (tag16 + 1) count.
  bool header(std::uint32_t& n, std::uint8_t first, std::uint8_t tag16) {
    if (p_ >= end_) return false;
    const std::uint8_t b = *p_;
    if (b >= first && b <= first + 15) {
      n = b & 0x0fu;
      ++p_;
      return true;
    }
    if (b == tag16) {
      std::uint16_t x;
      if (!big_endian(x, 1)) return false;
      n = x;
      return true;
    }
    return b == tag16 + 1 && big_endian(n, 1);
  }
  // The big-endian T after `skip` tag bytes.
  template <class T>
  bool big_endian(T& v, std::size_t skip) {
    if (static_cast<std::size_t>(end_ - p_) < skip + sizeof(T)) return false;
    std::memcpy(&v, p_ + skip, sizeof(T));
    if constexpr (std::endian::native == std::endian::little && sizeof(T) > 1) {
      if constexpr (sizeof(T) == 2) v = __builtin_bswap16(v);
      if constexpr (sizeof(T) == 4) v = __builtin_bswap32(v);
      if constexpr (sizeof(T) == 8) v = __builtin_bswap64(v);
    }
    p_ += skip + sizeof(T);
    return true;
  }

  const std::uint8_t* p_;
  const std::uint8_t* end_;
  MarkerNameIndex& names_;
  MarkerFrame& out_;
  FastFrameTop& top_;
};

}  // namespace

bool read_common_marker_msgpack(std::span<const std::uint8_t> payload, MarkerNameIndex& names,
                                MarkerFrame& out, FastFrameTop& top) {
  return MsgpackShapeReader(payload, names, out, top).frame();
}

}  // namespace fabrik::wire
