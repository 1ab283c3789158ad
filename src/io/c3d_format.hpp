// What the C3D reader and writer share (c3d.org, "C3D file format user guide"): 512-byte
// blocks; a header block; a parameter section of groups and parameters; then per frame, every
// point's X, Y, Z and residual word (int16 scaled by POINT:SCALE, or float when POINT:SCALE <
// 0) followed by the frame's analog samples in the same number type. The processor byte of the
// parameter section says how numbers are stored: 84 Intel (little-endian IEEE), 85 DEC
// (little-endian integers, VAX F-floating), 86 MIPS (big-endian IEEE). Not part of the API.
#pragma once

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

#include "io/marker_trial.hpp"

namespace fabrik::io::c3d {

static_assert(std::numeric_limits<float>::is_iec559, "IEEE floats are assumed");

inline constexpr std::size_t kBlockBytes = 512;
inline constexpr std::uint8_t kKey = 0x50;
inline constexpr int kProcessorBase = 83;  // processor byte = 83 + 1 (Intel), 2 (DEC), 3 (MIPS)

// Header words (16-bit, 1-based in the spec) as byte offsets.
inline constexpr std::size_t kHeaderPoints = 2;          // word 2: 3D points
inline constexpr std::size_t kHeaderAnalogValues = 4;    // word 3: analog values per frame
inline constexpr std::size_t kHeaderFirstFrame = 6;      // word 4
inline constexpr std::size_t kHeaderLastFrame = 8;       // word 5
inline constexpr std::size_t kHeaderScale = 12;          // words 7-8: float
inline constexpr std::size_t kHeaderDataStart = 16;      // word 9: block of the 3D data
inline constexpr std::size_t kHeaderAnalogSamples = 18;  // word 10: analog samples per frame
inline constexpr std::size_t kHeaderRate = 20;           // words 11-12: float

inline const char* processor_name(C3dProcessor p) {
  switch (p) {
    case C3dProcessor::intel:
      return "Intel";
    case C3dProcessor::dec:
      return "DEC";
    case C3dProcessor::mips:
      return "MIPS";
  }
  return "?";
}

// Reads and writes 16-bit integers and 32-bit floats in one processor's format.
class Numbers {
 public:
  explicit Numbers(C3dProcessor p) : p_(p) {}

  std::uint16_t u16(const std::uint8_t* b) const {
    return p_ == C3dProcessor::mips ? static_cast<std::uint16_t>(b[0] << 8 | b[1])
                                    : static_cast<std::uint16_t>(b[1] << 8 | b[0]);
  }
  std::int16_t i16(const std::uint8_t* b) const { return static_cast<std::int16_t>(u16(b)); }

  double f32(const std::uint8_t* b) const {
    const std::uint32_t b0 = b[0], b1 = b[1], b2 = b[2], b3 = b[3];
    switch (p_) {
      case C3dProcessor::intel:
        return std::bit_cast<float>(b0 | b1 << 8 | b2 << 16 | b3 << 24);
      case C3dProcessor::mips:
        return std::bit_cast<float>(b0 << 24 | b1 << 16 | b2 << 8 | b3);
      case C3dProcessor::dec:
        break;
    }
    // VAX F-floating: the first little-endian word holds the sign (bit 15), the exponent
    // (bits 14-7, excess 128) and the top 7 fraction bits; the second word the low 16 bits.
    // Value = 0.1fff...(binary) x 2^(exponent - 128): IEEE's layout read 4 times too large, so
    // decode it exactly rather than by the divide-by-4 trick, which fails at the extremes.
    const std::uint32_t high = b0 | b1 << 8, low = b2 | b3 << 8;
    const int exponent = static_cast<int>((high >> 7) & 0xFF);
    const bool negative = (high & 0x8000) != 0;
    if (exponent == 0) return negative ? std::nan("") : 0.0;  // reserved operand, or zero
    const std::uint32_t fraction = (high & 0x7F) << 16 | low;
    const double v = std::ldexp(1.0 + static_cast<double>(fraction) / 8388608.0, exponent - 129);
    return negative ? -v : v;
  }

  void put_u16(std::uint8_t* b, std::uint16_t v) const {
    const auto hi = static_cast<std::uint8_t>(v >> 8), lo = static_cast<std::uint8_t>(v & 0xFF);
    b[0] = p_ == C3dProcessor::mips ? hi : lo;
    b[1] = p_ == C3dProcessor::mips ? lo : hi;
  }
  void put_i16(std::uint8_t* b, std::int16_t v) const { put_u16(b, static_cast<std::uint16_t>(v)); }

  // `v` must be finite (callers write missing samples as zeros).
  void put_f32(std::uint8_t* b, float v) const {
    if (p_ != C3dProcessor::dec) {
      const std::uint32_t bits = std::bit_cast<std::uint32_t>(v);
      for (int i = 0; i < 4; ++i) {
        const int shift = p_ == C3dProcessor::mips ? 24 - 8 * i : 8 * i;
        b[i] = static_cast<std::uint8_t>((bits >> shift) & 0xFF);
      }
      return;
    }
    std::uint32_t high = 0, low = 0;
    if (v != 0.0f) {
      int e = 0;
      const double m = std::frexp(std::abs(static_cast<double>(v)), &e);  // m in [0.5, 1)
      const int exponent = e + 128;
      if (exponent > 255) throw std::invalid_argument("write_c3d: value too large for DEC");
      if (exponent >= 1) {  // smaller values flush to zero, as DEC has no denormals
        const auto fraction = static_cast<std::uint32_t>(std::ldexp(m, 24)) - 0x800000u;
        high =
            (v < 0.0f ? 0x8000u : 0u) | static_cast<std::uint32_t>(exponent) << 7 | fraction >> 16;
        low = fraction & 0xFFFF;
      }
    }
    b[0] = static_cast<std::uint8_t>(high & 0xFF);
    b[1] = static_cast<std::uint8_t>(high >> 8);
    b[2] = static_cast<std::uint8_t>(low & 0xFF);
    b[3] = static_cast<std::uint8_t>(low >> 8);
  }

 private:
  C3dProcessor p_;
};

}  // namespace fabrik::io::c3d
