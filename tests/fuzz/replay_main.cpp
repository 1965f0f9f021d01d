// Runs the ESPM decoder fuzz target without libFuzzer: over the files named on the command line
// (each file's bytes are one input, as libFuzzer runs a corpus; a folder stands for its files), or
// over N generated inputs with `--generated N [--seed S]`: valid streams of random frames in
// either framing, then mutated by bit flips, slipped (dropped or inserted) bytes, truncation,
// garbage runs, repeated spans and stray magics.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/Packet.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

using namespace viscera::robot::espm;
namespace fs = std::filesystem;

std::vector<uint8_t> generatedInput(std::mt19937_64& rng) {
  std::vector<uint8_t> in{static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng()), static_cast<uint8_t>(rng())};
  // A valid stream: information packets of one framing, sometimes other public pages, idle gaps.
  const Framing framing = rng() % 2 ? Framing::Public : Framing::Dissertation;
  for (int frames = 1 + static_cast<int>(rng() % 12); frames > 0; --frames) {
    if (rng() % 4 == 0) in.resize(in.size() + rng() % 40, 0);
    if (framing == Framing::Public && rng() % 5 == 0) {
      std::vector<uint32_t> payload(1 + rng() % 40);
      for (auto& q : payload) q = static_cast<uint32_t>(rng());
      appendPublicFrame(in, static_cast<uint16_t>(rng()), payload);
      continue;
    }
    Quadlets q;
    // Mostly well-formed packets; now and then one with unused bits set.
    const bool wellFormed = rng() % 8 != 0;
    for (int i = 0; i < kInformationQuadlets; ++i) q[i] = static_cast<uint32_t>(rng()) & (wellFormed ? usedBits(i) : ~0u);
    if (framing == Framing::Public) appendPublicFrame(in, kInformationPage, q);
    else appendDissertationFrame(in, q);
  }
  // Mutations, never touching the three control bytes.
  for (int m = static_cast<int>(rng() % 5); m > 0 && in.size() > 4; --m) {
    const size_t at = 3 + rng() % (in.size() - 3);
    switch (rng() % 7) {
      case 0:  // bit flips in a short span
        for (int k = 1 + static_cast<int>(rng() % 3); k > 0; --k)
          in[std::min(in.size() - 1, at + rng() % 4)] ^= static_cast<uint8_t>(1u << (rng() % 8));
        break;
      case 1:  // a dropped byte
        in.erase(in.begin() + static_cast<std::ptrdiff_t>(at));
        break;
      case 2:  // an inserted byte
        in.insert(in.begin() + static_cast<std::ptrdiff_t>(at), static_cast<uint8_t>(rng()));
        break;
      case 3:  // the stream cut short
        in.resize(at);
        break;
      case 4: {  // a garbage run
        std::vector<uint8_t> garbage(1 + rng() % 64);
        for (auto& b : garbage) b = static_cast<uint8_t>(rng());
        in.insert(in.begin() + static_cast<std::ptrdiff_t>(at), garbage.begin(), garbage.end());
        break;
      }
      case 5: {  // a span repeated
        const size_t length = std::min(in.size() - at, 1 + rng() % 200);
        const std::vector<uint8_t> span(in.begin() + static_cast<std::ptrdiff_t>(at),
                                        in.begin() + static_cast<std::ptrdiff_t>(at + length));
        in.insert(in.begin() + static_cast<std::ptrdiff_t>(at), span.begin(), span.end());
        break;
      }
      default: {  // a stray magic
        std::vector<uint8_t> magic;
        appendBigEndian32(magic, kMagic);
        in.insert(in.begin() + static_cast<std::ptrdiff_t>(at), magic.begin(), magic.end());
        break;
      }
    }
  }
  return in;
}

bool runFile(const fs::path& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    std::fprintf(stderr, "fuzz_espm_replay: cannot read %s\n", path.string().c_str());
    return false;
  }
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  LLVMFuzzerTestOneInput(bytes.data(), bytes.size());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  long generated = 0;
  uint64_t seed = 1;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--generated" || arg == "--seed") && i + 1 < argc) {
      char* end = nullptr;
      const unsigned long long value = std::strtoull(argv[++i], &end, 10);
      if (*end != '\0') {
        std::fprintf(stderr, "fuzz_espm_replay: %s needs a number, not '%s'\n", arg.c_str(), argv[i]);
        return 2;
      }
      if (arg == "--generated") generated = static_cast<long>(value);
      else seed = value;
    } else if (fs::is_directory(arg)) {
      std::vector<fs::path> inside;
      for (const auto& entry : fs::directory_iterator(arg))
        if (entry.is_regular_file()) inside.push_back(entry.path());
      std::sort(inside.begin(), inside.end());
      files.insert(files.end(), inside.begin(), inside.end());
    } else {
      files.emplace_back(arg);
    }
  }
  if (generated == 0 && files.empty()) {
    std::fprintf(stderr, "usage: fuzz_espm_replay [--generated N [--seed S]] [FILE|FOLDER ...]\n");
    return 2;
  }
  for (const fs::path& f : files)
    if (!runFile(f)) return 2;
  std::mt19937_64 rng(seed);
  uint64_t bytes = 0;
  for (long i = 0; i < generated; ++i) {
    const std::vector<uint8_t> input = generatedInput(rng);
    bytes += input.size();
    LLVMFuzzerTestOneInput(input.data(), input.size());
  }
  std::printf("fuzz_espm_replay: %zu files and %ld generated inputs (%llu bytes): every invariant held\n", files.size(),
              generated, static_cast<unsigned long long>(bytes));
  return 0;
}
