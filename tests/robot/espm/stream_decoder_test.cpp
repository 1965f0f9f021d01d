// The streaming decoder against streams whose every byte is known: a million packets mixed with
// garbage, idle gaps, truncated packets, dropped and inserted bytes and bit errors, fed in random
// pieces. Every intact packet must come out at its offset, nothing else may, and the counters must
// add up. Plus the cases the design turns on: resynchronising inside a failed frame, the overlap
// check, truncation at the end, unused bits, and the Auto framing's decision.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <vector>

#include "robot/espm/Crc16.h"
#include "robot/espm/Framing.h"
#include "robot/espm/StreamDecoder.h"
#include "tests/robot/espm/espm_test_support.h"

using namespace viscera::robot::espm;

using espm_test::randomPacket;

namespace {

// FNV-1a over payload quadlets: identifies a frame's content in the expected and decoded lists.
uint64_t hashQuadlets(std::span<const uint32_t> q) {
  uint64_t h = 1469598103934665603ull;
  for (uint32_t v : q) {
    h ^= v;
    h *= 1099511628211ull;
  }
  return h;
}

struct FrameId {
  uint64_t offset = 0;
  uint16_t page = 0;
  uint64_t hash = 0;
  bool operator==(const FrameId&) const = default;
};

std::ostream& operator<<(std::ostream& o, const FrameId& f) {
  return o << "{offset " << f.offset << ", page " << f.page << ", hash " << f.hash << "}";
}

// How often each kind of damage happens before a packet, per mille.
struct Damage {
  int garbage = 10;     // 1..64 random bytes, then an intact packet
  int idle = 20;        // 1..300 zero bytes, then an intact packet
  int truncated = 10;   // only the first 1..size-1 bytes of a packet
  int dropped = 10;     // a packet missing one byte
  int inserted = 5;     // a packet with one random byte added
  int burst = 10;       // a packet with a burst of up to 16 bits flipped
};

struct Stream {
  std::vector<uint8_t> bytes;
  std::vector<FrameId> intact;  // what a correct decoder hands over
  // Damaged packets whose magic is intact: each is at least one failed frame in the counters.
  uint64_t damagedWithMagic = 0;
};

// `count` packets in `framing`; with `otherPages`, one in ten is a public frame of another page
// and length instead (Public only).
Stream makeStream(Framing framing, int count, uint64_t seed, const Damage& d, bool otherPages = false) {
  std::mt19937_64 rng(seed);
  Stream s;
  s.bytes.reserve(static_cast<size_t>(count) * 150);
  std::vector<uint8_t> frame;
  for (int i = 0; i < count; ++i) {
    frame.clear();
    FrameId id;
    if (otherPages && rng() % 10 == 0) {
      std::vector<uint32_t> payload(1 + rng() % 64);
      for (auto& q : payload) q = static_cast<uint32_t>(rng());
      id.page = static_cast<uint16_t>(1 + rng() % 100);
      id.hash = hashQuadlets(payload);
      appendPublicFrame(frame, id.page, payload);
    } else {
      const Quadlets q = encodePacket(randomPacket(rng));
      id.hash = hashQuadlets(q);
      appendPacketFrame(frame, framing, decodePacket(q));
    }
    int r = static_cast<int>(rng() % 1000);
    bool intact = true;
    size_t damageAt = 0;  // first byte changed
    if ((r -= d.garbage) < 0) {
      for (size_t n = 1 + rng() % 64; n > 0; --n) s.bytes.push_back(static_cast<uint8_t>(rng()));
    } else if ((r -= d.idle) < 0) {
      s.bytes.resize(s.bytes.size() + 1 + rng() % 300, 0);
    } else if ((r -= d.truncated) < 0) {
      damageAt = 1 + rng() % (frame.size() - 1);
      frame.resize(damageAt);
      intact = false;
    } else if ((r -= d.dropped) < 0) {
      damageAt = rng() % frame.size();
      frame.erase(frame.begin() + static_cast<std::ptrdiff_t>(damageAt));
      intact = false;
    } else if ((r -= d.inserted) < 0) {
      damageAt = 1 + rng() % (frame.size() - 1);
      frame.insert(frame.begin() + static_cast<std::ptrdiff_t>(damageAt), static_cast<uint8_t>(rng()));
      intact = false;
    } else if ((r -= d.burst) < 0) {
      const size_t length = 1 + rng() % 16;
      const size_t start = rng() % (8 * frame.size() - length + 1);
      const uint64_t pattern = rng() | 1 | (uint64_t{1} << (length - 1));  // first and last bit flipped
      for (size_t b = 0; b < length; ++b)
        if ((pattern >> b) & 1) frame[(start + b) / 8] ^= static_cast<uint8_t>(0x80 >> ((start + b) % 8));
      damageAt = start / 8;
      intact = false;
    }
    // A magic changed in a byte past its 4th one, or cut after them, still announces a frame.
    if (!intact && damageAt >= 4 && !(frame.size() < 4)) ++s.damagedWithMagic;
    if (intact) {
      id.offset = s.bytes.size();
      s.intact.push_back(id);
    }
    s.bytes.insert(s.bytes.end(), frame.begin(), frame.end());
  }
  return s;
}

struct Result {
  std::vector<FrameId> frames;
  DecoderStats stats;
  Framing framing = Framing::Auto;
};

// Feeds `bytes` in pieces of random size (1..maxPiece bytes; 0 = all at once).
Result decode(const std::vector<uint8_t>& bytes, Framing framing, size_t maxPiece, uint64_t seed) {
  Result r;
  r.frames.reserve(bytes.size() / 134 + 1);
  StreamDecoder decoder(framing);
  const auto take = [&r](const DecodedFrame& f) { r.frames.push_back({f.offset, f.page, hashQuadlets(f.payload)}); };
  std::mt19937_64 rng(seed);
  size_t pos = 0;
  while (pos < bytes.size()) {
    const size_t piece = maxPiece == 0 ? bytes.size() : std::min(bytes.size() - pos, 1 + rng() % maxPiece);
    decoder.feed(bytes.data() + pos, piece, take);
    pos += piece;
  }
  decoder.finish(take);
  r.stats = decoder.stats();
  r.framing = decoder.framing();
  return r;
}

void expectConsistent(const DecoderStats& s, size_t streamBytes) {
  EXPECT_EQ(s.bytesFed, streamBytes);
  EXPECT_EQ(s.bytesInFrames + s.bytesSkipped, s.bytesFed);
}

// First index where two frame lists differ (for a short failure message).
size_t firstDifference(const std::vector<FrameId>& a, const std::vector<FrameId>& b) {
  size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  return i;
}

}  // namespace

