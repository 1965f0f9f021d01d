#include "core/State.h"
#include "core/Files.h"

#include <fstream>
#include <iterator>

#include "core/Error.h"

namespace viscera {

namespace {
constexpr char kMagic[8] = {'V', 'S', 'C', 'S', 'T', 'A', 'T', 'E'};
constexpr std::uint32_t kVersion = 3;  // 2: every stateful component has a block (springs, solvers, mappings); 3: plastic strains
}  // namespace

void StateReader::finish() const {
  if (pos_ != in_.size()) mismatch("it holds more values than this model has");
}

void StateReader::mismatch(const std::string& why) const {
  throw Error("state block of " + what_ + " does not fit this model: " + why);
}

State::State(const State& o) : time(o.time), steps(o.steps) {
  blocks_.reserve(o.blocks_.size());
  for (const auto& b : o.blocks_) blocks_.push_back({b.component, b.data ? b.data->clone() : nullptr, b.saved});
}

State& State::operator=(const State& o) {
  if (this != &o) {
    State copy(o);
    *this = std::move(copy);
  }
  return *this;
}

void State::add(std::string name, std::unique_ptr<ComponentState> data) {
  blocks_.push_back({std::move(name), std::move(data), {}});
}

ComponentState& State::live(int slot) {
  if (slot < 0 || static_cast<size_t>(slot) >= blocks_.size() || !blocks_[slot].data)
    throw Error("a component's state block is missing: the state was read from a file or made for another model "
                "(restore it into a simulation first)");
  return *blocks_[slot].data;
}

std::vector<char> State::bytesOf(size_t i) const {
  const Block& b = blocks_.at(i);
  if (!b.data) return b.saved;
  std::vector<char> out;
  StateWriter w(out);
  b.data->save(w);
  return out;
}

bool State::operator==(const State& o) const {
  // Bitwise on time, like the blocks: a restored state continues bit-identically.
  if (std::memcmp(&time, &o.time, sizeof time) != 0 || steps != o.steps || blocks_.size() != o.blocks_.size())
    return false;
  for (size_t i = 0; i < blocks_.size(); ++i)
    if (blocks_[i].component != o.blocks_[i].component || bytesOf(i) != o.bytesOf(i)) return false;
  return true;
}

size_t State::bytes() const {
  size_t n = 0;
  for (size_t i = 0; i < blocks_.size(); ++i) n += bytesOf(i).size();
  return n;
}

void State::save(const std::string& file) const {
  std::vector<char> out(std::begin(kMagic), std::end(kMagic));
  StateWriter w(out);
  w.put(kVersion);
  w.put(time);
  w.put(steps);
  w.count(static_cast<std::int64_t>(blocks_.size()));
  for (size_t i = 0; i < blocks_.size(); ++i) {
    const std::string& name = blocks_[i].component;
    w.count(static_cast<std::int64_t>(name.size()));
    w.raw(name.data(), name.size());
    w.put(bytesOf(i));
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
    if (version != kVersion) throw Error("state file version " + std::to_string(version) + " (this build reads " + std::to_string(kVersion) + ")");
    r.get(s.time);
    r.get(s.steps);
    const std::int64_t n = r.count();
    if (static_cast<size_t>(n) > body.size()) r.mismatch("a bad block count");
    s.blocks_.resize(n);
    for (auto& b : s.blocks_) {
      const std::int64_t len = r.count();
      if (static_cast<size_t>(len) > body.size()) r.mismatch("a bad name length");
      b.component.resize(len);
      r.raw(b.component.data(), len);
      r.get(b.saved);
    }
    r.finish();
  } catch (const Error& e) {
    throw Error(SourceLoc{file}, std::string("corrupt state file: ") + e.what());
  }
  return s;
}

}  // namespace viscera
