// The FPGA queue (robot/encoder/EncoderFpga) and the Rev 6 / Rev 7 register formats
// (robot/encoder/Registers): quadlets checked bit by bit against values worked out by hand, the
// host's Rev 6 decode formula, round trips, 26-bit saturation and the running-counter rule.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "robot/encoder/EncoderFpga.h"
#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityEstimators.h"

using namespace viscera::robot::encoder;

namespace {

// Channel levels after each forward edge from (A, B) = (0, 0): A rise, B rise, A fall, B fall.
constexpr ChannelLevels kForwardLevels[4] = {{true, false}, {true, true}, {false, true}, {false, false}};

// Edges moving forward at the given ticks, starting from both channels low.
EncoderFpga forwardEdges(const std::vector<int64_t>& ticks) {
  EncoderFpga fpga;
  for (size_t i = 0; i < ticks.size(); ++i) fpga.sample(ticks[i], kForwardLevels[i % 4]);
  return fpga;
}

// Ticks of edges separated by the given quarter times, the first edge at tick 100.
std::vector<int64_t> edgeTicks(const std::vector<int64_t>& quarters) {
  std::vector<int64_t> ticks{100};
  for (int64_t q : quarters) ticks.push_back(ticks.back() + q);
  return ticks;
}

}  // namespace

TEST(EncoderFpga, QueueHoldsTheLastFiveQuartersAndTheRunningCounter) {
  // Six forward edges 1000, 1200, 1300, 1400, 1500 ticks apart; read 500 ticks after the last.
  const EncoderFpga fpga = forwardEdges(edgeTicks({1000, 1200, 1300, 1400, 1500}));
  const FpgaReadout r = fpga.read(100 + 6400 + 500);
  const uint32_t expected[5] = {1500, 1400, 1300, 1200, 1000};  // T_i ... T_{i-4}
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(r.quarter[k].ticks, expected[k]) << k;
    EXPECT_FALSE(r.quarter[k].overflow) << k;
    EXPECT_TRUE(r.quarter[k].forward) << k;
    EXPECT_FALSE(r.quarter[k].error) << k;
  }
  EXPECT_EQ(r.running, 500u);
  EXPECT_FALSE(r.runningOverflow);
  EXPECT_EQ(r.position, 6);
  EXPECT_TRUE(r.forward);
  EXPECT_EQ(r.cycleSum(), 1500u + 1400 + 1300 + 1200);
  EXPECT_FALSE(r.cycleOverflow());
  EXPECT_FALSE(r.directionChanged());
  EXPECT_FALSE(r.partialCycle());
  // The sixth edge is a B rise (A rise, B rise, A fall, B fall, A rise, B rise), as is the second,
  // which ended T_{i-4}.
  EXPECT_EQ(r.quarter[0].edges, static_cast<uint8_t>(Edge::BRise));
  EXPECT_EQ(r.quarter[4].edges, static_cast<uint8_t>(Edge::BRise));
  EXPECT_EQ(r.quarter[1].edges, static_cast<uint8_t>(Edge::ARise));
}

TEST(EncoderFpga, EverythingIsOverflowedUntilEdgesArrive) {
  EncoderFpga fpga;
  FpgaReadout r = fpga.read(12345);
  EXPECT_TRUE(r.runningOverflow);
  EXPECT_TRUE(r.cycleOverflow());
  EXPECT_TRUE(r.partialCycle());
  // The first edge ends a quarter of unknown length: overflowed; three edges later the cycle still
  // holds it.
  fpga = forwardEdges({1000, 2000, 3000, 4000});
  r = fpga.read(4000);
  EXPECT_TRUE(r.quarter[3].overflow);
  EXPECT_TRUE(r.cycleOverflow());
  EXPECT_FALSE(r.partialCycle());
  EXPECT_EQ(quarterCycleVelocity(measure(r, RegisterFormat::Rev7)), 1 / (1000 * kRev7ClockPeriod));
  EXPECT_EQ(fullCycleVelocity(measure(r, RegisterFormat::Rev7)), 0);
  EXPECT_EQ(fullCycleVelocity(measure(r, RegisterFormat::Rev6)), 0);
}

