// The ESPM information packet of the dVRK-S arm (dissertation Appendix I, Tables I-1 to I-6): 32
// information quadlets (32-bit words) that the arm's FPGA streams to the controller, and its typed
// form. encodePacket / decodePacket convert between the two:
//  - Packet -> quadlets -> Packet is the identity for every valid Packet (fields within their bit
//    widths, encoder counts within 24 bits, unusedBitsSet == 0);
//  - quadlets -> Packet -> quadlets is the identity for quadlets whose unused bits are zero.
//
// Information quadlets (Table I-1):
//    0      buttons (Table I-6)
//    1-7    potentiometers 1-7 (Table I-2)
//    8      ESII status (raw; not monitored)
//    9-15   encoder positions 1-7 (Table I-3)
//    16     ESPM status (raw; not monitored)
//    17-23  first velocity quadlet of encoders 1-7 (Table I-4, Rev 6 period layout; raw)
//    24     instrument id (raw 32 bits)
//    25-31  second velocity quadlet of encoders 1-7 (Table I-5, Rev 6 layout; raw)
#pragma once

#include <array>
#include <cstdint>

namespace viscera::robot::espm {

inline constexpr int kInformationQuadlets = 32;
inline constexpr int kJointChannels = 7;  // 6 PSM joints and the jaw
using Quadlets = std::array<uint32_t, kInformationQuadlets>;

// Quadlet indices (Table I-1).
inline constexpr int kButtonsQuadlet = 0;
inline constexpr int kFirstPotQuadlet = 1;
inline constexpr int kEsiiStatusQuadlet = 8;
inline constexpr int kFirstEncoderQuadlet = 9;
inline constexpr int kEspmStatusQuadlet = 16;
inline constexpr int kFirstVelocityQuadlet = 17;
inline constexpr int kInstrumentIdQuadlet = 24;
inline constexpr int kSecondVelocityQuadlet = 25;

// One clutch's three sensors, from the most significant of its three bits down: ground fault
// (whether the cable is connected), then the normally open and the normally closed switch (two
// switches for redundancy).
struct Clutch {
  bool groundFault = false;
  bool normallyOpen = false;
  bool normallyClosed = false;
  bool operator==(const Clutch&) const = default;
};

// The flex motor switch (bits 10:8): ground fault, pressed, direction.
struct FlexMotorSwitch {
  bool groundFault = false;
  bool pressed = false;
  bool direction = false;
  bool operator==(const FlexMotorSwitch&) const = default;
};

// Buttons status quadlet (Table I-6). Bits 31:28 are unused.
struct Buttons {
  bool flexTransitionWarning = false;  // bit 27: flex switch contact transition warning
  bool flexFault = false;              // bit 26: flex switch contact fault
  uint8_t cannulaPowerStable = 0;      // bits 25:24 (2 bits); must be non-zero before cannulaId is read
  bool voltageMonitorError = false;    // bit 23
  bool esiiLinked = false;             // bit 22
  bool esiiFault = false;              // bit 21
  uint8_t cannulaId = 0;               // bits 20:18 (3 bits): cannula id or presence switch
  bool adapter2Present = false;        // bit 17: ECM or sterile adapter #2 present
  bool instrumentMagnet2 = false;      // bit 16
  bool instrumentMagnet1 = false;      // bit 15
  Clutch instrumentClutch;             // bits 14:12
  bool loopBackPresent = false;        // bit 11: instrument/camera loop back present
  FlexMotorSwitch flexMotorSwitch;     // bits 10:8
  bool adapter1Present = false;        // bit 7: ECM or sterile adapter #1 present
  Clutch link3Clutch;                  // bits 6:4
  bool debugPin = false;               // bit 3
  Clutch portClutch;                   // bits 2:0
  bool operator==(const Buttons&) const = default;
};

// Potentiometer quadlet (Table I-2): position in bits 17:6 (12 bits), flags in bits 5:1, parity in
// bit 0. The parity is EVEN over bits 17:0: the parity bit makes the number of ones in bits 17:0
// even. Bits 31:18 are unused.
struct Potentiometer {
  uint16_t position = 0;  // 0..4095
  uint8_t flags = 0;      // 0..31
  // Decoding: whether the quadlet's parity bit was right. Encoding writes the right parity bit
  // when true and deliberately the wrong one when false, so that a bad reading round-trips.
  bool parityOk = true;
  bool operator==(const Potentiometer&) const = default;
};

// Encoder position quadlet (Table I-3, Rev 7 layout): overflow in bit 24, a 24-bit counter in
// bits 23:0. The counter is offset binary around mid-range, as the dVRK host library reads it:
// count = counter - 0x800000, so counts run from -8388608 to 8388607. Bits 31:25 are unused.
struct EncoderPosition {
  int32_t count = 0;
  bool overflow = false;
  bool operator==(const EncoderPosition&) const = default;
};

inline constexpr int32_t kEncoderMidrange = 0x800000;
inline constexpr int32_t kEncoderCountMin = -kEncoderMidrange;     // -8388608
inline constexpr int32_t kEncoderCountMax = kEncoderMidrange - 1;  //  8388607

struct Packet {
  Buttons buttons;
  std::array<Potentiometer, kJointChannels> pots{};
  uint32_t esiiStatus = 0;
  std::array<EncoderPosition, kJointChannels> encoders{};
  uint32_t espmStatus = 0;
  std::array<uint32_t, kJointChannels> velocityFirst{};   // Table I-4 quadlets, raw
  uint32_t instrumentId = 0;
  std::array<uint32_t, kJointChannels> velocitySecond{};  // Table I-5 quadlets, raw
  // Set by decodePacket: bit i when information quadlet i had non-zero unused bits (buttons
  // 31:28, potentiometer 31:18, encoder 31:25). Those bits are not kept; encodePacket ignores
  // this field and writes unused bits as zero.
  uint32_t unusedBitsSet = 0;
  bool operator==(const Packet&) const = default;
};

// Which bits of each information quadlet carry information (the rest must be zero).
inline constexpr uint32_t kButtonsUsedBits = 0x0FFFFFFF;
inline constexpr uint32_t kPotUsedBits = 0x0003FFFF;
inline constexpr uint32_t kEncoderUsedBits = 0x01FFFFFF;
constexpr uint32_t usedBits(int quadlet) {
  if (quadlet == kButtonsQuadlet) return kButtonsUsedBits;
  if (quadlet >= kFirstPotQuadlet && quadlet < kFirstPotQuadlet + kJointChannels) return kPotUsedBits;
  if (quadlet >= kFirstEncoderQuadlet && quadlet < kFirstEncoderQuadlet + kJointChannels) return kEncoderUsedBits;
  return 0xFFFFFFFF;
}

// Field-wise conversions. Field values wider than their bits are masked to their width when
// encoding; an encoder count outside [kEncoderCountMin, kEncoderCountMax] wraps modulo 2^24 (as
// the 24-bit hardware counter does).
uint32_t encodeButtons(const Buttons& b);
Buttons decodeButtons(uint32_t quadlet);
uint32_t encodePot(const Potentiometer& p);
Potentiometer decodePot(uint32_t quadlet);
uint32_t encodeEncoder(const EncoderPosition& e);
EncoderPosition decodeEncoder(uint32_t quadlet);

Quadlets encodePacket(const Packet& packet);
Packet decodePacket(const Quadlets& quadlets);
// The same from 32 quadlets in caller storage (no copy).
Packet decodePacket(const uint32_t* quadlets);

}  // namespace viscera::robot::espm
