// Helpers shared by the ESPM tests: a bit-serial CRC written from the definition (independent of
// the table-driven code under test) and random information packets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <random>

#include "robot/espm/Packet.h"

namespace espm_test {

// CRC-16 bit by bit: each byte MSB first, shift left, XOR the polynomial 0x1DB7 when a one falls
// out; initial value 0xFFFF, no final XOR.
inline uint16_t referenceCrc(const uint8_t* data, size_t size) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < size; ++i)
    for (int b = 7; b >= 0; --b) {
      const bool in = ((data[i] >> b) & 1) != ((crc >> 15) & 1);
      crc = static_cast<uint16_t>(crc << 1);
      if (in) crc ^= 0x1DB7;
    }
  return crc;
}

// A packet with every field drawn at random within its bit width (unused bits zero).
inline viscera::robot::espm::Packet randomPacket(std::mt19937_64& rng) {
  using namespace viscera::robot::espm;
  Quadlets q;
  for (int i = 0; i < kInformationQuadlets; ++i) q[i] = static_cast<uint32_t>(rng()) & usedBits(i);
  return decodePacket(q);
}

}  // namespace espm_test
