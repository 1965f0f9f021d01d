// The ESPM CRC-16 (check value, agreement with a bit-serial reference, incremental use) and the
// information packet's bit layout (Tables I-1 to I-6) and round trips.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "robot/espm/Crc16.h"
#include "robot/espm/Packet.h"
#include "tests/robot/espm/espm_test_support.h"

using namespace viscera::robot::espm;

using espm_test::randomPacket;
using espm_test::referenceCrc;

namespace {

}  // namespace

TEST(EspmCrc, CheckValueOfDigits) {
  const char* digits = "123456789";
  EXPECT_EQ(crc16(reinterpret_cast<const uint8_t*>(digits), 9), 0x9BE5);  // the firmware's check value
  EXPECT_EQ(crc16(nullptr, 0), 0xFFFF);                                    // nothing shifted in
}

TEST(EspmCrc, TableDrivenMatchesBitSerialAndIncremental) {
  std::mt19937_64 rng(7);
  std::vector<uint8_t> buffer(300);
  for (auto& b : buffer) b = static_cast<uint8_t>(rng());
  for (size_t size = 0; size <= buffer.size(); ++size) {
    const uint16_t expected = referenceCrc(buffer.data(), size);
    ASSERT_EQ(crc16(buffer.data(), size), expected) << size;
    // Any split into two pieces gives the same CRC.
    const size_t cut = size / 3;
    Crc16 crc;
    crc.update(buffer.data(), cut);
    crc.update(buffer.data() + cut, size - cut);
    ASSERT_EQ(crc.value(), expected) << size;
  }
}

TEST(EspmPacket, ButtonsBitsFollowTableI6) {
  // One field at a time, against the bit numbers of Table I-6.
  const auto only = [](auto set) {
    Buttons b;
    set(b);
    return encodeButtons(b);
  };
  EXPECT_EQ(only([](Buttons& b) { b.flexTransitionWarning = true; }), 1u << 27);
  EXPECT_EQ(only([](Buttons& b) { b.flexFault = true; }), 1u << 26);
  EXPECT_EQ(only([](Buttons& b) { b.cannulaPowerStable = 3; }), 3u << 24);
  EXPECT_EQ(only([](Buttons& b) { b.voltageMonitorError = true; }), 1u << 23);
  EXPECT_EQ(only([](Buttons& b) { b.esiiLinked = true; }), 1u << 22);
  EXPECT_EQ(only([](Buttons& b) { b.esiiFault = true; }), 1u << 21);
  EXPECT_EQ(only([](Buttons& b) { b.cannulaId = 5; }), 5u << 18);
  EXPECT_EQ(only([](Buttons& b) { b.adapter2Present = true; }), 1u << 17);
  EXPECT_EQ(only([](Buttons& b) { b.instrumentMagnet2 = true; }), 1u << 16);
  EXPECT_EQ(only([](Buttons& b) { b.instrumentMagnet1 = true; }), 1u << 15);
  EXPECT_EQ(only([](Buttons& b) { b.instrumentClutch.groundFault = true; }), 1u << 14);
  EXPECT_EQ(only([](Buttons& b) { b.instrumentClutch.normallyOpen = true; }), 1u << 13);
  EXPECT_EQ(only([](Buttons& b) { b.instrumentClutch.normallyClosed = true; }), 1u << 12);
  EXPECT_EQ(only([](Buttons& b) { b.loopBackPresent = true; }), 1u << 11);
  EXPECT_EQ(only([](Buttons& b) { b.flexMotorSwitch.groundFault = true; }), 1u << 10);
  EXPECT_EQ(only([](Buttons& b) { b.flexMotorSwitch.pressed = true; }), 1u << 9);
  EXPECT_EQ(only([](Buttons& b) { b.flexMotorSwitch.direction = true; }), 1u << 8);
  EXPECT_EQ(only([](Buttons& b) { b.adapter1Present = true; }), 1u << 7);
  EXPECT_EQ(only([](Buttons& b) { b.link3Clutch.groundFault = true; }), 1u << 6);
  EXPECT_EQ(only([](Buttons& b) { b.link3Clutch.normallyOpen = true; }), 1u << 5);
  EXPECT_EQ(only([](Buttons& b) { b.link3Clutch.normallyClosed = true; }), 1u << 4);
  EXPECT_EQ(only([](Buttons& b) { b.debugPin = true; }), 1u << 3);
  EXPECT_EQ(only([](Buttons& b) { b.portClutch.groundFault = true; }), 1u << 2);
  EXPECT_EQ(only([](Buttons& b) { b.portClutch.normallyOpen = true; }), 1u << 1);
  EXPECT_EQ(only([](Buttons& b) { b.portClutch.normallyClosed = true; }), 1u << 0);
  // Every used bit decodes to exactly one field and back.
  for (int bit = 0; bit < 28; ++bit) EXPECT_EQ(encodeButtons(decodeButtons(1u << bit)), 1u << bit) << bit;
}

