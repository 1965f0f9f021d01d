#include "robot/espm/Capture.h"
#include "core/Files.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/scene/CsvTable.h"
#include "robot/encoder/EncoderFpga.h"
#include "robot/encoder/Quadrature.h"
#include "robot/encoder/Registers.h"
#include "core/Text.h"

namespace viscera::robot::espm {
namespace {

constexpr double kCounterModulus = 16777216.0;  // 2^24
constexpr size_t kReadPiece = size_t{1} << 20;

void requireLineRate(double lineRate, const std::string& source) {
  if (!(std::isfinite(lineRate) && lineRate > 0))
    throw Error(SourceLoc{source}, "line rate " + formatNumber(lineRate) + " bit/s is not a positive number");
}

// Collects the information packets a decoder emits.
class Collector {
 public:
  explicit Collector(Capture& capture) : capture_(capture), secondsPerByte_(8.0 / capture.lineRate) {}
  void operator()(const DecodedFrame& f) const {
    if (f.packet) capture_.samples.push_back({static_cast<double>(f.offset) * secondsPerByte_, f.offset, *f.packet});
  }

 private:
  Capture& capture_;
  double secondsPerByte_;
};

// The decoder's counters in words, for messages.
std::string describe(const DecoderStats& s) {
  std::ostringstream o;
  o << s.bytesFed << " bytes, " << s.framesOk << " good frames, " << s.crcFailures << " CRC failures, " << s.badHeaders
    << " bad headers, " << s.bytesSkipped << " bytes outside good frames";
  return o.str();
}

void finishCapture(StreamDecoder& decoder, Capture& capture, const CaptureOptions& options) {
  decoder.finish(Collector(capture));
  capture.stats = decoder.stats();
  capture.framing = decoder.framing();
  if (!capture.samples.empty()) return;
  if (capture.stats.bytesFed == 0) throw Error(SourceLoc{capture.source}, "the capture is empty: no ESPM packet");
  std::string why = "no valid ESPM packet (" + describe(capture.stats) + ")";
  if (options.framing == Framing::Auto && decoder.framing() == Framing::Auto && capture.stats.bytesFed > 0)
    why += "; the framing was not detected: no two frames in a row passed one framing (for a capture of a "
           "single packet, name the framing)";
  else if (capture.stats.framesOk > 0)
    why += "; the good frames are not information packets (page 0, 32 quadlets)";
  throw Error(SourceLoc{capture.source}, why);
}

}  // namespace

Capture decodeCapture(std::span<const uint8_t> bytes, const std::string& source, const CaptureOptions& options) {
  requireLineRate(options.lineRate, source);
  Capture capture;
  capture.source = source;
  capture.lineRate = options.lineRate;
  capture.samples.reserve(bytes.size() / kDissertationFrameBytes + 1);
  StreamDecoder decoder(options.framing);
  decoder.feed(bytes, Collector(capture));
  finishCapture(decoder, capture, options);
  return capture;
}

Capture readCapture(const std::string& path, const CaptureOptions& options) {
  requireLineRate(options.lineRate, path);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error(SourceLoc{path}, "is a folder, not a capture file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(SourceLoc{path}, std::string("cannot open the capture: ") + std::strerror(errno));
  Capture capture;
  capture.source = path;
  capture.lineRate = options.lineRate;
  StreamDecoder decoder(options.framing);
  const Collector collect(capture);
  std::vector<uint8_t> piece(kReadPiece);
  while (in) {
    in.read(reinterpret_cast<char*>(piece.data()), static_cast<std::streamsize>(piece.size()));
    decoder.feed(piece.data(), static_cast<size_t>(in.gcount()), collect);
  }
  if (in.bad()) throw Error(SourceLoc{path}, "cannot read the capture (read error)");
  finishCapture(decoder, capture, options);
  return capture;
}

std::vector<uint8_t> encodeCapture(std::span<const CaptureSample> samples, const CaptureOptions& options) {
  if (options.framing == Framing::Auto)
    throw Error("encodeCapture: a capture is written in the dissertation or the public framing, not auto");
  requireLineRate(options.lineRate, "encodeCapture");
  const double bytesPerSecond = options.lineRate / 8;
  const size_t frameBytes = packetFrameBytes(options.framing);
  std::vector<uint8_t> out;
  for (size_t i = 0; i < samples.size(); ++i) {
    const double t = samples[i].time;
    const double offset = std::round(t * bytesPerSecond);
    if (!(std::isfinite(offset) && offset >= 0 && offset < 1e15))
      throw Error("packet " + std::to_string(i) + ": time " + formatNumber(t) + " s is not a time in a capture");
    const size_t start = static_cast<size_t>(offset);
    if (start < out.size())
      throw Error("packet " + std::to_string(i) + " at t = " + formatNumber(t) + " s (byte " + std::to_string(start) +
                  ") starts before packet " + std::to_string(i - 1) + " ends (byte " + std::to_string(out.size()) +
                  "): a packet takes " + std::to_string(frameBytes) + " bytes on the line");
    out.resize(start, 0);
    appendPacketFrame(out, options.framing, samples[i].packet);
  }
  return out;
}

void writeCapture(const std::string& path, std::span<const CaptureSample> samples, const CaptureOptions& options) {
  std::vector<uint8_t> bytes;
  try {
    bytes = encodeCapture(samples, options);
  } catch (const Error& e) {
    throw Error(SourceLoc{path}, e.what());
  }
  writeFileAtomic(path, std::string(bytes.begin(), bytes.end()));
}

void JointScale::validate() const {
  for (int j = 0; j < kJointChannels; ++j) {
    if (!(std::isfinite(countsPerUnit[j]) && countsPerUnit[j] != 0))
      throw Error("encoder " + std::to_string(j + 1) + ": counts per unit " + formatNumber(countsPerUnit[j]) +
                  " is not a non-zero number");
    if (!std::isfinite(offset[j]))
      throw Error("encoder " + std::to_string(j + 1) + ": offset " + formatNumber(offset[j]) + " is not a number");
  }
}

EncoderPosition JointScale::toEncoder(int channel, double value) const {
  const double counts = std::round((value - offset[channel]) * countsPerUnit[channel]);
  if (!std::isfinite(counts))
    throw std::invalid_argument("JointScale::toEncoder: encoder " + std::to_string(channel + 1) + " value " +
                                formatNumber(value) + " gives no count");
  if (counts >= kEncoderCountMin && counts <= kEncoderCountMax) return {static_cast<int32_t>(counts), false};
  // Outside the 24-bit counter: it wraps and the overflow bit is set.
  const double wrapped = counts - kCounterModulus * std::floor((counts + kEncoderMidrange) / kCounterModulus);
  return {static_cast<int32_t>(std::clamp<double>(wrapped, kEncoderCountMin, kEncoderCountMax)), true};
}

JointTrajectory jointsFromCapture(const Capture& capture, const JointScale& scale) {
  scale.validate();
  constexpr int kJoints = 6;
  JointTrajectory joints(kJoints);
  Eigen::VectorXd q(kJoints);
  for (const CaptureSample& s : capture.samples) {
    for (int j = 0; j < kJoints; ++j) {
      const EncoderPosition& e = s.packet.encoders[j];
      if (e.overflow)
        throw Error(SourceLoc{capture.source}, "packet at byte offset " + std::to_string(s.offset) + " (t = " +
                                                   formatNumber(s.time) + " s): encoder " + std::to_string(j + 1) +
                                                   " has its overflow bit set, so its count is no joint position");
      q[j] = scale.toJoint(j, e.count);
    }
    joints.add(s.time, q);
  }
  return joints;
}

uint16_t potReading(double value, double lower, double upper) {
  const double r = std::round((value - lower) / (upper - lower) * 4095.0);
  return static_cast<uint16_t>(std::clamp(std::isnan(r) ? 0.0 : r, 0.0, 4095.0));
}

namespace {

// The Rev 6 velocity registers (Tables I-4 / I-5) of joint j's encoder at each packet time (s
// from the log's first sample). The encoder gives one edge per count (countsPerUnit edges per rad,
// or per m): a one-line quadrature encoder on a "shaft" geared so that a joint revolution is
// countsPerUnit x 2 pi counts. Its edges along the log's piecewise-linear motion are timed on the
// 49.152 MHz clock and fed through the FPGA's quarter-cycle queue, which is read at each packet.
std::vector<encoder::Rev6Registers> velocityRegisters(const JointTrajectory& joints, int j, double countsPerUnit,
                                                      const std::vector<double>& times) {
  const int n = joints.size();
  std::vector<double> t(static_cast<size_t>(n)), q(static_cast<size_t>(n));
  const double sign = countsPerUnit < 0 ? -1 : 1;  // a negative scale counts the other way
  double shortest = 1e-3;
  for (int i = 0; i < n; ++i) {
    t[i] = joints.time(i) - joints.start();
    q[i] = sign * joints.joints(i)[j];
    if (i > 0) shortest = std::min(shortest, t[i] - t[i - 1]);
  }
  // The joint moves linearly between samples and holds outside them.
  auto segment = [&](double time) {
    return static_cast<int>(std::upper_bound(t.begin(), t.end(), time) - t.begin()) - 1;
  };
  encoder::JointMotion motion;
  motion.angle = [&](double time) {
    if (n == 1 || time <= 0) return q.front();
    if (time >= t.back()) return q.back();
    const int i = segment(time);
    return q[i] + (time - t[i]) / (t[i + 1] - t[i]) * (q[i + 1] - q[i]);
  };
  motion.velocity = [&](double time) {
    if (n == 1 || time < 0 || time >= t.back()) return 0.0;
    const int i = segment(time);
    return (q[i + 1] - q[i]) / (t[i + 1] - t[i]);
  };
  encoder::EncoderSpec spec;
  spec.lines = 1;
  spec.gearRatio = std::abs(countsPerUnit) * 2 * M_PI / 4;
  const encoder::QuadratureEncoder enc(spec);
  std::vector<encoder::EdgeEvent> edges;
  try {
    // Velocity reversals happen only at samples, so half the shortest interval separates them.
    edges = enc.simulate(motion, 0, times.back(), shortest / 2);
  } catch (const std::invalid_argument& e) {
    throw Error("velocities of joint " + std::to_string(j + 1) + ": " + e.what() +
                " (the motion crosses too many encoder counts; lower the counts per unit)");
  }
  std::vector<int64_t> ticks(times.size());
  for (size_t k = 0; k < times.size(); ++k) ticks[k] = static_cast<int64_t>(std::floor(times[k] * spec.clockHz));
  const std::vector<encoder::FpgaReadout> readouts =
      encoder::readAt(edges, enc.levels(q.front()), enc.count(q.front()), ticks);
  std::vector<encoder::Rev6Registers> registers(readouts.size());
  for (size_t k = 0; k < readouts.size(); ++k) registers[k] = encoder::encodeRev6(readouts[k]);
  return registers;
}

}  // namespace

std::vector<CaptureSample> synthesizeCapture(const JointTrajectory& joints, const SynthesisOptions& o) {
  if (joints.dof() != 6) throw Error("synthesizeCapture: the joint trajectory has " + std::to_string(joints.dof()) + " joints, not 6");
  if (joints.empty()) throw Error("synthesizeCapture: the joint trajectory has no samples");
  requireLineRate(o.lineRate, "synthesizeCapture");
  o.scale.validate();
  if (!(std::isfinite(o.rate) && o.rate > 0)) throw Error("rate: " + formatNumber(o.rate) + " packets/s is not a positive number");
  const double bytesPerPacket = o.lineRate / (8 * o.rate);
  const size_t frameBytes = packetFrameBytes(o.framing);
  if (bytesPerPacket < static_cast<double>(frameBytes)) {
    std::ostringstream m;
    m << "rate: " << formatNumber(o.rate) << " packets/s do not fit on a " << formatNumber(o.lineRate / 1e6)
      << " Mbit/s line: a " << framingName(o.framing) << "-framed packet takes " << frameBytes << " bytes, so at most "
      << static_cast<long long>(std::floor(o.lineRate / (8.0 * static_cast<double>(frameBytes)))) << " packets/s";
    throw Error(m.str());
  }

  Packet packet;
  packet.instrumentId = o.instrumentId;
  packet.velocityFirst.fill(kVelocityFirstNoMeasurement);
  packet.velocitySecond.fill(kVelocitySecondNoMeasurement);
  // The slack keeps a last sample that rate * duration reaches up to rounding.
  const double span = joints.end() - joints.start();
  const long long count = static_cast<long long>(std::floor(span * o.rate * (1 + 1e-12) + 1e-9)) + 1;
  std::vector<CaptureSample> samples;
  samples.reserve(static_cast<size_t>(count));
  std::vector<double> times;
  times.reserve(static_cast<size_t>(count));
  Eigen::VectorXd q(6);
  for (long long k = 0; k < count; ++k) {
    const uint64_t offset = static_cast<uint64_t>(std::llround(static_cast<double>(k) * bytesPerPacket));
    const double time = static_cast<double>(offset) * 8 / o.lineRate;
    joints.sample(joints.start() + time, q);
    for (int j = 0; j < 6; ++j) {
      packet.encoders[j] = o.scale.toEncoder(j, q[j]);
      packet.pots[j] = {potReading(q[j], o.potLower[j], o.potUpper[j]), 0, true};
    }
    samples.push_back({time, offset, packet});
    times.push_back(time);
  }
  if (o.velocities)
    for (int j = 0; j < 6; ++j) {
      const std::vector<encoder::Rev6Registers> registers = velocityRegisters(joints, j, o.scale.countsPerUnit[j], times);
      for (size_t k = 0; k < samples.size(); ++k) {
        samples[k].packet.velocityFirst[j] = registers[k].period;
        samples[k].packet.velocitySecond[j] = registers[k].acceleration;
      }
    }
  return samples;
}

}  // namespace viscera::robot::espm
