#include "bridges/qtm/byte_io.hpp"

#include <bit>
#include <cstring>

namespace fabrik::qtm {

std::uint64_t ByteReader::unsigned_of(std::size_t width) {
  if (!ok_ || remaining() < width) {
    ok_ = false;
    return 0;
  }
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < width; ++i) {
    const std::size_t shift = order_ == ByteOrder::little ? 8 * i : 8 * (width - 1 - i);
    v |= static_cast<std::uint64_t>(bytes_[pos_ + i]) << shift;
  }
  pos_ += width;
  return v;
}

std::uint8_t ByteReader::u8() { return static_cast<std::uint8_t>(unsigned_of(1)); }
std::uint16_t ByteReader::u16() { return static_cast<std::uint16_t>(unsigned_of(2)); }
std::uint32_t ByteReader::u32() { return static_cast<std::uint32_t>(unsigned_of(4)); }
std::uint64_t ByteReader::u64() { return unsigned_of(8); }
float ByteReader::f32() { return std::bit_cast<float>(u32()); }

void ByteReader::skip(std::size_t n) {
  if (!ok_ || remaining() < n) {
    ok_ = false;
    return;
  }
  pos_ += n;
}

void ByteWriter::unsigned_of(std::uint64_t v, std::size_t width) {
  for (std::size_t i = 0; i < width; ++i) {
    const std::size_t shift = order_ == ByteOrder::little ? 8 * i : 8 * (width - 1 - i);
    out_.push_back(static_cast<std::uint8_t>(v >> shift));
  }
}

void ByteWriter::f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }

void ByteWriter::patch_u32(std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) {
    const std::size_t shift = order_ == ByteOrder::little ? 8 * i : 8 * (3 - i);
    out_[at + i] = static_cast<std::uint8_t>(v >> shift);
  }
}

}  // namespace fabrik::qtm
