// Frames of the ESPM link: how information quadlets travel as bytes. Two framings exist:
//
//  Dissertation (Appendix I): the magic quadlet 0xAC450F28, the 32 information quadlets, then the
//  16-bit CRC as 2 bytes, most significant first: 134 bytes. The CRC covers the 128 information
//  bytes, not the magic.
//
//  Public (the public dVRK controller firmware): the magic, a header quadlet
//  {page[31:16], 6'b0 [15:10], length[9:0]}, `length` payload quadlets (1..1023; 0 is invalid),
//  then the quadlet {16'b0, crc16}: 12 + 4 * length bytes. The CRC covers the header and the
//  payload. Non-zero bits 15:10 of the header, or a non-zero upper half of the CRC quadlet, make the
//  frame invalid. The ESPM information packet is page 0 with length 32 (140 bytes).
//
// Quadlets are stored big-endian (most significant byte first, network order, as IEEE-1394
// quadlets), and the CRC (see Crc16.h) runs over the bytes in that order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "robot/espm/Packet.h"

namespace viscera::robot::espm {

enum class Framing { Dissertation, Public, Auto };

// "dissertation", "public", "auto".
const char* framingName(Framing framing);
// The inverse of framingName; false when `name` is none of them.
bool parseFraming(std::string_view name, Framing& framing);

inline constexpr uint32_t kMagic = 0xAC450F28;
inline constexpr size_t kDissertationFrameBytes = 4 + 4 * kInformationQuadlets + 2;  // 134
inline constexpr int kMaxPublicPayload = 1023;
inline constexpr uint16_t kInformationPage = 0;
inline constexpr size_t publicFrameBytes(int length) { return 12 + 4 * static_cast<size_t>(length); }
inline constexpr size_t kMaxFrameBytes = publicFrameBytes(kMaxPublicPayload);  // 4104
// Bytes of one information packet in a framing (Dissertation or Public).
inline constexpr size_t packetFrameBytes(Framing framing) {
  return framing == Framing::Public ? publicFrameBytes(kInformationQuadlets) : kDissertationFrameBytes;
}

inline uint32_t loadBigEndian32(const uint8_t* p) {
  return uint32_t{p[0]} << 24 | uint32_t{p[1]} << 16 | uint32_t{p[2]} << 8 | uint32_t{p[3]};
}
inline void appendBigEndian32(std::vector<uint8_t>& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<uint8_t>(v >> shift));
}

// Appends one frame to `out`.
void appendDissertationFrame(std::vector<uint8_t>& out, const Packet& packet);
void appendDissertationFrame(std::vector<uint8_t>& out, const Quadlets& quadlets);
// Throws std::invalid_argument when the payload has 0 or more than 1023 quadlets.
void appendPublicFrame(std::vector<uint8_t>& out, uint16_t page, std::span<const uint32_t> payload);
// The information packet as page 0, length 32.
void appendPublicFrame(std::vector<uint8_t>& out, const Packet& packet);
// The information packet in `framing` (Dissertation or Public; std::invalid_argument for Auto).
void appendPacketFrame(std::vector<uint8_t>& out, Framing framing, const Packet& packet);

// What the bytes at a magic hold under one framing.
struct FrameCheck {
  enum Status {
    Ok,         // a complete frame whose CRC (and header) is right
    NeedMore,   // the bytes end before the frame could be judged
    BadHeader,  // public framing: bits 15:10 of the header set, or length 0
    BadCrc      // the CRC does not match (or the CRC quadlet's upper half is not zero)
  };
  Status status = NeedMore;
  size_t size = 0;    // bytes of the frame, known once the header is (Ok, BadCrc, and NeedMore after the header)
  uint16_t page = 0;  // public framing's page; 0 for the dissertation framing
  int length = 0;     // payload quadlets
};

// Judges the frame that starts at `data` (its first 4 bytes are taken to be the magic and are not
// looked at) with `available` bytes readable there, under `framing` (Dissertation or Public).
FrameCheck checkFrame(Framing framing, const uint8_t* data, size_t available);

}  // namespace viscera::robot::espm
