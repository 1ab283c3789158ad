// Bounds-checked little-endian reading and writing of NatNet payloads. Every
// read checks the remaining length first, so a short or lying packet ends in a
// failed Reader (ok() == false), never in a read past the buffer.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fabrik::natnet::detail {

static_assert(std::endian::native == std::endian::little,
              "NatNet is little endian; this codec copies bytes as they are");

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  std::size_t offset() const { return offset_; }
  std::size_t remaining() const { return ok() ? bytes_.size() - offset_ : 0; }

  // The first failure wins: later reads are no-ops returning zeros.
  void fail(std::string what) {
    if (ok()) error_ = std::move(what) + " (at byte " + std::to_string(offset_) + ")";
  }

  template <class T>
  T get(const char* what) {
    T value{};
    if (!ok()) return value;
    if (remaining() < sizeof(T)) {
      fail(std::string("truncated: ") + what + " needs " + std::to_string(sizeof(T)) +
           " bytes, " + std::to_string(remaining()) + " left");
      return value;
    }
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }

  // A count that must be >= 0 and whose items (each at least min_item_bytes)
  // fit in what is left: a hostile count cannot make us allocate or loop.
  std::size_t count(const char* what, std::size_t min_item_bytes) {
    const std::int32_t n = get<std::int32_t>(what);
    if (!ok()) return 0;
    if (n < 0) {
      fail(std::string(what) + " is negative (" + std::to_string(n) + ")");
      return 0;
    }
    if (min_item_bytes > 0 && static_cast<std::size_t>(n) > remaining() / min_item_bytes) {
      fail(std::string(what) + " " + std::to_string(n) + " does not fit in the " +
           std::to_string(remaining()) + " bytes left");
      return 0;
    }
    return static_cast<std::size_t>(n);
  }

  // A NUL-terminated string that must end inside the payload.
  std::string cstring(const char* what) {
    if (!ok()) return {};
    if (remaining() == 0) {  // also keeps memchr away from an empty span's null data()
      fail(std::string("truncated: ") + what + " is missing");
      return {};
    }
    const auto* begin = bytes_.data() + offset_;
    const void* nul = std::memchr(begin, 0, remaining());
    if (nul == nullptr) {
      fail(std::string("truncated: ") + what + " has no terminating NUL");
      return {};
    }
    const auto length = static_cast<std::size_t>(static_cast<const std::uint8_t*>(nul) - begin);
    std::string s(reinterpret_cast<const char*>(begin), length);
    offset_ += length + 1;
    return s;
  }

  void skip(std::size_t n, const char* what) {
    if (!ok()) return;
    if (remaining() < n) {
      fail(std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes, " +
           std::to_string(remaining()) + " left");
      return;
    }
    offset_ += n;
  }

  std::span<const std::uint8_t> take(std::size_t n, const char* what) {
    const std::size_t at = offset_;
    skip(n, what);
    return ok() ? bytes_.subspan(at, n) : std::span<const std::uint8_t>{};
  }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t offset_ = 0;
  std::string error_;
};

class Writer {
 public:
  template <class T>
  void put(T value) {
    const auto at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &value, sizeof(T));
  }
  void cstring(std::string_view s) {
    bytes.insert(bytes.end(), s.begin(), s.end());
    bytes.push_back(0);
  }
  void zeros(std::size_t n) { bytes.insert(bytes.end(), n, 0); }
  // A placeholder int32 to be filled in later (byte counts of NatNet 4.1).
  std::size_t reserve_int32() {
    const auto at = bytes.size();
    put<std::int32_t>(0);
    return at;
  }
  void patch_int32(std::size_t at, std::int32_t value) {
    std::memcpy(bytes.data() + at, &value, sizeof value);
  }
  std::vector<std::uint8_t> bytes;
};

}  // namespace fabrik::natnet::detail
