// Frame layouts of both framings, and error detection: every single-bit error and every burst of
// up to 16 bits in a frame is caught (the CRC-16 is a polynomial code of degree 16 with a non-zero
// constant term, over the bits in stream order), so no corrupted frame is ever handed over.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/StreamDecoder.h"
#include "tests/robot/espm/espm_test_support.h"

using namespace viscera::robot::espm;

using espm_test::randomPacket;
using espm_test::referenceCrc;

namespace {

struct Decoded {
  std::vector<uint64_t> offsets;
  DecoderStats stats;
};

Decoded decodeAll(StreamDecoder& decoder, const std::vector<uint8_t>& bytes) {
  Decoded d;
  decoder.reset();
  const auto take = [&d](const DecodedFrame& f) { d.offsets.push_back(f.offset); };
  decoder.feed(bytes, take);
  decoder.finish(take);
  d.stats = decoder.stats();
  return d;
}

void flipBit(std::vector<uint8_t>& bytes, size_t bit) { bytes[bit / 8] ^= static_cast<uint8_t>(0x80 >> (bit % 8)); }

// Frames of both framings carrying a random information packet.
std::vector<uint8_t> oneFrame(Framing framing, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> bytes;
  appendPacketFrame(bytes, framing, randomPacket(rng));
  return bytes;
}

}  // namespace

TEST(EspmFraming, DissertationFrameLayout) {
  Packet p;
  p.instrumentId = 0x01020304;
  p.buttons.portClutch.normallyClosed = true;  // quadlet 0 = 1
  std::vector<uint8_t> f;
  appendDissertationFrame(f, p);
  ASSERT_EQ(f.size(), 134u);
  EXPECT_EQ(std::vector<uint8_t>(f.begin(), f.begin() + 8), (std::vector<uint8_t>{0xAC, 0x45, 0x0F, 0x28, 0, 0, 0, 1}));
  // Quadlet 24 big-endian at bytes 4 + 96.
  EXPECT_EQ(std::vector<uint8_t>(f.begin() + 100, f.begin() + 104), (std::vector<uint8_t>{1, 2, 3, 4}));
  // The CRC covers the 128 information bytes, not the magic, and is stored most significant first.
  const uint16_t crc = referenceCrc(f.data() + 4, 128);
  EXPECT_EQ(f[132], crc >> 8);
  EXPECT_EQ(f[133], crc & 0xFF);
}

TEST(EspmFraming, PublicFrameLayout) {
  const std::vector<uint32_t> payload{0xDEADBEEF, 0x00000001, 0x80000000};
  std::vector<uint8_t> f;
  appendPublicFrame(f, 0x1234, payload);
  ASSERT_EQ(f.size(), 24u);  // magic, header, 3 quadlets, CRC quadlet
  const std::vector<uint8_t> head{0xAC, 0x45, 0x0F, 0x28, 0x12, 0x34, 0x00, 0x03, 0xDE, 0xAD, 0xBE, 0xEF};
  EXPECT_EQ(std::vector<uint8_t>(f.begin(), f.begin() + 12), head);
  // {16'b0, crc16} over the header and the payload.
  const uint16_t crc = referenceCrc(f.data() + 4, 16);
  EXPECT_EQ(std::vector<uint8_t>(f.begin() + 20, f.end()),
            (std::vector<uint8_t>{0, 0, static_cast<uint8_t>(crc >> 8), static_cast<uint8_t>(crc & 0xFF)}));
  // The information packet is page 0, length 32.
  std::vector<uint8_t> packet;
  appendPublicFrame(packet, Packet{});
  ASSERT_EQ(packet.size(), 140u);
  EXPECT_EQ(loadBigEndian32(packet.data() + 4), 32u);

  EXPECT_THROW(appendPublicFrame(f, 0, std::vector<uint32_t>{}), std::invalid_argument);
  EXPECT_THROW(appendPublicFrame(f, 0, std::vector<uint32_t>(1024)), std::invalid_argument);
  std::vector<uint8_t> longest;
  appendPublicFrame(longest, 7, std::vector<uint32_t>(1023, 0x5A5A5A5A));
  EXPECT_EQ(longest.size(), kMaxFrameBytes);
  EXPECT_EQ(checkFrame(Framing::Public, longest.data(), longest.size()).status, FrameCheck::Ok);
}