// A CRC-16 passes a corrupted frame with probability 2^-16 unless the damage is a burst of at most
// 16 bits. Here bit errors are such bursts (always caught); truncated frames and dropped bytes
// are refused by the overlap check whenever the next packet is intact; what is left is a byte
// inserted into the raw second half of a packet (~2500 such packets) or two damaged packets in a
// row (~25): about 2500 * 2^-16 = 0.04 false packets expected, and none with this seed.
TEST(EspmStreamDecoder, MillionPacketDissertationStream) {
  const Stream s = makeStream(Framing::Dissertation, 1'000'000, 1, Damage{});
  const Result r = decode(s.bytes, Framing::Dissertation, 4096, 2);
  const size_t at = firstDifference(r.frames, s.intact);
  ASSERT_EQ(r.frames.size(), s.intact.size()) << "first difference at " << at;
  ASSERT_EQ(at, s.intact.size()) << (at < r.frames.size() ? r.frames[at] : FrameId{}) << " vs " << s.intact[at];
  expectConsistent(r.stats, s.bytes.size());
  EXPECT_EQ(r.stats.framesOk, s.intact.size());
  EXPECT_EQ(r.stats.packets, s.intact.size());
  EXPECT_EQ(r.stats.bytesInFrames, s.intact.size() * kDissertationFrameBytes);
  // Every damaged packet with its magic intact is one refused frame; stray magics in garbage
  // and in damaged frames (about 2^-32 per byte) add practically nothing.
  EXPECT_EQ(r.stats.crcFailures + r.stats.rejectedOverlap + r.stats.truncatedFrames, s.damagedWithMagic);
  EXPECT_GT(s.damagedWithMagic, 30'000u);
}

TEST(EspmStreamDecoder, PublicStreamWithOtherPages) {
  const Stream s = makeStream(Framing::Public, 300'000, 3, Damage{}, true);
  const Result r = decode(s.bytes, Framing::Public, 1000, 4);
  const size_t at = firstDifference(r.frames, s.intact);
  ASSERT_EQ(r.frames.size(), s.intact.size()) << "first difference at " << at;
  ASSERT_EQ(at, s.intact.size());
  expectConsistent(r.stats, s.bytes.size());
  EXPECT_LT(r.stats.packets, r.stats.framesOk);  // the other pages are frames, not packets
  EXPECT_EQ(r.stats.badHeaders + r.stats.crcFailures + r.stats.rejectedOverlap + r.stats.truncatedFrames,
            s.damagedWithMagic);
}

TEST(EspmStreamDecoder, AutoFramingDecidesAndKeepsEverything) {
  for (Framing framing : {Framing::Dissertation, Framing::Public}) {
    const Stream s = makeStream(framing, 100'000, 5, Damage{});
    const Result r = decode(s.bytes, Framing::Auto, 300, 6);
    EXPECT_EQ(r.framing, framing);
    ASSERT_EQ(r.frames, s.intact) << framingName(framing);
    expectConsistent(r.stats, s.bytes.size());
  }
}

TEST(EspmStreamDecoder, PiecesDoNotChangeTheResult) {
  const Stream s = makeStream(Framing::Public, 3'000, 8, Damage{}, true);
  const Result whole = decode(s.bytes, Framing::Public, 0, 0);
  ASSERT_EQ(whole.frames, s.intact);
  for (size_t maxPiece : {size_t{1}, size_t{3}, size_t{150}, size_t{5000}}) {
    const Result r = decode(s.bytes, Framing::Public, maxPiece, maxPiece);
    EXPECT_EQ(r.frames, whole.frames) << maxPiece;
    EXPECT_EQ(r.stats.crcFailures, whole.stats.crcFailures) << maxPiece;
    EXPECT_EQ(r.stats.badHeaders, whole.stats.badHeaders) << maxPiece;
    EXPECT_EQ(r.stats.bytesSkipped, whole.stats.bytesSkipped) << maxPiece;
  }
}

// A stray magic whose frame would swallow the start of a real one: the search goes on from the
// byte after the stray magic and finds the real frame at its offset.
TEST(EspmStreamDecoder, ResynchronisesAfterTheFailedMagicNotAfterItsFrame) {
  std::mt19937_64 rng(12);
  std::vector<uint8_t> bytes;
  appendBigEndian32(bytes, kMagic);
  for (int i = 0; i < 50; ++i) bytes.push_back(static_cast<uint8_t>(rng() | 1));  // no zero, no magic
  const uint64_t real = bytes.size();
  appendDissertationFrame(bytes, randomPacket(rng));
  const Result r = decode(bytes, Framing::Dissertation, 0, 0);
  ASSERT_EQ(r.frames.size(), 1u);
  EXPECT_EQ(r.frames[0].offset, real);
  EXPECT_EQ(r.stats.crcFailures, 1u);
  EXPECT_EQ(r.stats.bytesSkipped, real);

  // Public: a header announcing 1023 quadlets, then real frames and the end of the stream
  // before those 4104 bytes: the stray magic is a truncated frame, the real ones still come out.
  std::vector<uint8_t> pub;
  appendBigEndian32(pub, kMagic);
  appendBigEndian32(pub, 0x000003FF);
  std::vector<uint64_t> offsets;
  for (int k = 0; k < 5; ++k) {
    offsets.push_back(pub.size());
    appendPublicFrame(pub, randomPacket(rng));
  }
  const Result p = decode(pub, Framing::Public, 7, 1);
  ASSERT_EQ(p.frames.size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(p.frames[k].offset, offsets[k]);
  EXPECT_EQ(p.stats.truncatedFrames, 1u);
  expectConsistent(p.stats, pub.size());
}

TEST(EspmStreamDecoder, TruncatedFrameAtTheEnd) {
  std::mt19937_64 rng(13);
  std::vector<uint8_t> bytes;
  appendDissertationFrame(bytes, randomPacket(rng));
  appendDissertationFrame(bytes, randomPacket(rng));
  std::vector<uint8_t> third;
  appendDissertationFrame(third, randomPacket(rng));
  bytes.insert(bytes.end(), third.begin(), third.begin() + 50);
  const Result r = decode(bytes, Framing::Dissertation, 0, 0);
  EXPECT_EQ(r.frames.size(), 2u);
  EXPECT_EQ(r.stats.truncatedFrames, 1u);
  EXPECT_EQ(r.stats.bytesSkipped, 50u);
  expectConsistent(r.stats, bytes.size());
}

// A frame cut short whose CRC happens to pass over the start of the next frame (made to pass
// here by searching the cut frame's instrument id): the overlap check refuses it.
TEST(EspmStreamDecoder, CutFrameThatPassesItsCrcIsRefusedByTheOverlapCheck) {
  std::mt19937_64 rng(14);
  const Packet next = randomPacket(rng);
  std::vector<uint8_t> nextFrame;
  appendDissertationFrame(nextFrame, next);
  const size_t cut = 120;  // bytes of the first frame that arrive; quadlet 24 (bytes 100..103) is among them
  Packet first = randomPacket(rng);
  std::vector<uint8_t> bytes;
  bool passes = false;
  for (uint32_t id = 0; id < (1u << 22) && !passes; ++id) {
    first.instrumentId = id;
    bytes.clear();
    appendDissertationFrame(bytes, first);
    bytes.resize(cut);
    bytes.insert(bytes.end(), nextFrame.begin(), nextFrame.end());
    passes = checkFrame(Framing::Dissertation, bytes.data(), bytes.size()).status == FrameCheck::Ok;
  }
  ASSERT_TRUE(passes);
  const Result r = decode(bytes, Framing::Dissertation, 0, 0);
  ASSERT_EQ(r.frames.size(), 1u);
  EXPECT_EQ(r.frames[0].offset, cut);
  EXPECT_EQ(r.frames[0].hash, hashQuadlets(encodePacket(next)));
  EXPECT_EQ(r.stats.rejectedOverlap, 1u);
}

TEST(EspmStreamDecoder, PacketWithUnusedBitsIsRefused) {
  Quadlets q{};
  q[kFirstEncoderQuadlet + 2] = 0x02800000;  // encoder 3: bit 25 set
  std::vector<uint8_t> bytes;
  appendDissertationFrame(bytes, q);
  const Result r = decode(bytes, Framing::Dissertation, 0, 0);
  EXPECT_TRUE(r.frames.empty());
  EXPECT_EQ(r.stats.rejectedUnusedBits, 1u);
  // Frames taken as plain quadlets (the flash link) are not checked.
  StreamDecoder raw(Framing::Dissertation, false);
  int frames = 0;
  raw.feed(bytes, [&](const DecodedFrame& f) { frames += f.packet == nullptr; });
  raw.finish([&](const DecodedFrame& f) { frames += f.packet == nullptr; });
  EXPECT_EQ(frames, 1);
}

// A public stream built so that every frame also passes the dissertation CRC (the upper half of
// the last payload quadlet is set to the CRC a dissertation frame would carry there): Auto must
// still decide Public, because the dissertation reading is never followed by another frame.
TEST(EspmStreamDecoder, AutoIsNotFooledByAFrameThatPassesBothCrcs) {
  std::mt19937_64 rng(15);
  std::vector<uint8_t> bytes;
  std::vector<uint64_t> offsets;
  for (int k = 0; k < 20; ++k) {
    Quadlets q = encodePacket(randomPacket(rng));
    std::vector<uint8_t> probe;
    appendPublicFrame(probe, kInformationPage, q);
    // Bytes 4..131 of the public frame are what a dissertation frame's CRC would cover, and bytes
    // 132..133 (the upper half of payload quadlet 31) where it would be stored.
    const uint16_t crc = crc16(probe.data() + 4, 128);
    q[31] = (q[31] & 0xFFFF) | uint32_t{crc} << 16;
    offsets.push_back(bytes.size());
    appendPublicFrame(bytes, kInformationPage, q);
    ASSERT_EQ(checkFrame(Framing::Dissertation, bytes.data() + offsets.back(), bytes.size() - offsets.back()).status,
              FrameCheck::Ok);
  }
  const Result r = decode(bytes, Framing::Auto, 0, 0);
  EXPECT_EQ(r.framing, Framing::Public);
  ASSERT_EQ(r.frames.size(), 20u);
  for (int k = 0; k < 20; ++k) EXPECT_EQ(r.frames[k].offset, offsets[k]);
}

TEST(EspmStreamDecoder, AutoDecidesAcrossIdleGapsAndNotFromOneFrame) {
  std::mt19937_64 rng(16);
  // Packets every 2500 bytes (1 kHz at 20 Mbit/s), idle zeros between.
  std::vector<uint8_t> bytes;
  for (int k = 0; k < 5; ++k) {
    bytes.resize(2500 * static_cast<size_t>(k), 0);
    appendPublicFrame(bytes, randomPacket(rng));
  }
  const Result r = decode(bytes, Framing::Auto, 97, 3);
  EXPECT_EQ(r.framing, Framing::Public);
  ASSERT_EQ(r.frames.size(), 5u);
  EXPECT_EQ(r.frames[4].offset, 10000u);

  // One frame alone does not decide anything: nothing is handed over.
  std::vector<uint8_t> single;
  appendDissertationFrame(single, randomPacket(rng));
  const Result one = decode(single, Framing::Auto, 0, 0);
  EXPECT_EQ(one.framing, Framing::Auto);
  EXPECT_TRUE(one.frames.empty());
  expectConsistent(one.stats, single.size());
  EXPECT_EQ(one.stats.bytesSkipped, single.size());
}

// Undecided, the decoder holds at most about 2 * kAutoHoldBytes: after 10 MiB of garbage it has
// dropped the oldest bytes, and still decides and decodes the packets that follow.
TEST(EspmStreamDecoder, AutoDropsOldBytesWhileUndecided) {
  std::mt19937_64 rng(17);
  std::vector<uint8_t> bytes(size_t{10} << 20);
  for (auto& b : bytes) b = static_cast<uint8_t>(rng() | 1);  // no zero bytes, (practically) no magic
  const uint64_t garbage = bytes.size();
  for (int k = 0; k < 4; ++k) appendDissertationFrame(bytes, randomPacket(rng));
  const Result r = decode(bytes, Framing::Auto, 65536, 1);
  EXPECT_EQ(r.framing, Framing::Dissertation);
  ASSERT_EQ(r.frames.size(), 4u);
  EXPECT_EQ(r.frames[0].offset, garbage);
  EXPECT_EQ(r.stats.bytesSkipped, garbage);
  expectConsistent(r.stats, bytes.size());
}

TEST(EspmStreamDecoder, FeedAfterFinishIsRefusedUntilReset) {
  StreamDecoder decoder(Framing::Dissertation);
  const uint8_t byte = 0;
  decoder.finish({});
  EXPECT_THROW(decoder.feed(&byte, 1, {}), std::logic_error);
  decoder.reset();
  EXPECT_NO_THROW(decoder.feed(&byte, 1, {}));
}