TEST(EspmPacket, PotentiometerLayoutAndEvenParity) {
  // Position 0xABC in 17:6, flags 0b10110 in 5:1: 0xABC << 6 = 0x2AF00, 0x16 << 1 = 0x2C.
  // 0x2AF2C = 10 1010 1111 0010 1100 has 10 ones, already even, so the parity bit is 0.
  EXPECT_EQ(encodePot({0xABC, 0x16, true}), 0x2AF2Cu);
  // Position 1, no flags: bit 6 alone is one 1, so the parity bit is set.
  EXPECT_EQ(encodePot({1, 0, true}), 0x41u);
  EXPECT_TRUE(decodePot(0x41).parityOk);
  EXPECT_FALSE(decodePot(0x40).parityOk);  // odd number of ones in 17:0
  EXPECT_EQ(decodePot(0x2AF2C).position, 0xABC);
  EXPECT_EQ(decodePot(0x2AF2C).flags, 0x16);
  // A bad parity is written on request, so that a bad reading round-trips.
  EXPECT_EQ(encodePot({1, 0, false}), 0x40u);
}

TEST(EspmPacket, EncoderIsOffsetBinaryAroundMidrange) {
  EXPECT_EQ(encodeEncoder({0, false}), 0x800000u);
  EXPECT_EQ(encodeEncoder({-8388608, false}), 0x000000u);
  EXPECT_EQ(encodeEncoder({8388607, true}), 0x1FFFFFFu);  // overflow bit 24 and counter 0xFFFFFF
  EXPECT_EQ(decodeEncoder(0x800001).count, 1);
  EXPECT_EQ(decodeEncoder(0x7FFFFF).count, -1);
  EXPECT_TRUE(decodeEncoder(0x1000000).overflow);
  EXPECT_EQ(decodeEncoder(0x1000000).count, -8388608);
}

TEST(EspmPacket, QuadletPositionsFollowTableI1) {
  Packet p;
  p.buttons.debugPin = true;           // quadlet 0 = 0x8
  p.pots[6] = {2, 0, true};            // quadlet 7 = 2 << 6 = 0x80, one 1: parity bit set
  p.esiiStatus = 0x11111111;           // quadlet 8
  p.encoders[0] = {5, false};          // quadlet 9
  p.espmStatus = 0x22222222;           // quadlet 16
  p.velocityFirst[0] = 0x33333333;     // quadlet 17
  p.velocityFirst[6] = 0x44444444;     // quadlet 23
  p.instrumentId = 0x55555555;         // quadlet 24
  p.velocitySecond[0] = 0x66666666;    // quadlet 25
  p.velocitySecond[6] = 0x77777777;    // quadlet 31
  const Quadlets q = encodePacket(p);
  EXPECT_EQ(q[0], 0x8u);
  EXPECT_EQ(q[7], 0x81u);
  EXPECT_EQ(q[8], 0x11111111u);
  EXPECT_EQ(q[9], 0x800005u);
  EXPECT_EQ(q[16], 0x22222222u);
  EXPECT_EQ(q[17], 0x33333333u);
  EXPECT_EQ(q[23], 0x44444444u);
  EXPECT_EQ(q[24], 0x55555555u);
  EXPECT_EQ(q[25], 0x66666666u);
  EXPECT_EQ(q[31], 0x77777777u);
}

TEST(EspmPacket, RoundTripsOfTenThousandRandomPackets) {
  std::mt19937_64 rng(2024);
  for (int i = 0; i < 10000; ++i) {
    // Quadlets with unused bits zero (any parity) -> Packet -> the same quadlets.
    Quadlets q;
    for (int k = 0; k < kInformationQuadlets; ++k) q[k] = static_cast<uint32_t>(rng()) & usedBits(k);
    const Packet p = decodePacket(q);
    ASSERT_EQ(p.unusedBitsSet, 0u);
    ASSERT_EQ(encodePacket(p), q) << "packet " << i;
    // Packet -> quadlets -> the same Packet.
    const Packet r = randomPacket(rng);
    ASSERT_EQ(decodePacket(encodePacket(r)), r) << "packet " << i;
  }
}

TEST(EspmPacket, UnusedBitsAreFlaggedAndDropped) {
  Quadlets q{};
  q[0] = 0x10000000;  // buttons bit 28
  q[3] = 0x00040000;  // potentiometer 3 bit 18
  q[15] = 0x02000000; // encoder 7 bit 25
  q[8] = 0xFFFFFFFF;  // ESII status is raw: no unused bits
  const Packet p = decodePacket(q);
  EXPECT_EQ(p.unusedBitsSet, (1u << 0) | (1u << 3) | (1u << 15));
  const Quadlets back = encodePacket(p);
  EXPECT_EQ(back[0], 0u);
  EXPECT_EQ(back[3], 0u);
  EXPECT_EQ(back[15], 0u);  // counter 0 (count -8388608) is written back as counter 0
  EXPECT_EQ(back[8], 0xFFFFFFFFu);
}