TEST(Registers, Rev7QuadletsBitByBit) {
  const EncoderFpga fpga = forwardEdges(edgeTicks({1000, 1200, 1300, 1400, 1500}));
  const Rev7Registers q = encodeRev7(fpga.read(100 + 6400 + 500));
  // period: direction (bit 30) | S = 5400 = 0x1518.
  EXPECT_EQ(q.period, 0x40001518u);
  // quarters: direction | edge mask B rise 0100 in bits 29:26 (0x10000000) | 1500 = 0x5DC, 1000 = 0x3E8.
  EXPECT_EQ(q.quarter, 0x500005DCu);
  EXPECT_EQ(q.quarterPrev, 0x500003E8u);
  // running: direction | 500 = 0x1F4.
  EXPECT_EQ(q.running, 0x400001F4u);

  const Measurement m = decodeRev7(q.period, q.quarter, q.quarterPrev, q.running);
  EXPECT_EQ(m.period, 5400u);
  EXPECT_EQ(m.quarter, 1500u);
  EXPECT_EQ(m.quarterPrev, 1000u);
  EXPECT_EQ(m.running, 500u);
  EXPECT_EQ(m.quarterEdges, 0x4);
  EXPECT_EQ(m.quarterPrevEdges, 0x4);
  EXPECT_TRUE(m.forward && m.quarterForward && m.quarterPrevForward);
  EXPECT_FALSE(m.overflow || m.quarterOverflow || m.quarterPrevOverflow || m.runningOverflow);
  EXPECT_FALSE(m.directionChanged || m.encoderError || m.partialCycle);
  EXPECT_TRUE(m.hasRunning && m.hasEdgeMasks);
  EXPECT_EQ(m.clockPeriod, 1 / 49.152e6);
}

TEST(Registers, Rev6QuadletsBitByBitAndTheHostDecodeFormula) {
  // Quarters T_{i-4} .. T_i = 0x0ABCDE, 0x100000, 0x100000, 0x100000, 0x123456 ticks, read at the
  // last edge: S = 0x423456.
  const std::vector<int64_t> ticks = edgeTicks({0x0ABCDE, 0x100000, 0x100000, 0x100000, 0x123456});
  const FpgaReadout r = forwardEdges(ticks).read(ticks.back());
  ASSERT_EQ(r.running, 0u);
  const Rev6Registers q = encodeRev6(r);
  // period = direction 0x40000000 | T_i bits 11:4 (0x45) << 22 = 0x11400000 | S >> 4 = 0x42345.
  EXPECT_EQ(q.period, 0x51442345u);
  // acceleration = T_i bits 23:12 (0x123) << 20 | T_{i-4} bits 23:4 (0xABCD).
  EXPECT_EQ(q.acceleration, 0x1230ABCDu);
  // The host's formula.
  const uint32_t per = q.period, acc = q.acceleration;
  const uint32_t q1 = ((acc & 0xFFF00000) >> 12) | ((per & 0x3FC00000) >> 22);
  const uint32_t q5 = acc & 0xFFFFF;
  EXPECT_EQ(q1, 0x123456u >> 4);
  EXPECT_EQ(q5, 0x0ABCDEu >> 4);
  const Measurement m = decodeRev6(per, acc);
  EXPECT_EQ(m.quarter, q1);
  EXPECT_EQ(m.quarterPrev, q5);
  EXPECT_EQ(m.period, 0x42345u);
  EXPECT_TRUE(m.forward);
  EXPECT_FALSE(m.overflow || m.quarterOverflow || m.quarterPrevOverflow);
  EXPECT_FALSE(m.hasRunning || m.hasEdgeMasks);
  EXPECT_EQ(m.clockPeriod, 16 / 49.152e6);
}

TEST(Registers, RoundTripsRev7ExactlyAndRev6ToSixteenTicks) {
  std::mt19937 rng(20180101);
  std::uniform_int_distribution<int64_t> quarter(1, 2000000);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<int64_t> quarters(7);
    for (auto& q : quarters) q = quarter(rng);
    const std::vector<int64_t> ticks = edgeTicks(quarters);
    const EncoderFpga fpga = forwardEdges(ticks);
    const int64_t lastEdge = ticks.back();
    // Read before the running counter passes the oldest quarter of S, so no substitution applies.
    const FpgaReadout r = fpga.read(lastEdge + quarters[3] / 2);
    ASSERT_FALSE(r.runningExceedsOldest());

    const Rev7Registers q7 = encodeRev7(r);
    const Measurement m7 = decodeRev7(q7.period, q7.quarter, q7.quarterPrev, q7.running);
    EXPECT_EQ(m7.period, r.cycleSum());
    EXPECT_EQ(m7.quarter, r.quarter[0].ticks);
    EXPECT_EQ(m7.quarterPrev, r.quarter[4].ticks);
    EXPECT_EQ(m7.running, r.running);

    // Rev 6 drops the low 4 bits: decoded x 16 <= value < decoded x 16 + 16.
    const Rev6Registers q6 = encodeRev6(r);
    const Measurement m6 = decodeRev6(q6.period, q6.acceleration);
    EXPECT_LE(m6.period * 16u, r.cycleSum());
    EXPECT_LT(r.cycleSum(), m6.period * 16u + 16);
    EXPECT_EQ(m6.quarter, r.quarter[0].ticks >> 4);
    EXPECT_EQ(m6.quarterPrev, r.quarter[4].ticks >> 4);
  }
}

