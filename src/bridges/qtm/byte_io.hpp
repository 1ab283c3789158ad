// Fixed-width integers and IEEE 754 floats in the byte order a QTM RT
// connection chose (the RT protocol documentation, "Byte order": the TCP
// port picks it, base port + 1 little endian, base port + 2 big endian).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace fabrik::qtm {

enum class ByteOrder { little, big };

// Reads from a bounded span; every read checks the remaining size first, so a
// short buffer sets `ok` to false instead of reading past the end.
class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> bytes, ByteOrder order) : bytes_(bytes), order_(order) {}

  std::uint8_t u8();
  std::uint16_t u16();
  std::uint32_t u32();
  std::uint64_t u64();
  float f32();
  void skip(std::size_t n);

  bool ok() const { return ok_; }
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return bytes_.size() - pos_; }

 private:
  std::uint64_t unsigned_of(std::size_t width);

  std::span<const std::uint8_t> bytes_;
  ByteOrder order_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

// Appends to a byte vector (whose capacity the caller keeps between packets).
class ByteWriter {
 public:
  ByteWriter(std::vector<std::uint8_t>& out, ByteOrder order) : out_(out), order_(order) {}

  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { unsigned_of(v, 2); }
  void u32(std::uint32_t v) { unsigned_of(v, 4); }
  void u64(std::uint64_t v) { unsigned_of(v, 8); }
  void f32(float v);
  void bytes(std::span<const std::uint8_t> b) { out_.insert(out_.end(), b.begin(), b.end()); }
  // Overwrites a u32 written earlier at `at` (a size known only at the end).
  void patch_u32(std::size_t at, std::uint32_t v);

  std::size_t size() const { return out_.size(); }

 private:
  void unsigned_of(std::uint64_t v, std::size_t width);

  std::vector<std::uint8_t>& out_;
  ByteOrder order_;
};

}  // namespace fabrik::qtm
