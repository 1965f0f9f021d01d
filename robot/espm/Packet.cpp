#include "robot/espm/Packet.h"

#include <bit>

namespace viscera::robot::espm {
namespace {

constexpr uint32_t bit(bool value, int position) { return static_cast<uint32_t>(value) << position; }
constexpr bool flag(uint32_t quadlet, int position) { return (quadlet >> position) & 1u; }

// A clutch's three bits with the ground fault at `top` (then normally open, normally closed).
constexpr uint32_t encodeClutch(const Clutch& c, int top) {
  return bit(c.groundFault, top) | bit(c.normallyOpen, top - 1) | bit(c.normallyClosed, top - 2);
}
constexpr Clutch decodeClutch(uint32_t q, int top) { return {flag(q, top), flag(q, top - 1), flag(q, top - 2)}; }

}  // namespace

uint32_t encodeButtons(const Buttons& b) {
  return bit(b.flexTransitionWarning, 27) | bit(b.flexFault, 26) | (uint32_t{b.cannulaPowerStable} & 0x3) << 24 |
         bit(b.voltageMonitorError, 23) | bit(b.esiiLinked, 22) | bit(b.esiiFault, 21) |
         (uint32_t{b.cannulaId} & 0x7) << 18 | bit(b.adapter2Present, 17) | bit(b.instrumentMagnet2, 16) |
         bit(b.instrumentMagnet1, 15) | encodeClutch(b.instrumentClutch, 14) | bit(b.loopBackPresent, 11) |
         bit(b.flexMotorSwitch.groundFault, 10) | bit(b.flexMotorSwitch.pressed, 9) |
         bit(b.flexMotorSwitch.direction, 8) | bit(b.adapter1Present, 7) | encodeClutch(b.link3Clutch, 6) |
         bit(b.debugPin, 3) | encodeClutch(b.portClutch, 2);
}

Buttons decodeButtons(uint32_t q) {
  Buttons b;
  b.flexTransitionWarning = flag(q, 27);
  b.flexFault = flag(q, 26);
  b.cannulaPowerStable = static_cast<uint8_t>((q >> 24) & 0x3);
  b.voltageMonitorError = flag(q, 23);
  b.esiiLinked = flag(q, 22);
  b.esiiFault = flag(q, 21);
  b.cannulaId = static_cast<uint8_t>((q >> 18) & 0x7);
  b.adapter2Present = flag(q, 17);
  b.instrumentMagnet2 = flag(q, 16);
  b.instrumentMagnet1 = flag(q, 15);
  b.instrumentClutch = decodeClutch(q, 14);
  b.loopBackPresent = flag(q, 11);
  b.flexMotorSwitch = {flag(q, 10), flag(q, 9), flag(q, 8)};
  b.adapter1Present = flag(q, 7);
  b.link3Clutch = decodeClutch(q, 6);
  b.debugPin = flag(q, 3);
  b.portClutch = decodeClutch(q, 2);
  return b;
}

uint32_t encodePot(const Potentiometer& p) {
  const uint32_t body = (uint32_t{p.position} & 0xFFF) << 6 | (uint32_t{p.flags} & 0x1F) << 1;
  // Even parity over bits 17:0: the parity bit is the parity of bits 17:1, flipped on request.
  const uint32_t parity = (std::popcount(body) & 1u) ^ static_cast<uint32_t>(!p.parityOk);
  return body | parity;
}

Potentiometer decodePot(uint32_t q) {
  return {static_cast<uint16_t>((q >> 6) & 0xFFF), static_cast<uint8_t>((q >> 1) & 0x1F),
          (std::popcount(q & kPotUsedBits) & 1) == 0};
}

uint32_t encodeEncoder(const EncoderPosition& e) {
  const uint32_t counter = (static_cast<uint32_t>(e.count) + static_cast<uint32_t>(kEncoderMidrange)) & 0xFFFFFF;
  return bit(e.overflow, 24) | counter;
}

EncoderPosition decodeEncoder(uint32_t q) {
  return {static_cast<int32_t>(q & 0xFFFFFF) - kEncoderMidrange, flag(q, 24)};
}

Quadlets encodePacket(const Packet& p) {
  Quadlets q{};
  q[kButtonsQuadlet] = encodeButtons(p.buttons);
  for (int j = 0; j < kJointChannels; ++j) {
    q[kFirstPotQuadlet + j] = encodePot(p.pots[j]);
    q[kFirstEncoderQuadlet + j] = encodeEncoder(p.encoders[j]);
    q[kFirstVelocityQuadlet + j] = p.velocityFirst[j];
    q[kSecondVelocityQuadlet + j] = p.velocitySecond[j];
  }
  q[kEsiiStatusQuadlet] = p.esiiStatus;
  q[kEspmStatusQuadlet] = p.espmStatus;
  q[kInstrumentIdQuadlet] = p.instrumentId;
  return q;
}

Packet decodePacket(const uint32_t* q) {
  Packet p;
  p.buttons = decodeButtons(q[kButtonsQuadlet]);
  p.unusedBitsSet = static_cast<uint32_t>((q[kButtonsQuadlet] & ~kButtonsUsedBits) != 0) << kButtonsQuadlet;
  for (int j = 0; j < kJointChannels; ++j) {
    const uint32_t pot = q[kFirstPotQuadlet + j];
    const uint32_t enc = q[kFirstEncoderQuadlet + j];
    p.pots[j] = decodePot(pot);
    p.encoders[j] = decodeEncoder(enc);
    p.unusedBitsSet |= static_cast<uint32_t>((pot & ~kPotUsedBits) != 0) << (kFirstPotQuadlet + j);
    p.unusedBitsSet |= static_cast<uint32_t>((enc & ~kEncoderUsedBits) != 0) << (kFirstEncoderQuadlet + j);
    p.velocityFirst[j] = q[kFirstVelocityQuadlet + j];
    p.velocitySecond[j] = q[kSecondVelocityQuadlet + j];
  }
  p.esiiStatus = q[kEsiiStatusQuadlet];
  p.espmStatus = q[kEspmStatusQuadlet];
  p.instrumentId = q[kInstrumentIdQuadlet];
  return p;
}

Packet decodePacket(const Quadlets& quadlets) { return decodePacket(quadlets.data()); }

}  // namespace viscera::robot::espm
