// ESPM captures: the raw bytes of the arm's link as recorded. The ESPM streams packets at
// 20 Mbit/s; a capture is the line itself, idle time being zero bytes, so a packet's time is its
// byte offset: t = offset * 8 / lineRate (s). Also the conversion between encoder counts and the
// PSM's joint values, and the synthesis of a capture from a joint trajectory.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "robot/espm/Framing.h"
#include "robot/espm/Packet.h"
#include "robot/espm/StreamDecoder.h"
#include "robot/kinematics/JointTrajectory.h"

namespace viscera::robot::espm {

inline constexpr double kLineRate = 20e6;  // bit/s of the ESPM link

struct CaptureOptions {
  Framing framing = Framing::Auto;
  double lineRate = kLineRate;  // bit/s
};

struct CaptureSample {
  double time = 0;      // s: offset * 8 / lineRate
  uint64_t offset = 0;  // byte offset of the packet's magic in the capture
  Packet packet;
};

struct Capture {
  std::string source;  // the file, for messages
  Framing framing = Framing::Auto;  // the framing decoded (decided, for Auto)
  double lineRate = kLineRate;
  std::vector<CaptureSample> samples;  // the information packets, in stream order
  DecoderStats stats;
  // Time from the first packet to the last (0 for a single packet).
  double duration() const { return samples.empty() ? 0.0 : samples.back().time - samples.front().time; }
};

// Decodes a whole capture held in memory; `source` names it in messages. Throws viscera::Error
// naming `source` when no information packet decodes (with the decoder's counters, and saying so
// when an Auto framing could not be decided) or when the line rate is not a positive number.
Capture decodeCapture(std::span<const uint8_t> bytes, const std::string& source, const CaptureOptions& options = {});
// Reads and decodes a capture file (in pieces, so it need not fit in memory twice). Errors as
// decodeCapture, and for a file that cannot be read.
Capture readCapture(const std::string& path, const CaptureOptions& options = {});

// The bytes of a capture: each packet's frame starts at byte round(time * lineRate / 8), zero
// bytes in between (CaptureSample::offset is not read). options.framing is Dissertation or
// Public. Throws viscera::Error for a negative or non-finite time, or a packet that would start
// before the previous one ends (the message gives its index and times).
std::vector<uint8_t> encodeCapture(std::span<const CaptureSample> samples, const CaptureOptions& options);
// The same, written to `path` atomically (a temporary file in the same folder, then a rename).
void writeCapture(const std::string& path, std::span<const CaptureSample> samples, const CaptureOptions& options);

// Encoder counts <-> joint values, per channel (encoders 1-6 are the PSM joints 1-6, encoder 7 the
// jaw): q = count / countsPerUnit + offset. Units: rad for revolute joints and the jaw, m for the
// insertion (joint 3). Defaults: 1e5 counts/rad, 1e6 counts/m, no offset.
struct JointScale {
  std::array<double, kJointChannels> countsPerUnit{1e5, 1e5, 1e6, 1e5, 1e5, 1e5, 1e5};
  std::array<double, kJointChannels> offset{};

  // Throws viscera::Error naming the entry when a count per unit is zero or not finite, or an
  // offset is not finite.
  void validate() const;
  double toJoint(int channel, int32_t count) const { return count / countsPerUnit[channel] + offset[channel]; }
  // Rounds to the nearest count. A count outside the 24-bit range [-8388608, 8388607] wraps
  // modulo 2^24, as the hardware counter does, and sets the overflow bit. Throws
  // std::invalid_argument for a non-finite value.
  EncoderPosition toEncoder(int channel, double value) const;
};

// The six PSM joints of every packet of `capture` (encoders 1-6; the jaw is not a PSM joint),
// timed by the packets (capture.samples[i].time). A packet whose encoder 1-6 has its overflow bit
// set gives no joint value: viscera::Error naming the capture, the packet's byte offset and time,
// and the encoder.
JointTrajectory jointsFromCapture(const Capture& capture, const JointScale& scale = {});

// The 12-bit reading of a potentiometer spanning [lower, upper] (0 at lower, 4095 at upper),
// rounded; values outside the span read 0 or 4095.
uint16_t potReading(double value, double lower, double upper);

// Velocity quadlets of an encoder without a measurement (Table I-4 / I-5 layout, Rev 6): the
// overflow bit set, no direction, every count saturated at its maximum, as the firmware reports
// a period counter that ran out.
inline constexpr uint32_t kVelocityFirstNoMeasurement = 0xBFFFFFFF;
inline constexpr uint32_t kVelocitySecondNoMeasurement = 0xFFFFFFFF;

// How a joint trajectory becomes a capture.
struct SynthesisOptions {
  double rate = 1000;  // packets per second
  double lineRate = kLineRate;
  Framing framing = Framing::Dissertation;
  JointScale scale;
  // Range each joint's potentiometer spans (the joint limits).
  std::array<double, 6> potLower{};
  std::array<double, 6> potUpper{};
  uint32_t instrumentId = 0;
  // Fill the velocity quadlets with the Rev 6 registers of simulated encoders (one edge per
  // count, see JointScale) read at each packet's time; false leaves them "no measurement".
  bool velocities = true;
};

// Packets of `joints` (6 joints) at `rate`: packet k starts at byte round(k * lineRate / (8 rate))
// and carries the joints sampled (linear interpolation) at joints.start() + its time, as encoder
// counts (JointScale) and potentiometer readings; the jaw's encoder and potentiometer read 0,
// buttons and status quadlets are 0. The velocity quadlets of joints 1-6 hold the Rev 6 registers
// (period, acceleration) of each joint's encoder, simulated along the log with one edge per count
// and read at the packet's time (see SynthesisOptions::velocities); the jaw's read "no
// measurement", as do joints that have not yet moved through a full encoder cycle. Packets run from
// the first sample to the last (times relative to the first sample). Throws viscera::Error when
// the rate is not positive, or so high that a packet does not fit in its period on the line
// (naming the limit), and when the trajectory is empty or not 6 joints.
std::vector<CaptureSample> synthesizeCapture(const JointTrajectory& joints, const SynthesisOptions& options);

}  // namespace viscera::robot::espm
