// The FPGA side of velocity measurement (dissertation Appendix II, Fig. II-5; the public dVRK
// firmware): a quadrature decoder (position count and direction) and a queue of six 26-bit
// registers, a running counter T_r that counts clock ticks since the last edge and the
// quarter-cycle times T_i ... T_{i-4} of the last five edges. Every edge pushes the running counter
// into the queue (with its flags) and clears it. Registers saturate at 2^26 - 1 and then carry an
// overflow flag; after power-up every register is overflowed.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "robot/encoder/Quadrature.h"

namespace viscera::robot::encoder {

// Largest value of a 26-bit counter register (1.37 s at 49.152 MHz).
inline constexpr uint32_t kCounterMax = (1u << 26) - 1;

// One quarter-cycle register and its flags.
struct QuarterCount {
  uint32_t ticks = kCounterMax;  // clock ticks between the edge before and the edge that ended it
  bool overflow = true;          // the counter saturated (or nothing was measured yet)
  bool forward = false;          // decoder direction at the edge that ended it
  bool error = false;            // that edge cannot follow the one before (both channels changed at once)
  uint8_t edges = 0;             // Edge mask of the edge(s) that ended it; 0 before any edge
};

// The registers as the host reads them at one tick.
struct FpgaReadout {
  int64_t tick = 0;                      // when it was read
  std::array<QuarterCount, 5> quarter;   // [0] = T_i (most recent) ... [4] = T_{i-4}
  uint32_t running = kCounterMax;        // T_r, ticks since the last edge (saturated)
  bool runningOverflow = true;
  bool forward = false;                  // decoder direction (of the last counted edge)
  int64_t position = 0;                  // quadrature count

  // S_i = T_i + T_{i-1} + T_{i-2} + T_{i-3}, the full cycle (Eq. II.2); 28 bits, not saturated.
  uint32_t cycleSum() const { return quarter[0].ticks + quarter[1].ticks + quarter[2].ticks + quarter[3].ticks; }
  // Whether the cycle is unusable: one of its quarters overflowed or the sum does not fit 26 bits.
  bool cycleOverflow() const;
  // The cycle sum the dissertation's FPGA reports: S_i, but once the running counter exceeds the
  // quarter it will replace in the next sum (the oldest of S_i, T_{i-3}; of the same edge type as
  // the quarter in progress and so "T_{i-4}" counted from the edge still to come), T_r takes its
  // place, so a decelerating or stopping encoder shows a growing period at once.
  uint32_t cycleSumWithRunning() const;
  // Whether the running counter's substitution applies (it is also an overflow when T_r is).
  bool runningExceedsOldest() const { return running > quarter[3].ticks; }
  // Whether the four quarters of S_i were not all measured in the same direction.
  bool directionChanged() const;
  // Whether an edge error is among the four quarters of S_i.
  bool encoderError() const;
  // Whether fewer than four edges have been seen (the oldest quarter of S_i has no edge yet).
  bool partialCycle() const { return quarter[3].edges == 0; }
};

class EncoderFpga {
 public:
  // The decoder starts with the channels at `initial`, the position count at `position`; all
  // timing registers overflowed.
  explicit EncoderFpga(ChannelLevels initial = {}, int64_t position = 0);

  // The channels as sampled at `tick` (ticks must not decrease). Nothing happens unless a level
  // changed. One channel changing is an edge: counted up or down by the decoder's direction
  // (A xor the previous B: forward when A leads B). Both changing at once is not counted; it
  // still ends a quarter, flagged as an error with both channels' bits in its edge mask.
  void sample(int64_t tick, ChannelLevels levels);

  // The registers as latched by a host read at `tick` (not before the last sample).
  FpgaReadout read(int64_t tick) const;

  ChannelLevels levels() const { return levels_; }
  int64_t position() const { return position_; }

 private:
  ChannelLevels levels_;
  int64_t position_ = 0;
  bool forward_ = false;
  bool anyEdge_ = false;       // whether the running counter has been cleared by an edge yet
  int64_t lastEdgeTick_ = 0;
  std::array<QuarterCount, 5> quarter_{};
};

// Reads an encoder at the given host ticks (increasing) while its edge events (in time order)
// are fed to the FPGA: element k is the readout at ticks[k], with every event at or before that
// tick applied. Events that share a tick are sampled together (each toggles its channel).
std::vector<FpgaReadout> readAt(std::span<const EdgeEvent> events, ChannelLevels initial, int64_t position,
                                std::span<const int64_t> ticks);

}  // namespace viscera::robot::encoder
