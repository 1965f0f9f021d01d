// CRC-16 of the ESPM protocol (dVRK-S arm link), as the public dVRK controller firmware computes it:
// polynomial 0x1DB7 (x^16 + x^12 + x^11 + x^10 + x^8 + x^7 + x^5 + x^4 + x^2 + x + 1), initial
// value 0xFFFF, bits taken most significant first (not reflected), no final XOR. The bytes are
// taken in stream order, so a big-endian quadlet contributes its most significant byte first.
// Check value: the CRC of the ASCII bytes "123456789" is 0x9BE5.
//
// Because the generator has degree 16 and a non-zero constant term, every error burst of at most
// 16 bits (in this bit order) changes the CRC, and so does every single-bit error.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace viscera::robot::espm {

inline constexpr uint16_t kCrcPolynomial = 0x1DB7;
inline constexpr uint16_t kCrcInitial = 0xFFFF;

// Incremental CRC: update() with the bytes in order, in any number of pieces, then value().
class Crc16 {
 public:
  void update(const uint8_t* data, size_t size) { state_ = crc16Update(state_, data, size); }
  void update(std::span<const uint8_t> bytes) { update(bytes.data(), bytes.size()); }
  uint16_t value() const { return state_; }
  void reset() { state_ = kCrcInitial; }

  // Continues a CRC whose register holds `state` over `size` more bytes. Table driven, eight
  // bytes per step (slicing-by-8), byte by byte for the rest.
  static uint16_t crc16Update(uint16_t state, const uint8_t* data, size_t size);

 private:
  uint16_t state_ = kCrcInitial;
};

// CRC of a whole buffer (from the initial value).
inline uint16_t crc16(const uint8_t* data, size_t size) { return Crc16::crc16Update(kCrcInitial, data, size); }
inline uint16_t crc16(std::span<const uint8_t> bytes) { return crc16(bytes.data(), bytes.size()); }

}  // namespace viscera::robot::espm
