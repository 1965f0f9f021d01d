#include "engine/State.h"
#include "core/Files.h"

#include <fstream>
#include <iterator>

#include "core/Error.h"

namespace viscera {

namespace {
constexpr char kMagic[8] = {'V', 'S', 'C', 'S', 'T', 'A', 'T', 'E'};
constexpr std::uint32_t kVersion = 1;
}  // namespace

void StateReader::finish() const {
  if (pos_ != in_.size()) mismatch("it holds more values than this model has");
}

void StateReader::mismatch(const std::string& why) const {
  throw Error("state block of " + what_ + " does not fit this model: " + why);
}

size_t State::bytes() const {
  size_t n = 0;
  for (const auto& b : blocks) n += b.bytes.size();
  return n;
}

void State::save(const std::string& file) const {
  std::vector<char> out(std::begin(kMagic), std::end(kMagic));
  StateWriter w(out);
  w.put(kVersion);
  w.put(time);
  w.put(steps);
  w.count(static_cast<std::int64_t>(blocks.size()));
  for (const auto& b : blocks) {
    w.count(static_cast<std::int64_t>(b.component.size()));
    w.raw(b.component.data(), b.component.size());
    w.put(b.bytes);
  }
  writeFileAtomic(file, std::string(out.begin(), out.end()));
}

State State::load(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error(SourceLoc{file}, "cannot open the state file");
  std::vector<char> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data.size() < sizeof kMagic || !std::equal(std::begin(kMagic), std::end(kMagic), data.begin()))
    throw Error(SourceLoc{file}, "not a Viscera state file");
  std::vector<char> body(data.begin() + sizeof kMagic, data.end());
  StateReader r(body, "the file");
  State s;
  try {
    std::uint32_t version = 0;
    r.get(version);
    if (version != kVersion) throw Error("state file version " + std::to_string(version) + " (this build reads 1)");
    r.get(s.time);
    r.get(s.steps);
    const std::int64_t n = r.count();
    if (static_cast<size_t>(n) > body.size()) r.mismatch("a bad block count");
    s.blocks.resize(n);
    for (auto& b : s.blocks) {
      const std::int64_t len = r.count();
      if (static_cast<size_t>(len) > body.size()) r.mismatch("a bad name length");
      b.component.resize(len);
      r.raw(b.component.data(), len);
      r.get(b.bytes);
    }
    r.finish();
  } catch (const Error& e) {
    throw Error(SourceLoc{file}, std::string("corrupt state file: ") + e.what());
  }
  return s;
}

}  // namespace viscera