TEST(Registers, CountersSaturateAt26BitsWithOverflowFlags) {
  // Two edges 2^26 + 5 ticks apart: the quarter saturates at 0x3FFFFFF and overflows.
  EncoderFpga fpga;
  fpga.sample(1000, kForwardLevels[0]);
  fpga.sample(1000 + (int64_t{1} << 26) + 5, kForwardLevels[1]);
  FpgaReadout r = fpga.read(1000 + (int64_t{1} << 26) + 5);
  EXPECT_EQ(r.quarter[0].ticks, kCounterMax);
  EXPECT_TRUE(r.quarter[0].overflow);
  Rev7Registers q = encodeRev7(r);
  EXPECT_EQ(q.quarter & 0x83FFFFFFu, 0x83FFFFFFu);  // overflow bit and a full count
  EXPECT_NE(q.period & 0x80000000u, 0u);
  EXPECT_EQ(q.period & kCounterMax, kCounterMax);
  // Rev 6 quarters saturate at 24 bits, so the 20-bit field is all ones: overflow for the host.
  const Rev6Registers q6 = encodeRev6(r);
  EXPECT_TRUE(decodeRev6(q6.period, q6.acceleration).quarterOverflow);

  // The running counter: 2^26 - 2 ticks after an edge still counting, 2^26 - 1 saturated.
  r = fpga.read(1000 + (int64_t{1} << 26) + 5 + kCounterMax - 1);
  EXPECT_EQ(r.running, kCounterMax - 1);
  EXPECT_FALSE(r.runningOverflow);
  r = fpga.read(1000 + (int64_t{1} << 26) + 5 + 3 * int64_t{kCounterMax});
  EXPECT_EQ(r.running, kCounterMax);
  EXPECT_TRUE(r.runningOverflow);
  EXPECT_EQ(encodeRev7(r).running & 0x83FFFFFFu, 0x83FFFFFFu);

  // A sum of four unsaturated quarters past 26 bits: the period overflows, the quarters do not.
  const FpgaReadout s = forwardEdges(edgeTicks({1 << 24, 1 << 24, 1 << 24, 1 << 24, 1 << 24})).read(100 + 5 * (1 << 24));
  EXPECT_FALSE(s.quarter[0].overflow || s.quarter[3].overflow);
  EXPECT_TRUE(s.cycleOverflow());
  q = encodeRev7(s);
  EXPECT_EQ(q.period, 0x80000000u | 0x40000000u | kCounterMax);
  EXPECT_EQ(fullCycleVelocity(decodeRev7(q.period, q.quarter, q.quarterPrev, q.running)), 0);
}

