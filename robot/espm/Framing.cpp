#include "robot/espm/Framing.h"

#include <stdexcept>

#include "robot/espm/Crc16.h"

namespace viscera::robot::espm {

const char* framingName(Framing framing) {
  switch (framing) {
    case Framing::Dissertation: return "dissertation";
    case Framing::Public: return "public";
    case Framing::Auto: return "auto";
  }
  return "auto";
}

bool parseFraming(std::string_view name, Framing& framing) {
  for (Framing f : {Framing::Dissertation, Framing::Public, Framing::Auto})
    if (name == framingName(f)) {
      framing = f;
      return true;
    }
  return false;
}

void appendDissertationFrame(std::vector<uint8_t>& out, const Quadlets& quadlets) {
  const size_t start = out.size();
  appendBigEndian32(out, kMagic);
  for (uint32_t q : quadlets) appendBigEndian32(out, q);
  const uint16_t crc = crc16(out.data() + start + 4, 4 * kInformationQuadlets);
  out.push_back(static_cast<uint8_t>(crc >> 8));
  out.push_back(static_cast<uint8_t>(crc & 0xFF));
}

void appendDissertationFrame(std::vector<uint8_t>& out, const Packet& packet) {
  appendDissertationFrame(out, encodePacket(packet));
}

void appendPublicFrame(std::vector<uint8_t>& out, uint16_t page, std::span<const uint32_t> payload) {
  if (payload.empty() || payload.size() > static_cast<size_t>(kMaxPublicPayload))
    throw std::invalid_argument("appendPublicFrame: the payload must have 1 to 1023 quadlets, not " +
                                std::to_string(payload.size()));
  const size_t start = out.size();
  appendBigEndian32(out, kMagic);
  appendBigEndian32(out, uint32_t{page} << 16 | static_cast<uint32_t>(payload.size()));
  for (uint32_t q : payload) appendBigEndian32(out, q);
  appendBigEndian32(out, crc16(out.data() + start + 4, 4 + 4 * payload.size()));
}

void appendPublicFrame(std::vector<uint8_t>& out, const Packet& packet) {
  const Quadlets q = encodePacket(packet);
  appendPublicFrame(out, kInformationPage, q);
}

void appendPacketFrame(std::vector<uint8_t>& out, Framing framing, const Packet& packet) {
  if (framing == Framing::Dissertation) appendDissertationFrame(out, packet);
  else if (framing == Framing::Public) appendPublicFrame(out, packet);
  else throw std::invalid_argument("appendPacketFrame: a packet is written in the dissertation or the public framing");
}

FrameCheck checkFrame(Framing framing, const uint8_t* data, size_t available) {
  FrameCheck c;
  if (framing == Framing::Dissertation) {
    c.size = kDissertationFrameBytes;
    c.length = kInformationQuadlets;
    if (available < c.size) return c;
    const uint16_t stored = static_cast<uint16_t>(data[c.size - 2] << 8 | data[c.size - 1]);
    c.status = crc16(data + 4, 4 * kInformationQuadlets) == stored ? FrameCheck::Ok : FrameCheck::BadCrc;
    return c;
  }
  if (available < 8) return c;
  const uint32_t header = loadBigEndian32(data + 4);
  c.page = static_cast<uint16_t>(header >> 16);
  c.length = static_cast<int>(header & 0x3FF);
  if ((header & 0xFC00) != 0 || c.length == 0) {
    c.status = FrameCheck::BadHeader;
    return c;
  }
  c.size = publicFrameBytes(c.length);
  if (available < c.size) return c;
  const uint32_t crcQuadlet = loadBigEndian32(data + c.size - 4);
  const bool ok = (crcQuadlet >> 16) == 0 && crc16(data + 4, c.size - 8) == (crcQuadlet & 0xFFFF);
  c.status = ok ? FrameCheck::Ok : FrameCheck::BadCrc;
  return c;
}

}  // namespace viscera::robot::espm
