// The velocity registers of one encoder as the dVRK FPGA reports them, and their decoding into a
// Measurement for the velocity estimators. Two layouts (public dVRK firmware and host library):
//
// Rev 6: times in counts of the 49.152 MHz clock divided by 16 (3.072 MHz), two quadlets (also
// the first and second velocity quadlets of the ESPM packet):
//   period        bit 31 overflow, bit 30 direction, bits 29:22 T_i bits 11:4,
//                 bits 21:0 the cycle sum bits 25:4 (with the running-counter substitution, see
//                 FpgaReadout::cycleSumWithRunning)
//   acceleration  bits 31:20 T_i bits 23:12, bits 19:0 T_{i-4} bits 23:4
//   Quarter times saturate at 24 bits before the low 4 bits are dropped, so a quarter field of
//   0xFFFFF means overflow. The host decodes T_i = ((acc & 0xFFF00000) >> 12) | ((per & 0x3FC00000)
//   >> 22) and T_{i-4} = acc & 0xFFFFF.
// Rev 7: times in counts of the full 49.152 MHz clock, four quadlets:
//   period        bit 31 overflow, 30 direction (of T_i), 29 direction changed (within the cycle),
//                 28 encoder error, 27 partial cycle (fewer than 4 edges), 26 zero, 25:0 S_i
//   quarter       bit 31 overflow, 30 direction, 29:26 edge mask (A rise, B rise, A fall, B fall),
//                 25:0 T_i ticks
//   quarter prev  the same for T_{i-4}
//   running       bit 31 overflow, 30 direction (decoder), 29:26 zero, 25:0 T_r ticks
#pragma once

#include <cstdint>

#include "robot/encoder/EncoderFpga.h"

namespace viscera::robot::encoder {

// Clock period of the Rev 6 time fields: 16 ticks of the FPGA clock.
inline constexpr double kRev6ClockPeriod = 16 / kFpgaClockHz;
inline constexpr double kRev7ClockPeriod = 1 / kFpgaClockHz;

enum class RegisterFormat { Rev6, Rev7 };

struct Rev6Registers {
  uint32_t period = 0;
  uint32_t acceleration = 0;
};

struct Rev7Registers {
  uint32_t period = 0;
  uint32_t quarter = 0;
  uint32_t quarterPrev = 0;
  uint32_t running = 0;
};

// What the host knows about one encoder's timing after decoding its registers. Times are counts of
// a clock with period `clockPeriod` (s). Fields a format does not carry are false/zero, with
// hasRunning / hasEdgeMasks saying which.
struct Measurement {
  double clockPeriod = kRev7ClockPeriod;
  uint32_t period = 0;          // S: the last full cycle (four quarters)
  uint32_t quarter = 0;         // T_i: the last quarter cycle
  uint32_t quarterPrev = 0;     // T_{i-4}: the quarter of the same edge type one cycle earlier
  uint32_t running = 0;         // T_r: time since the last edge
  bool overflow = true;         // S unusable (too slow, stopped, or not measured yet)
  bool quarterOverflow = true;
  bool quarterPrevOverflow = true;
  bool runningOverflow = false;
  bool forward = false;         // direction bit of the period
  bool quarterForward = false;  // direction of T_i (Rev 6: the period's)
  bool quarterPrevForward = false;
  bool directionChanged = false;  // the cycle spans a reversal (Rev 7)
  bool encoderError = false;      // an illegal edge within the cycle (Rev 7)
  bool partialCycle = false;      // fewer than four edges seen (Rev 7)
  uint8_t quarterEdges = 0;       // edge masks (Rev 7)
  uint8_t quarterPrevEdges = 0;
  bool hasRunning = false;
  bool hasEdgeMasks = false;
};

// Registers of a readout. Rev 6 reports the cycle sum with the running-counter substitution and
// sets the overflow bit also when the running counter has overflowed (the encoder stopped).
Rev6Registers encodeRev6(const FpgaReadout& readout);
Measurement decodeRev6(uint32_t period, uint32_t acceleration);
Rev7Registers encodeRev7(const FpgaReadout& readout);
Measurement decodeRev7(uint32_t period, uint32_t quarter, uint32_t quarterPrev, uint32_t running);

// Encodes in `format` and decodes again: what a host reading that format would know.
Measurement measure(const FpgaReadout& readout, RegisterFormat format);

}  // namespace viscera::robot::encoder