TEST(EspmFraming, PublicHeaderAndCrcQuadletChecks) {
  std::vector<uint8_t> f;
  appendPublicFrame(f, 2, std::vector<uint32_t>{1, 2});
  EXPECT_EQ(checkFrame(Framing::Public, f.data(), f.size()).status, FrameCheck::Ok);
  EXPECT_EQ(checkFrame(Framing::Public, f.data(), f.size() - 1).status, FrameCheck::NeedMore);
  EXPECT_EQ(checkFrame(Framing::Public, f.data(), 7).status, FrameCheck::NeedMore);

  auto bad = f;
  bad[6] |= 0x04;  // header bit 10
  EXPECT_EQ(checkFrame(Framing::Public, bad.data(), bad.size()).status, FrameCheck::BadHeader);
  bad = f;
  bad[7] = 0;  // length 0
  EXPECT_EQ(checkFrame(Framing::Public, bad.data(), bad.size()).status, FrameCheck::BadHeader);
  // A non-zero upper half of the CRC quadlet, even with the right CRC below it.
  bad = f;
  bad[f.size() - 4] = 0x01;
  EXPECT_EQ(checkFrame(Framing::Public, bad.data(), bad.size()).status, FrameCheck::BadCrc);
}

// Every single-bit error in the middle frame of three: the other two are still decoded, at their
// offsets, and the damaged one never is.
TEST(EspmFraming, EverySingleBitErrorIsDetected) {
  for (Framing framing : {Framing::Dissertation, Framing::Public}) {
    std::mt19937_64 rng(11);
    std::vector<uint8_t> stream;
    for (int k = 0; k < 3; ++k) appendPacketFrame(stream, framing, randomPacket(rng));
    const size_t frame = packetFrameBytes(framing);
    StreamDecoder decoder(framing);
    ASSERT_EQ(decodeAll(decoder, stream).offsets, (std::vector<uint64_t>{0, frame, 2 * frame}));
    for (size_t bit = 8 * frame; bit < 16 * frame; ++bit) {
      auto damaged = stream;
      flipBit(damaged, bit);
      const Decoded d = decodeAll(decoder, damaged);
      ASSERT_EQ(d.offsets, (std::vector<uint64_t>{0, 2 * frame})) << framingName(framing) << " bit " << bit;
      ASSERT_EQ(d.stats.bytesInFrames + d.stats.bytesSkipped, d.stats.bytesFed);
    }
  }
}

// Every burst of length L = 1..16 bits (first and last bit flipped, any bits between) at every
// start position of a frame: all inner patterns for L <= 12, 48 seeded random ones for longer.
TEST(EspmFraming, EveryBurstUpTo16BitsIsDetected) {
  for (Framing framing : {Framing::Dissertation, Framing::Public}) {
    const std::vector<uint8_t> frame = oneFrame(framing, 5);
    const size_t bits = 8 * frame.size();
    StreamDecoder decoder(framing);
    ASSERT_EQ(decodeAll(decoder, frame).offsets.size(), 1u);
    std::mt19937_64 rng(99);
    uint64_t bursts = 0;
    for (int length = 1; length <= 16; ++length) {
      const int inner = std::max(0, length - 2);
      const bool exhaustive = length <= 12;
      const uint64_t patterns = exhaustive ? (uint64_t{1} << inner) : 48;
      for (size_t start = 0; start + length <= bits; ++start)
        for (uint64_t k = 0; k < patterns; ++k) {
          const uint64_t middle = exhaustive ? k : rng() & ((uint64_t{1} << inner) - 1);
          auto damaged = frame;
          flipBit(damaged, start);
          if (length > 1) flipBit(damaged, start + length - 1);
          for (int i = 0; i < inner; ++i)
            if ((middle >> i) & 1) flipBit(damaged, start + 1 + i);
          const Decoded d = decodeAll(decoder, damaged);
          ASSERT_TRUE(d.offsets.empty()) << framingName(framing) << " burst of " << length << " at bit " << start;
          ++bursts;
        }
    }
    // 1072 (dissertation) or 1152 (public) bit positions times the pattern counts.
    EXPECT_GT(bursts, 2000000u);
  }
}
