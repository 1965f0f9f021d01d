// The ESPM stream decoder on a back-to-back stream (no idle bytes, the worst case for the line):
// about 4 MB of random information packets, pre-built, fed in 64 KiB pieces as a capture reader
// would. Target: at least 100 times the 20 Mbit/s line (2.5 MB/s), i.e. 250 MB/s on one core;
// "x_line_rate" is the measured rate over the line's.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/StreamDecoder.h"

using namespace viscera::robot::espm;

namespace {

constexpr double kLineBytesPerSecond = 20e6 / 8;

std::vector<uint8_t> backToBackStream(Framing framing, size_t targetBytes) {
  std::mt19937_64 rng(1);
  std::vector<uint8_t> bytes;
  bytes.reserve(targetBytes + kMaxFrameBytes);
  while (bytes.size() < targetBytes) {
    Quadlets q;
    for (int i = 0; i < kInformationQuadlets; ++i) q[i] = static_cast<uint32_t>(rng()) & usedBits(i);
    appendPacketFrame(bytes, framing, decodePacket(q));
  }
  return bytes;
}

void decodeStream(benchmark::State& state, Framing framing) {
  const std::vector<uint8_t> stream = backToBackStream(framing, size_t{4} << 20);
  constexpr size_t kPiece = 64 * 1024;
  StreamDecoder decoder(framing);
  uint64_t encoderSum = 0;  // touches every packet so that the decode is not optimised away
  const auto take = [&encoderSum](const DecodedFrame& f) { encoderSum += static_cast<uint32_t>(f.packet->encoders[0].count); };
  for (auto _ : state) {
    decoder.reset();
    for (size_t pos = 0; pos < stream.size(); pos += kPiece)
      decoder.feed(stream.data() + pos, std::min(kPiece, stream.size() - pos), take);
    decoder.finish(take);
    benchmark::DoNotOptimize(encoderSum);
  }
  if (decoder.stats().packets * packetFrameBytes(framing) != stream.size()) state.SkipWithError("packets were lost");
  const double bytes = static_cast<double>(stream.size()) * static_cast<double>(state.iterations());
  state.SetBytesProcessed(static_cast<int64_t>(bytes));
  state.counters["x_line_rate"] = benchmark::Counter(bytes / kLineBytesPerSecond, benchmark::Counter::kIsRate);
}

void BM_EspmStreamDecodeDissertation(benchmark::State& state) { decodeStream(state, Framing::Dissertation); }
void BM_EspmStreamDecodePublic(benchmark::State& state) { decodeStream(state, Framing::Public); }
BENCHMARK(BM_EspmStreamDecodeDissertation)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EspmStreamDecodePublic)->Unit(benchmark::kMillisecond);

}  // namespace
