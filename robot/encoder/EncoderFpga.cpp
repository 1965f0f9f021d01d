#include "robot/encoder/EncoderFpga.h"

#include <stdexcept>

namespace viscera::robot::encoder {
namespace {

constexpr uint8_t kARise = static_cast<uint8_t>(Edge::ARise), kBRise = static_cast<uint8_t>(Edge::BRise),
                  kAFall = static_cast<uint8_t>(Edge::AFall), kBFall = static_cast<uint8_t>(Edge::BFall);

// The edge that comes before `edge` when moving forward (A rise, B rise, A fall, B fall) and when
// moving backward (B rise, A rise, B fall, A fall); and the edge it undoes on a reversal (the same
// channel's other transition).
uint8_t forwardPredecessor(uint8_t edge) {
  switch (edge) {
    case kARise: return kBFall;
    case kBRise: return kARise;
    case kAFall: return kBRise;
    default: return kAFall;
  }
}
uint8_t backwardPredecessor(uint8_t edge) {
  switch (edge) {
    case kARise: return kBRise;
    case kBRise: return kAFall;
    case kAFall: return kBFall;
    default: return kARise;
  }
}
uint8_t reversed(uint8_t edge) {
  switch (edge) {
    case kARise: return kAFall;
    case kAFall: return kARise;
    case kBRise: return kBFall;
    default: return kBRise;
  }
}

uint32_t saturated(int64_t ticks) { return ticks >= kCounterMax ? kCounterMax : static_cast<uint32_t>(ticks); }

}  // namespace

bool FpgaReadout::cycleOverflow() const {
  for (int k = 0; k < 4; ++k)
    if (quarter[k].overflow) return true;
  return cycleSum() > kCounterMax;
}

uint32_t FpgaReadout::cycleSumWithRunning() const {
  return runningExceedsOldest() ? cycleSum() - quarter[3].ticks + running : cycleSum();
}

bool FpgaReadout::directionChanged() const {
  for (int k = 1; k < 4; ++k)
    if (quarter[k].forward != quarter[0].forward) return true;
  return false;
}

bool FpgaReadout::encoderError() const {
  for (int k = 0; k < 4; ++k)
    if (quarter[k].error) return true;
  return false;
}

EncoderFpga::EncoderFpga(ChannelLevels initial, int64_t position) : levels_(initial), position_(position) {}

void EncoderFpga::sample(int64_t tick, ChannelLevels now) {
  const bool aChanged = now.a != levels_.a, bChanged = now.b != levels_.b;
  if (!aChanged && !bChanged) return;
  if (anyEdge_ && tick < lastEdgeTick_) throw std::invalid_argument("EncoderFpga: samples must come in tick order");

  // Direction as the decoder sees it at this edge: A now xor B before (1 when A leads B).
  const bool forwardNow = now.a != levels_.b;
  uint8_t edges = 0;
  if (aChanged) edges |= now.a ? kARise : kAFall;
  if (bChanged) edges |= now.b ? kBRise : kBFall;

  // A single edge must continue the sequence of the previous one, or undo it on a reversal.
  bool error = aChanged && bChanged;
  const uint8_t previous = quarter_[0].edges;
  if (!error && previous != 0) {
    if (quarter_[0].forward == forwardNow)
      error = previous != (forwardNow ? forwardPredecessor(edges) : backwardPredecessor(edges));
    else
      error = previous != reversed(edges);
  }

  // Shift the queue: the running counter becomes T_i, T_{i-4} drops out.
  for (int k = 4; k > 0; --k) quarter_[k] = quarter_[k - 1];
  QuarterCount& q = quarter_[0];
  const int64_t elapsed = anyEdge_ ? tick - lastEdgeTick_ : kCounterMax;
  q.ticks = saturated(elapsed);
  q.overflow = elapsed >= kCounterMax;
  q.forward = forwardNow;
  q.error = error;
  q.edges = edges;

  // The decoder counts single edges only; a double change leaves count and direction alone.
  if (aChanged != bChanged) {
    forward_ = forwardNow;
    position_ += forwardNow ? 1 : -1;
  }
  levels_ = now;
  anyEdge_ = true;
  lastEdgeTick_ = tick;
}

FpgaReadout EncoderFpga::read(int64_t tick) const {
  FpgaReadout r;
  r.tick = tick;
  r.quarter = quarter_;
  const int64_t elapsed = anyEdge_ ? tick - lastEdgeTick_ : kCounterMax;
  r.running = saturated(elapsed);
  r.runningOverflow = elapsed >= kCounterMax;
  r.forward = forward_;
  r.position = position_;
  return r;
}

std::vector<FpgaReadout> readAt(std::span<const EdgeEvent> events, ChannelLevels initial, int64_t position,
                                std::span<const int64_t> ticks) {
  EncoderFpga fpga(initial, position);
  std::vector<FpgaReadout> out;
  out.reserve(ticks.size());
  size_t next = 0;
  for (int64_t tick : ticks) {
    // Events of one tick reach the FPGA together: it samples the levels after all of them.
    while (next < events.size() && events[next].tick <= tick) {
      const int64_t edgeTick = events[next].tick;
      ChannelLevels levels = fpga.levels();
      for (; next < events.size() && events[next].tick == edgeTick; ++next) {
        if (static_cast<uint8_t>(events[next].type) & (kARise | kAFall)) levels.a = !levels.a;
        else levels.b = !levels.b;
      }
      fpga.sample(edgeTick, levels);
    }
    out.push_back(fpga.read(tick));
  }
  return out;
}

}  // namespace viscera::robot::encoder
