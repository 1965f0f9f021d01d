#include "robot/encoder/Registers.h"

#include <algorithm>

namespace viscera::robot::encoder {
namespace {

constexpr uint32_t kBit31 = 0x80000000u, kBit30 = 0x40000000u, kBit29 = 0x20000000u, kBit28 = 0x10000000u,
                   kBit27 = 0x08000000u;
// Rev 6 quarter times keep 24 bits (saturating) and send bits 23:4.
constexpr uint32_t kRev6QuarterMax = 0xFFFFFF;
constexpr uint32_t kRev6QuarterField = 0xFFFFF;
constexpr uint32_t kRev6PeriodField = 0x3FFFFF;

uint32_t rev6Quarter(const QuarterCount& q) { return q.overflow ? kRev6QuarterMax : std::min(q.ticks, kRev6QuarterMax); }

uint32_t rev7Quarter(const QuarterCount& q) {
  return (q.overflow ? kBit31 : 0u) | (q.forward ? kBit30 : 0u) | (static_cast<uint32_t>(q.edges & 0xF) << 26) |
         (q.ticks & kCounterMax);
}

}  // namespace

Rev6Registers encodeRev6(const FpgaReadout& r) {
  const uint32_t sum = r.cycleSumWithRunning();
  const bool overflow = r.cycleOverflow() || r.runningOverflow || sum > kCounterMax;
  const uint32_t q1 = rev6Quarter(r.quarter[0]);
  const uint32_t q5 = rev6Quarter(r.quarter[4]);
  Rev6Registers out;
  out.period = (overflow ? kBit31 : 0u) | (r.forward ? kBit30 : 0u) | (((q1 >> 4) & 0xFF) << 22) |
               (overflow ? kRev6PeriodField : (sum >> 4));
  out.acceleration = (((q1 >> 12) & 0xFFF) << 20) | (q5 >> 4);
  return out;
}

Measurement decodeRev6(uint32_t period, uint32_t acceleration) {
  Measurement m;
  m.clockPeriod = kRev6ClockPeriod;
  m.period = period & kRev6PeriodField;
  m.quarter = ((acceleration & 0xFFF00000u) >> 12) | ((period & 0x3FC00000u) >> 22);
  m.quarterPrev = acceleration & kRev6QuarterField;
  m.overflow = (period & kBit31) != 0;
  m.quarterOverflow = m.quarter == kRev6QuarterField;
  m.quarterPrevOverflow = m.quarterPrev == kRev6QuarterField;
  m.forward = (period & kBit30) != 0;
  // Rev 6 keeps no direction per quarter: both are taken to be the period's.
  m.quarterForward = m.forward;
  m.quarterPrevForward = m.forward;
  return m;
}

Rev7Registers encodeRev7(const FpgaReadout& r) {
  const bool overflow = r.cycleOverflow();
  Rev7Registers out;
  out.period = (overflow ? kBit31 : 0u) | (r.quarter[0].forward ? kBit30 : 0u) | (r.directionChanged() ? kBit29 : 0u) |
               (r.encoderError() ? kBit28 : 0u) | (r.partialCycle() ? kBit27 : 0u) |
               (overflow ? kCounterMax : r.cycleSum());
  out.quarter = rev7Quarter(r.quarter[0]);
  out.quarterPrev = rev7Quarter(r.quarter[4]);
  out.running = (r.runningOverflow ? kBit31 : 0u) | (r.forward ? kBit30 : 0u) | (r.running & kCounterMax);
  return out;
}

Measurement decodeRev7(uint32_t period, uint32_t quarter, uint32_t quarterPrev, uint32_t running) {
  Measurement m;
  m.clockPeriod = kRev7ClockPeriod;
  m.period = period & kCounterMax;
  m.overflow = (period & kBit31) != 0;
  m.forward = (period & kBit30) != 0;
  m.directionChanged = (period & kBit29) != 0;
  m.encoderError = (period & kBit28) != 0;
  m.partialCycle = (period & kBit27) != 0;
  m.quarter = quarter & kCounterMax;
  m.quarterOverflow = (quarter & kBit31) != 0;
  m.quarterForward = (quarter & kBit30) != 0;
  m.quarterEdges = static_cast<uint8_t>((quarter >> 26) & 0xF);
  m.quarterPrev = quarterPrev & kCounterMax;
  m.quarterPrevOverflow = (quarterPrev & kBit31) != 0;
  m.quarterPrevForward = (quarterPrev & kBit30) != 0;
  m.quarterPrevEdges = static_cast<uint8_t>((quarterPrev >> 26) & 0xF);
  m.running = running & kCounterMax;
  m.runningOverflow = (running & kBit31) != 0;
  m.hasRunning = true;
  m.hasEdgeMasks = true;
  return m;
}

Measurement measure(const FpgaReadout& readout, RegisterFormat format) {
  if (format == RegisterFormat::Rev6) {
    const Rev6Registers r = encodeRev6(readout);
    return decodeRev6(r.period, r.acceleration);
  }
  const Rev7Registers r = encodeRev7(readout);
  return decodeRev7(r.period, r.quarter, r.quarterPrev, r.running);
}

}  // namespace viscera::robot::encoder