TEST(Registers, RunningCounterReplacesTheQuarterOfItsTypeOnceLonger) {
  // Quarters 1000, 1200, 1300, 1400, 1500: S_i = 5400, its oldest quarter T_{i-3} = 1200 is of the
  // edge type the quarter in progress will end with ("T_{i-4}" counted from the coming edge).
  const EncoderFpga fpga = forwardEdges(edgeTicks({1000, 1200, 1300, 1400, 1500}));
  const int64_t lastEdge = 100 + 6400;
  // Not longer yet (equal): S_i as it is.
  FpgaReadout r = fpga.read(lastEdge + 1200);
  EXPECT_FALSE(r.runningExceedsOldest());
  EXPECT_EQ(r.cycleSumWithRunning(), 5400u);
  EXPECT_EQ(decodeRev6(encodeRev6(r).period, 0).period, 5400u >> 4);
  // 1700 ticks without an edge: the sum is T_r + T_i + T_{i-1} + T_{i-2} = 1700 + 1500 + 1400 + 1300.
  r = fpga.read(lastEdge + 1700);
  EXPECT_TRUE(r.runningExceedsOldest());
  EXPECT_EQ(r.cycleSumWithRunning(), 5900u);
  EXPECT_EQ(decodeRev6(encodeRev6(r).period, 0).period, 5900u >> 4);
  // Rev 7 reports S_i and the running counter separately.
  const Rev7Registers q = encodeRev7(r);
  EXPECT_EQ(q.period & kCounterMax, 5400u);
  EXPECT_EQ(q.running & kCounterMax, 1700u);
  // Once the running counter overflows, Rev 6 flags the period: the encoder has stopped.
  r = fpga.read(lastEdge + kCounterMax + 10);
  const Rev6Registers q6 = encodeRev6(r);
  EXPECT_NE(q6.period & 0x80000000u, 0u);
  EXPECT_EQ(fullCycleVelocity(decodeRev6(q6.period, q6.acceleration)), 0);
  EXPECT_EQ(quarterCycleVelocity(decodeRev6(q6.period, q6.acceleration)), 0);
}

TEST(Registers, DirectionChangeAndDoubleEdgesAreFlagged) {
  // Six forward edges, then back across the last one (B rise undone: B fall, backward).
  EncoderFpga fpga = forwardEdges(edgeTicks({1000, 1000, 1000, 1000, 1000}));
  int64_t tick = 100 + 5000;
  fpga.sample(tick += 3000, {true, false});
  FpgaReadout r = fpga.read(tick);
  EXPECT_FALSE(r.forward);
  EXPECT_EQ(r.position, 5);
  EXPECT_EQ(r.quarter[0].edges, static_cast<uint8_t>(Edge::BFall));
  EXPECT_FALSE(r.quarter[0].error);  // undoing the previous edge is legal
  EXPECT_TRUE(r.directionChanged());
  Measurement m = measure(r, RegisterFormat::Rev7);
  EXPECT_TRUE(m.directionChanged);
  EXPECT_FALSE(m.forward);
  EXPECT_EQ(cycleAcceleration(m), 0);
  // Three more backward edges (from (A, B) = (1, 0): A fall, B rise, A rise): after four backward
  // quarters the cycle is in one direction again.
  const ChannelLevels back[3] = {{false, false}, {false, true}, {true, true}};
  for (const auto& l : back) fpga.sample(tick += 1000, l);
  r = fpga.read(tick);
  EXPECT_FALSE(r.directionChanged());
  EXPECT_EQ(r.position, 2);
  EXPECT_FALSE(encodeRev7(r).period & 0x20000000u);

  // Both channels at once: a quarter flagged as an error with both bits, not counted.
  fpga.sample(tick += 1000, {false, false});
  r = fpga.read(tick);
  EXPECT_TRUE(r.quarter[0].error);
  EXPECT_EQ(r.quarter[0].edges, static_cast<uint8_t>(Edge::AFall) | static_cast<uint8_t>(Edge::BFall));
  EXPECT_EQ(r.position, 2);
  EXPECT_NE(encodeRev7(r).period & 0x10000000u, 0u);
}

TEST(Registers, AccelerationNeedsMatchingEdgeMasks) {
  // Rev 7 quarters 1000 and 1100 ticks, S = 4200: acceleration with equal masks, none otherwise.
  const uint32_t period = 0x40000000u | 4200;
  const uint32_t q1 = 0x40000000u | (0x4u << 26) | 1000, running = 0x40000000u | 10;
  const Measurement same = decodeRev7(period, q1, 0x40000000u | (0x4u << 26) | 1100, running);
  const Measurement other = decodeRev7(period, q1, 0x40000000u | (0x8u << 26) | 1100, running);
  // II.6: a = 8 (1100 - 1000) / (4200 x 4300 x T^2 x 2100) counts/s^2.
  const double T = 1 / 49.152e6;
  EXPECT_NEAR(cycleAcceleration(same, {0}), 8.0 * 100 / (4200.0 * 4300 * T * T * 2100), 1e-9 * 8.0 * 100 / (4200.0 * 4300 * T * T * 2100));
  EXPECT_EQ(cycleAcceleration(other, {0}), 0);
  // Below the threshold (T_i shorter than 2000 ticks by default) acceleration is off.
  EXPECT_EQ(cycleAcceleration(same), 0);
}
