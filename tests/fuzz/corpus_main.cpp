// Runs a fuzz target without libFuzzer, as `make test` does: every file of the seed folders given
// (each file's bytes are one input, as libFuzzer runs a corpus), then `--mutations N` variants of
// each seed made by the mutations libFuzzer starts with (bit flips, bytes set to edge values,
// spans erased, repeated or cut, numbers replaced by extreme ones), from `--seed S`. A variant
// never changes the first byte, which picks the reader in the targets that have several.
#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

Bytes readBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Text that readers treat specially: numbers at and past the limits, and markup.
const char* const kTokens[] = {"-1", "0", "4294967296", "2147483648", "9223372036854775808", "1e308", "-1e308", "nan",
                               "inf", "1e-320", "0x1F", "65536", "100000000", "\xEF\xBB\xBF", "\r", "\n", "\"", "<", "/>",
                               "<Node>", "</Node>", ",", " ", "\t", "\0", "end_header\n", "DATA binary\n", "$EndElements"};

// Values an attribute may be given: edge numbers, several numbers, words and nothing.
const char* const kValues[] = {"0", "-1", "1e308", "-1e308", "nan", "inf", "1e-320", "4294967296", "65536 65536 1",
                               "1 1 100000000", "0 0 0", "1 2", "1 2 3 4 5 6 7", "", " ", "@missing", "@[-1].position",
                               "true", "false", "2 kPa", "1 N/m", "3 mm", "abc", "0-8", "0.5", "1e-12", "-0"};

// In an XML seed, most variants change one attribute value (keeping the markup whole, so that
// they reach the builder); the rest are byte-level.
bool mutateXmlValue(Bytes& in, std::mt19937_64& rng) {
  std::vector<std::pair<size_t, size_t>> values;  // [begin, end) inside the quotes
  for (size_t i = 1; i < in.size(); ++i)
    if (in[i] == '"' && in[i - 1] == '=') {
      const size_t end = static_cast<size_t>(std::find(in.begin() + static_cast<long>(i) + 1, in.end(), '"') - in.begin());
      if (end >= in.size()) break;
      values.push_back({i + 1, end});
      i = end;
    }
  if (values.empty()) return false;
  const auto [b, e] = values[rng() % values.size()];
  const std::string v = kValues[rng() % std::size(kValues)];
  in.erase(in.begin() + static_cast<long>(b), in.begin() + static_cast<long>(e));
  in.insert(in.begin() + static_cast<long>(b), v.begin(), v.end());
  return true;
}

Bytes mutate(Bytes in, std::mt19937_64& rng) {
  if (!in.empty() && in[0] == '<' && rng() % 10 < 7) {
    for (int m = 1 + static_cast<int>(rng() % 2); m > 0; --m) mutateXmlValue(in, rng);
    return in;
  }
  const int count = 1 + static_cast<int>(rng() % 4);
  for (int m = 0; m < count && in.size() > 1; ++m) {
    const size_t at = 1 + rng() % (in.size() - 1);
    const size_t span = 1 + rng() % std::min<size_t>(64, in.size() - at);
    switch (rng() % 7) {
      case 0: in[at] ^= static_cast<uint8_t>(1u << (rng() % 8)); break;
      case 1: in[at] = static_cast<uint8_t>(std::array<int, 6>{0, 0xFF, 0x7F, '-', '9', '.'}[rng() % 6]); break;
      case 2: in.erase(in.begin() + static_cast<long>(at), in.begin() + static_cast<long>(at + span)); break;
      case 3: {
        const Bytes piece(in.begin() + static_cast<long>(at), in.begin() + static_cast<long>(at + span));
        in.insert(in.begin() + static_cast<long>(at), piece.begin(), piece.end());
        break;
      }
      case 4: in.resize(at); break;
      case 5: {
        // A token in place of the number or word at `at`.
        size_t end = at;
        while (end < in.size() && (std::isalnum(in[end]) || in[end] == '.' || in[end] == '-' || in[end] == '+')) ++end;
        const std::string token = kTokens[rng() % std::size(kTokens)];
        in.erase(in.begin() + static_cast<long>(at), in.begin() + static_cast<long>(end));
        in.insert(in.begin() + static_cast<long>(at), token.begin(), token.end());
        break;
      }
      default:
        for (size_t k = 0; k < span && at + k < in.size(); ++k) in[at + k] = static_cast<uint8_t>(rng());
        break;
    }
  }
  return in;
}

}  // namespace

int main(int argc, char** argv) {
  long mutations = 0;
  unsigned long long seed = 1;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--mutations" || arg == "--seed") && i + 1 < argc) {
      char* end = nullptr;
      const unsigned long long value = std::strtoull(argv[++i], &end, 10);
      if (*end != '\0') {
        std::fprintf(stderr, "%s: %s needs a number, not '%s'\n", argv[0], arg.c_str(), argv[i]);
        return 2;
      }
      (arg == "--mutations" ? mutations = static_cast<long>(value) : 0), (arg == "--seed" ? seed = value : 0);
    } else if (fs::is_directory(arg)) {
      for (const auto& e : fs::recursive_directory_iterator(arg))
        if (e.is_regular_file()) files.push_back(e.path());
    } else if (fs::is_regular_file(arg)) {
      files.push_back(arg);
    } else {
      std::fprintf(stderr, "%s: no such file or folder: %s\n", argv[0], arg.c_str());
      return 2;
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: %s [--mutations N] [--seed S] FILE|FOLDER ...\n", argv[0]);
    return 2;
  }
  std::sort(files.begin(), files.end());  // the same order, and so the same variants, every run
  std::mt19937_64 rng(seed);
  long inputs = 0;
  for (const auto& f : files) {
    const Bytes seedBytes = readBytes(f);
    LLVMFuzzerTestOneInput(seedBytes.data(), seedBytes.size());
    ++inputs;
    for (long k = 0; k < mutations; ++k) {
      const Bytes v = mutate(seedBytes, rng);
      LLVMFuzzerTestOneInput(v.data(), v.size());
      ++inputs;
    }
  }
  std::printf("%ld inputs from %zu seeds, no failure\n", inputs, files.size());
  return 0;
}
