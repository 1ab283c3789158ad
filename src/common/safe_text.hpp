// Untrusted bytes (a topic frame, a marker name, an error text that quotes
// input, a file name) made fit for any output: the log, a stats payload, a
// pose. The result is valid UTF-8 without control characters and bounded in
// length, so no consumer (a JSON serialiser, a terminal, a log parser) can be
// tripped by what a peer sent. Every byte string from the wire goes through
// safe_text() before it reaches an output.
//
// Kept as is: printable ASCII and well-formed UTF-8 sequences of printable
// characters. Written as \xHH: control characters (C0, DEL, and the C1
// controls U+0080-U+009F) and every byte that is not part of a well-formed
// sequence (stray continuation bytes, overlong forms, surrogates, code points
// above U+10FFFF, truncated sequences). Applying it twice changes nothing.
// Writing never allocates: the caller gives the buffer.
//
// In common/ (not transport/) because setup-time text takes the same path:
// config errors (ConfigError), endpoint and file arguments on stderr.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace fabrik {

namespace safe_text_detail {

// Length of the well-formed UTF-8 sequence at s[0] (RFC 3629), 0 if there is none.
inline std::size_t utf8_sequence(std::string_view s) {
  const auto b = [&](std::size_t i) { return static_cast<unsigned char>(s[i]); };
  const unsigned char c = b(0);
  std::size_t n;
  unsigned char lo = 0x80, hi = 0xbf;  // allowed range of the second byte
  if (c >= 0xc2 && c <= 0xdf) {
    n = 2;
  } else if (c >= 0xe0 && c <= 0xef) {
    n = 3;
    if (c == 0xe0) lo = 0xa0;  // no overlong forms
    if (c == 0xed) hi = 0x9f;  // no surrogates
  } else if (c >= 0xf0 && c <= 0xf4) {
    n = 4;
    if (c == 0xf0) lo = 0x90;
    if (c == 0xf4) hi = 0x8f;  // nothing above U+10FFFF
  } else {
    return 0;
  }
  if (s.size() < n || b(1) < lo || b(1) > hi) return 0;
  for (std::size_t i = 2; i < n; ++i)
    if (b(i) < 0x80 || b(i) > 0xbf) return 0;
  if (n == 2 && c == 0xc2 && b(1) <= 0x9f) return 0;  // C1 controls
  return n;
}

}  // namespace safe_text_detail

// Calls piece(bytes, length) for each output piece of `in` (a character
// kept as is, or one byte escaped) until it returns false.
template <class Piece>
void safe_text_pieces(std::string_view in, Piece&& piece) {
  static constexpr char hex[] = "0123456789abcdef";
  for (std::size_t i = 0; i < in.size();) {
    const auto c = static_cast<unsigned char>(in[i]);
    const std::size_t seq = c >= 0x80 ? safe_text_detail::utf8_sequence(in.substr(i)) : 0;
    if (c >= 0x20 && c < 0x7f) {
      if (!piece(in.data() + i, 1)) return;
      ++i;
    } else if (seq > 0) {
      if (!piece(in.data() + i, seq)) return;
      i += seq;
    } else {
      const char escaped[4] = {'\\', 'x', hex[c >> 4], hex[c & 15]};
      if (!piece(escaped, 4)) return;
      ++i;
    }
  }
}

// Writes the safe form of `in` into out[0, capacity) and returns its length
// (no terminating NUL). When it does not fit, it is cut at a character
// boundary and ends in "...". capacity must be at least 4.
inline std::size_t safe_text(std::string_view in, char* out, std::size_t capacity) {
  static constexpr std::string_view ellipsis = "...";
  std::size_t total = 0;
  safe_text_pieces(in, [&](const char*, std::size_t len) {
    total += len;
    return total <= capacity;
  });
  const bool cut = total > capacity;
  const std::size_t room = cut ? capacity - ellipsis.size() : capacity;
  std::size_t n = 0;
  safe_text_pieces(in, [&](const char* piece, std::size_t len) {
    if (n + len > room) return false;
    std::memcpy(out + n, piece, len);
    n += len;
    return true;
  });
  if (cut) {
    std::memcpy(out + n, ellipsis.data(), ellipsis.size());
    n += ellipsis.size();
  }
  return n;
}

// The same into a std::string of at most max_bytes (allocates; for setup-time messages).
inline std::string safe_text(std::string_view in, std::size_t max_bytes = 256) {
  std::string out(max_bytes, '\0');
  out.resize(safe_text(in, out.data(), max_bytes));
  return out;
}

// Multi-line text (an error that lists names on lines of their own) made
// safe line by line: its line breaks stay, everything else is as safe_text()
// makes it, never cut.
inline std::string safe_lines(std::string_view in) {
  std::string out;
  for (std::size_t start = 0;;) {
    const std::size_t end = std::min(in.find('\n', start), in.size());
    const std::string_view line = in.substr(start, end - start);
    out += safe_text(line, 4 * line.size() + 4);  // room for every byte escaped: no cut
    if (end == in.size()) return out;
    out += '\n';
    start = end + 1;
  }
}

// A fixed-capacity text that never allocates: last_error survives an
// out-of-memory error path.
template <std::size_t Capacity>
class FixedText {
 public:
  void assign_safe(std::string_view untrusted) { size_ = safe_text(untrusted, data_, Capacity); }
  void clear() { size_ = 0; }
  bool empty() const { return size_ == 0; }
  std::string_view view() const { return {data_, size_}; }

 private:
  char data_[Capacity];
  std::size_t size_ = 0;
};

}  // namespace fabrik
