// A strict JSON reader (RFC 8259) that drives a SAX handler with nlohmann's
// interface (null, boolean, number_*, string, start_object, key, ...), for
// the daemon's hot path: unlike nlohmann::json::sax_parse, whose lexer
// allocates its token buffers on every call, it reuses one buffer, so after
// the first frames it does not allocate. It accepts exactly what nlohmann
// accepts (tests/test_codec.cpp checks the two against each other on
// mutated payloads): UTF-8 validated, surrogate pairs, no NaN or trailing
// commas, numbers that fit a double.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

namespace fabrik::wire {

class JsonSaxReader {
 public:
  // Stops at the first error (error() says what and where) or when the
  // handler returns false (error() empty: the handler keeps its own reason).
  template <class Sax>
  bool parse(std::string_view text, Sax& sax) {
    text_ = text;
    pos_ = text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;  // a UTF-8 byte order mark, as nlohmann
    error_.clear();
    if (!value(sax, 0)) return false;
    skip_ws();
    if (pos_ != text_.size()) return syntax("unexpected content after the value");
    return true;
  }
  const std::string& error() const { return error_; }
  // Tokens (strings, numbers) up to `bytes` long read without allocating,
  // even on the first payloads that reach the reader.
  void reserve(std::size_t bytes) { buf_.reserve(bytes); }

 private:
  static constexpr int kMaxDepth = 512;  // guards the stack if a handler allows any nesting

  template <class Sax>
  bool value(Sax& sax, int depth) {
    skip_ws();
    if (pos_ >= text_.size()) return syntax("unexpected end of input");
    switch (text_[pos_]) {
      case '{':
        return object(sax, depth);
      case '[':
        return array(sax, depth);
      case '"':
        ++pos_;
        return string_token() && sax.string(buf_);
      case 't':
        return literal("true") && sax.boolean(true);
      case 'f':
        return literal("false") && sax.boolean(false);
      case 'n':
        return literal("null") && sax.null();
      default:
        return number(sax);
    }
  }

  template <class Sax>
  bool object(Sax& sax, int depth) {
    if (depth >= kMaxDepth) return syntax("nesting too deep");
    ++pos_;
    if (!sax.start_object(static_cast<std::size_t>(-1))) return false;
    skip_ws();
    if (peek('}')) return ++pos_, sax.end_object();
    for (;;) {
      skip_ws();
      if (!peek('"')) return syntax("expected a string key");
      ++pos_;
      if (!string_token() || !sax.key(buf_)) return false;
      skip_ws();
      if (!peek(':')) return syntax("expected ':'");
      ++pos_;
      if (!value(sax, depth + 1)) return false;
      skip_ws();
      if (peek(',')) {
        ++pos_;
        continue;
      }
      if (peek('}')) return ++pos_, sax.end_object();
      return syntax("expected ',' or '}'");
    }
  }

  template <class Sax>
  bool array(Sax& sax, int depth) {
    if (depth >= kMaxDepth) return syntax("nesting too deep");
    ++pos_;
    if (!sax.start_array(static_cast<std::size_t>(-1))) return false;
    skip_ws();
    if (peek(']')) return ++pos_, sax.end_array();
    for (;;) {
      if (!value(sax, depth + 1)) return false;
      skip_ws();
      if (peek(',')) {
        ++pos_;
        continue;
      }
      if (peek(']')) return ++pos_, sax.end_array();
      return syntax("expected ',' or ']'");
    }
  }

  template <class Sax>
  bool number(Sax& sax) {
    const std::size_t start = pos_;
    bool integer = true;
    if (peek('-')) ++pos_;
    if (peek('0')) {
      ++pos_;
    } else if (digit()) {
      while (digit()) ++pos_;
    } else {
      return syntax(pos_ == start ? "unexpected character" : "expected a digit");
    }
    if (peek('.')) {
      integer = false;
      ++pos_;
      if (!digit()) return syntax("expected a digit after '.'");
      while (digit()) ++pos_;
    }
    if (peek('e') || peek('E')) {
      integer = false;
      ++pos_;
      if (peek('+') || peek('-')) ++pos_;
      if (!digit()) return syntax("expected a digit in the exponent");
      while (digit()) ++pos_;
    }
    const char* first = text_.data() + start;
    const char* last = text_.data() + pos_;
    if (integer) {
      if (*first == '-') {
        std::int64_t v;
        if (std::from_chars(first, last, v).ec == std::errc()) return sax.number_integer(v);
      } else {
        std::uint64_t v;
        if (std::from_chars(first, last, v).ec == std::errc()) return sax.number_unsigned(v);
      }
    }
    // Floats, and integers too large for 64 bits (as nlohmann does).
    double v = 0.0;
    buf_.assign(first, last);
    const auto r = std::from_chars(first, last, v);
    if (r.ec == std::errc::result_out_of_range) {
      // Underflow reads as (nearly) zero, overflow is an error: as nlohmann (strtod).
      v = std::strtod(buf_.c_str(), nullptr);
      if (!std::isfinite(v)) return syntax("number overflow");
    } else if (r.ec != std::errc() || r.ptr != last) {
      return syntax("invalid number");
    }
    return sax.number_float(v, buf_);
  }

