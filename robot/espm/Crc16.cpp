#include "robot/espm/Crc16.h"

#include <array>

namespace viscera::robot::espm {
namespace {

// table[k][b]: what the byte b contributes to the register when k more bytes follow it, i.e. the
// CRC register after shifting in b then k zero bytes, starting from zero. table[0] is the
// classic byte-at-a-time table.
using Tables = std::array<std::array<uint16_t, 256>, 8>;

constexpr Tables makeTables() {
  Tables t{};
  for (unsigned b = 0; b < 256; ++b) {
    uint16_t r = static_cast<uint16_t>(b << 8);
    for (int bit = 0; bit < 8; ++bit) r = static_cast<uint16_t>(r & 0x8000 ? (r << 1) ^ kCrcPolynomial : r << 1);
    t[0][b] = r;
  }
  for (size_t k = 1; k < t.size(); ++k)
    for (unsigned b = 0; b < 256; ++b) {
      const uint16_t r = t[k - 1][b];
      t[k][b] = static_cast<uint16_t>((r << 8) ^ t[0][r >> 8]);
    }
  return t;
}

constexpr Tables kTables = makeTables();

}  // namespace

uint16_t Crc16::crc16Update(uint16_t state, const uint8_t* data, size_t size) {
  uint32_t crc = state;
  // Eight bytes at a time: the register is XORed into the first two bytes (it would be shifted
  // out by them), then every byte's contribution is looked up by how many bytes follow it.
  while (size >= 8) {
    const uint8_t b0 = static_cast<uint8_t>(data[0] ^ (crc >> 8));
    const uint8_t b1 = static_cast<uint8_t>(data[1] ^ (crc & 0xFF));
    crc = kTables[7][b0] ^ kTables[6][b1] ^ kTables[5][data[2]] ^ kTables[4][data[3]] ^ kTables[3][data[4]] ^
          kTables[2][data[5]] ^ kTables[1][data[6]] ^ kTables[0][data[7]];
    data += 8;
    size -= 8;
  }
  for (; size > 0; --size, ++data) crc = ((crc << 8) ^ kTables[0][(crc >> 8) ^ *data]) & 0xFFFF;
  return static_cast<uint16_t>(crc);
}

}  // namespace viscera::robot::espm
