// Fuzz target of the ESPM stream decoder. The input's first three bytes choose the framing (byte 0)
// and how the rest is cut into pieces (byte 1: the largest piece, 1 to 8192 bytes; byte 2: the
// seed of the piece sizes); the rest is the stream. Checked on every input, aborting on a
// violation:
//  - frames come in stream order without overlapping, inside the stream, in the requested framing;
//  - every frame re-encodes to exactly the bytes at its offset, and its packet to its payload;
//  - the counters add up: bytes in frames + bytes skipped = bytes fed = stream size.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/Packet.h"
#include "robot/espm/StreamDecoder.h"

using namespace viscera::robot::espm;

namespace {

void require(bool condition, const char* what) {
  if (condition) return;
  std::fprintf(stderr, "ESPM decoder invariant violated: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 3) return 0;
  constexpr Framing kFramings[3] = {Framing::Dissertation, Framing::Public, Framing::Auto};
  const Framing requested = kFramings[data[0] % 3];
  const size_t maxPiece = size_t{1} << (data[1] % 14);
  uint32_t seed = data[2];
  const uint8_t* stream = data + 3;
  const size_t n = size - 3;

  StreamDecoder decoder(requested);
  uint64_t nextFree = 0, inFrames = 0, frames = 0;
  std::vector<uint8_t> encoded;
  const auto check = [&](const DecodedFrame& f) {
    require(f.offset >= nextFree, "frames out of order or overlapping");
    require(f.offset + f.size <= n, "frame beyond the stream");
    require(requested == Framing::Auto || f.framing == requested, "frame in another framing than requested");
    encoded.clear();
    if (f.framing == Framing::Dissertation) {
      require(f.payload.size() == kInformationQuadlets, "dissertation frame without 32 quadlets");
      Quadlets q;
      std::memcpy(q.data(), f.payload.data(), sizeof q);
      appendDissertationFrame(encoded, q);
    } else {
      appendPublicFrame(encoded, f.page, f.payload);
    }
    require(encoded.size() == f.size && std::memcmp(encoded.data(), stream + f.offset, f.size) == 0,
            "frame does not re-encode to the bytes at its offset");
    if (f.packet) {
      const Quadlets q = encodePacket(*f.packet);
      require(f.payload.size() == q.size() && std::memcmp(q.data(), f.payload.data(), sizeof q) == 0,
              "packet does not re-encode to its payload");
    }
    nextFree = f.offset + f.size;
    inFrames += f.size;
    ++frames;
  };

  for (size_t pos = 0; pos < n;) {
    seed = seed * 1103515245u + 12345u;
    const size_t piece = std::min(n - pos, 1 + (seed >> 8) % maxPiece);
    decoder.feed(stream + pos, piece, check);
    pos += piece;
  }
  decoder.finish(check);

  const DecoderStats& s = decoder.stats();
  require(s.bytesFed == n, "bytes fed miscounted");
  require(s.bytesInFrames == inFrames && s.framesOk == frames, "frames miscounted");
  require(s.bytesInFrames + s.bytesSkipped == s.bytesFed, "bytes in frames + bytes skipped != bytes fed");
  require(s.packets <= s.framesOk && s.truncatedFrames <= 1, "counters out of range");
  return 0;
}