  // The string after its opening quote, unescaped into buf_.
  bool string_token() {
    buf_.clear();
    for (;;) {
      if (pos_ >= text_.size()) return syntax("unterminated string");
      const auto c = static_cast<unsigned char>(text_[pos_]);
      if (c == '"') {
        ++pos_;
        return true;
      }
      if (c < 0x20) return syntax("control character in a string");
      if (c == '\\') {
        if (!escape()) return false;
        continue;
      }
      if (c < 0x80) {
        buf_ += static_cast<char>(c);
        ++pos_;
        continue;
      }
      if (!utf8_sequence()) return syntax("invalid UTF-8 in a string");
    }
  }

  bool escape() {
    ++pos_;  // the backslash
    if (pos_ >= text_.size()) return syntax("unterminated escape");
    const char e = text_[pos_++];
    switch (e) {
      case '"':
        buf_ += '"';
        return true;
      case '\\':
        buf_ += '\\';
        return true;
      case '/':
        buf_ += '/';
        return true;
      case 'b':
        buf_ += '\b';
        return true;
      case 'f':
        buf_ += '\f';
        return true;
      case 'n':
        buf_ += '\n';
        return true;
      case 'r':
        buf_ += '\r';
        return true;
      case 't':
        buf_ += '\t';
        return true;
      case 'u':
        break;
      default:
        return syntax("invalid escape");
    }
    std::uint32_t cp = 0;
    if (!hex4(cp)) return false;
    if (cp >= 0xDC00 && cp <= 0xDFFF) return syntax("lone low surrogate");
    if (cp >= 0xD800 && cp <= 0xDBFF) {
      std::uint32_t low = 0;
      if (!(pos_ + 1 < text_.size() && text_[pos_] == '\\' && text_[pos_ + 1] == 'u'))
        return syntax("high surrogate without its low half");
      pos_ += 2;
      if (!hex4(low)) return false;
      if (low < 0xDC00 || low > 0xDFFF) return syntax("high surrogate without its low half");
      cp = 0x10000 + ((cp - 0xD800) << 10) + (low - 0xDC00);
    }
    append_utf8(cp);
    return true;
  }

  bool hex4(std::uint32_t& out) {
    if (pos_ + 4 > text_.size()) return syntax("truncated \\u escape");
    for (int i = 0; i < 4; ++i) {
      const char h = text_[pos_++];
      out <<= 4;
      if (h >= '0' && h <= '9')
        out |= static_cast<std::uint32_t>(h - '0');
      else if (h >= 'a' && h <= 'f')
        out |= static_cast<std::uint32_t>(h - 'a' + 10);
      else if (h >= 'A' && h <= 'F')
        out |= static_cast<std::uint32_t>(h - 'A' + 10);
      else
        return syntax("invalid \\u escape");
    }
    return true;
  }

  void append_utf8(std::uint32_t cp) {
    if (cp < 0x80) {
      buf_ += static_cast<char>(cp);
    } else if (cp < 0x800) {
      buf_ += static_cast<char>(0xC0 | (cp >> 6));
      buf_ += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      buf_ += static_cast<char>(0xE0 | (cp >> 12));
      buf_ += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      buf_ += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      buf_ += static_cast<char>(0xF0 | (cp >> 18));
      buf_ += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      buf_ += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      buf_ += static_cast<char>(0x80 | (cp & 0x3F));
    }
  }

  // One multi-byte UTF-8 sequence (RFC 3629: no overlongs, no surrogates, <= U+10FFFF).
  bool utf8_sequence() {
    const auto b = [&](std::size_t i) { return static_cast<unsigned char>(text_[pos_ + i]); };
    const auto cont = [&](std::size_t i, unsigned char lo = 0x80, unsigned char hi = 0xBF) {
      return pos_ + i < text_.size() && b(i) >= lo && b(i) <= hi;
    };
    const unsigned char c = b(0);
    std::size_t n = 0;
    if (c >= 0xC2 && c <= 0xDF)
      n = cont(1) ? 2 : 0;
    else if (c == 0xE0)
      n = cont(1, 0xA0) && cont(2) ? 3 : 0;
    else if ((c >= 0xE1 && c <= 0xEC) || c == 0xEE || c == 0xEF)
      n = cont(1) && cont(2) ? 3 : 0;
    else if (c == 0xED)
      n = cont(1, 0x80, 0x9F) && cont(2) ? 3 : 0;
    else if (c == 0xF0)
      n = cont(1, 0x90) && cont(2) && cont(3) ? 4 : 0;
    else if (c >= 0xF1 && c <= 0xF3)
      n = cont(1) && cont(2) && cont(3) ? 4 : 0;
    else if (c == 0xF4)
      n = cont(1, 0x80, 0x8F) && cont(2) && cont(3) ? 4 : 0;
    if (n == 0) return false;
    buf_.append(text_.data() + pos_, n);
    pos_ += n;
    return true;
  }

  bool literal(std::string_view word) {
    if (text_.substr(pos_, word.size()) != word) return syntax("invalid literal");
    pos_ += word.size();
    return true;
  }
  void skip_ws() {
    while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\t' ||
                                   text_[pos_] == '\n' || text_[pos_] == '\r'))
      ++pos_;
  }
  bool peek(char c) const { return pos_ < text_.size() && text_[pos_] == c; }
  bool digit() const { return pos_ < text_.size() && text_[pos_] >= '0' && text_[pos_] <= '9'; }
  bool syntax(const char* what) {
    error_ = "not valid JSON at byte ";
    error_ += std::to_string(pos_);
    error_ += ": ";
    error_ += what;
    return false;
  }

  std::string_view text_;
  std::size_t pos_ = 0;
  std::string buf_;
  std::string error_;
};

}  // namespace fabrik::wire
