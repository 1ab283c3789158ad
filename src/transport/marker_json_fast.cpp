#include "marker_json_fast.hpp"

#include <charconv>
#include <cstdint>

namespace fabrik::wire {

namespace {

// 10^0 .. 10^22: every one exactly a double.
constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                             1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

class JsonShapeReader {
 public:
  JsonShapeReader(std::string_view text, MarkerNameIndex& names, MarkerFrame& out,
                    FastFrameTop& top)
      : p_(text.data()), end_(text.data() + text.size()), names_(names), out_(out), top_(top) {}

  bool frame() {
    ws();
    if (!eat('{')) return false;
    ws();
    if (eat('}')) return at_end();
    for (;;) {
      std::string_view key;
      if (!string(key)) return false;
      ws();
      if (!eat(':')) return false;
      ws();
      if (!top_value(key)) return false;
      ws();
      if (eat(',')) {
        ws();
        continue;
      }
      return eat('}') && at_end();
    }
  }

 private:
  bool top_value(std::string_view key) {
    if (key == "markers") return markers();
    if (key == "frame") {
      const char* first = p_;
      bool integer = false;
      double unused;
      if (!number(unused, integer) || !integer || *first == '-') return false;
      if (std::from_chars(first, p_, out_.frame).ec != std::errc()) return false;
      top_.has_frame = true;
      return true;
    }
    bool integer;
    if (key == "time") return out_.has_time = number(out_.time_s, integer);
    if (key == "stamp_us") return out_.has_stamp = number(out_.stamp_us, integer);
    if (key == "units" || key == "subject") {
      std::string_view value;
      return string(value) && set_units_or_subject(key, value, out_, top_);
    }
    return false;  // other keys, "orientations" included: the full reader
  }

  bool markers() {
    if (!eat('{')) return false;
    ws();
    if (eat('}')) return true;
    for (std::size_t position = 0;; ++position) {
      std::string_view name;
      if (!string(name)) return false;
      ws();
      if (!eat(':')) return false;
      ws();
      if (!marker_value(count_marker(names_, position, name, out_))) return false;
      ws();
      if (eat(',')) {
        ws();
        continue;
      }
      return eat('}');
    }
  }

  // [x, y, z], [x, y, z, confidence] or null, for marker i (-1: unknown, read and dropped).
  bool marker_value(int i) {
    if (end_ - p_ >= 4 && std::string_view(p_, 4) == "null") {
      p_ += 4;
      if (i >= 0) out_.visible[i] = 0;
      return true;
    }
    if (!eat('[')) return false;
    double xyz[3];
    bool integer;
    for (int k = 0; k < 3; ++k) {
      ws();
      if (!number(xyz[k], integer)) return false;
      ws();
      if (!eat(k < 2 ? ',' : ']') && !(k == 2 && eat(','))) return false;
    }
    const bool with_confidence = p_[-1] == ',';
    double confidence = 1.0;
    if (with_confidence) {
      ws();
      if (!number(confidence, integer)) return false;
      ws();
      if (!eat(']')) return false;
    }
    if (i >= 0)
      set_marker(out_, i, {xyz[0], xyz[1], xyz[2]}, with_confidence ? &confidence : nullptr);
    return true;
  }

  // A JSON number, read as the full reader reads it: an integer token
  // through a 64-bit integer when it fits (so "-0" is +0.0), anything else
  // as a correctly rounded double. Overflow and underflow are declined.
  bool number(double& v, bool& integer) {
    const char* first = p_;
    const bool negative = eat('-');
    std::uint64_t mantissa = 0;
    int digits = 0, decimals = 0;
    if (eat('0')) {
    } else if (digit()) {
      while (digit()) mantissa = mantissa * 10 + static_cast<unsigned>(*p_++ - '0'), ++digits;
    } else {
      return false;
    }
    integer = true;
    if (eat('.')) {
      integer = false;
      if (!digit()) return false;
      while (digit())
        mantissa = mantissa * 10 + static_cast<unsigned>(*p_++ - '0'), ++digits, ++decimals;
    }
    bool exponent = false;
    if (p_ < end_ && (*p_ == 'e' || *p_ == 'E')) {
      integer = false;
      exponent = true;
      ++p_;
      if (p_ < end_ && (*p_ == '+' || *p_ == '-')) ++p_;
      if (!digit()) return false;
      while (digit()) ++p_;
    }
    // Clinger's fast path: an integer mantissa and a power of ten both exact
    // as doubles, so the one division rounds correctly. (Digits counts
    // leading zeros of the fraction too, which only makes it stricter.)
    if (!integer && !exponent && digits <= 19 && mantissa <= (std::uint64_t{1} << 53) &&
        decimals <= 22) {
      v = static_cast<double>(mantissa) / kPow10[decimals];
      if (negative) v = -v;
      return true;
    }
    if (integer) {
      if (negative) {
        std::int64_t i;
        if (std::from_chars(first, p_, i).ec == std::errc()) return v = static_cast<double>(i), true;
      } else {
        std::uint64_t u;
        if (std::from_chars(first, p_, u).ec == std::errc()) return v = static_cast<double>(u), true;
      }
    }
    const auto r = std::from_chars(first, p_, v);
    return r.ec == std::errc() && r.ptr == p_;
  }

  // A string of printable ASCII without escapes, after its opening quote.
  bool string(std::string_view& s) {
    if (!eat('"')) return false;
    const char* first = p_;
    while (p_ < end_) {
      const auto c = static_cast<unsigned char>(*p_);
      if (c == '"') {
        s = {first, static_cast<std::size_t>(p_ - first)};
        ++p_;
        return true;
      }
      if (c < 0x20 || c == '\\' || c >= 0x80) return false;
      ++p_;
    }
    return false;
  }

  void ws() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\n' || *p_ == '\r' || *p_ == '\t')) ++p_;
  }
  bool eat(char c) {
    if (p_ < end_ && *p_ == c) return ++p_, true;
    return false;
  }
  bool digit() const { return p_ < end_ && *p_ >= '0' && *p_ <= '9'; }
  bool at_end() {
    ws();
    return p_ == end_;
  }

  const char* p_;
  const char* end_;
  MarkerNameIndex& names_;
  MarkerFrame& out_;
  FastFrameTop& top_;
};

}  // namespace

bool read_common_marker_json(std::string_view text, MarkerNameIndex& names, MarkerFrame& out,
                             FastFrameTop& top) {
  return JsonShapeReader(text, names, out, top).frame();
}

}  // namespace fabrik::wire
