// Quadrature incremental encoders: the two square-wave channels A and B of an encoder on a joint,
// with the imperfections that matter for velocity estimation (uneven duty cycles, a phase of B that
// is not 90 electrical degrees), and the edge events a joint motion produces, timed by root finding
// and quantised to the ticks of the FPGA clock that samples them.
//
// Convention (that of the dVRK firmware): moving forward, A leads B and the edges come in the order
// A rise, B rise, A fall, B fall. Moving backward an edge is crossed the other way round, so a
// position where A rises going forward makes A fall going backward: the backward order is
// B rise, A rise, B fall, A fall.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace viscera::robot::encoder {

// The clock of the dVRK FPGA that times encoder edges (the FireWire clock).
inline constexpr double kFpgaClockHz = 49.152e6;

// An edge type, as the bit it sets in the 4-bit edge mask of the Rev 7 quarter-cycle registers
// (mask bits 3..0: A rise, B rise, A fall, B fall).
enum class Edge : uint8_t { ARise = 0x8, BRise = 0x4, AFall = 0x2, BFall = 0x1 };

struct EncoderSpec {
  double lines = 16;        // cycles (lines) per encoder revolution
  double gearRatio = 1;     // encoder revolutions per joint revolution
  double dutyA = 0.5;       // fraction of a cycle that A is high
  double dutyB = 0.5;       // fraction of a cycle that B is high
  double phaseB = 90;       // electrical degrees from A's rise to B's rise
  double clockHz = kFpgaClockHz;

  // Quadrature counts (edges) per joint revolution: 4 x lines x gear ratio.
  double countsPerRevolution() const { return 4 * lines * gearRatio; }
};

// Throws std::invalid_argument "field: what is wrong" unless the numbers are finite and positive,
// the duty cycles are in (0, 1), and the edges alternate A rise, B rise, A fall, B fall within a
// cycle (B rises while A is high and falls while A is low), which a quadrature decoder needs.
void validate(const EncoderSpec& spec);

// A joint's angle (rad) over time (s) and its exact derivative (rad/s).
struct JointMotion {
  std::function<double(double)> angle;
  std::function<double(double)> velocity;
};

// One edge seen by the FPGA.
struct EdgeEvent {
  double time = 0;     // exact crossing time, s
  int64_t tick = 0;    // first clock tick at or after `time` (tick k is at time k / clockHz)
  Edge type = Edge::ARise;
  bool forward = true;  // direction of travel at the crossing
};

// The levels of the two channels.
struct ChannelLevels {
  bool a = false;
  bool b = false;
};

class QuadratureEncoder {
 public:
  // Most edges one simulation returns (480 MB of events).
  static constexpr size_t kMaxEdges = 20'000'000;

  // Validates `spec` (see validate).
  explicit QuadratureEncoder(const EncoderSpec& spec);

  const EncoderSpec& spec() const { return spec_; }

  // Encoder position in cycles for a joint angle in rad: angle x lines x gear ratio / 2 pi.
  double cycles(double angle) const { return angle * cyclesPerRadian_; }
  // The position count of a decoder at `angle`: the number of edge positions at or below it,
  // counted from angle 0 (an edge at 0 counts). Moving across an edge forward adds one, backward
  // takes one away.
  int64_t count(double angle) const;
  // Channel levels at `angle` (a channel is high from its rising edge up to, not including, its
  // falling edge).
  ChannelLevels levels(double angle) const;

  // The edges the motion produces in [t0, t1], in time order, with their ticks. The motion is cut
  // into pieces where the velocity keeps its sign: the velocity is sampled every `maxStep` seconds
  // and a reversal between samples is located by bisection, so at most one reversal may fall
  // between two samples. Each edge time is then found by safeguarded Newton iteration on the
  // angle to 1e-12 s. Two edges of one channel within the same tick (a reversal right at an edge)
  // cancel: the sampled channel never changed. Throws std::invalid_argument for t1 < t0, a step
  // that is not positive, or more than kMaxEdges edges ("edges: ...").
  std::vector<EdgeEvent> simulate(const JointMotion& motion, double t0, double t1, double maxStep) const;

 private:
  // Appends the edges crossed while the angle moves monotonically over [ta, tb].
  void monotonePiece(const JointMotion& motion, double ta, double tb, std::vector<EdgeEvent>& out) const;

  EncoderSpec spec_;
  double cyclesPerRadian_ = 0;
  // Edge positions within one cycle, increasing: A rise (0), B rise, A fall, B fall.
  double edgeAt_[4] = {};
};

// Edge type crossed at edge position k (0..3 within a cycle: A rise, B rise, A fall, B fall) in
// the given direction.
Edge edgeCrossed(int k, bool forward);

}  // namespace viscera::robot::encoder
