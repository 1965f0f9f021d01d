// `viscera espm decode`: decodes an ESPM capture (the raw bytes of the dVRK-S arm's link) into a
// summary and a CSV of its packets; `viscera espm synth`: writes the capture an arm following a
// joint log would have sent.
#include "apps/viscera/EspmCommand.h"
#include "core/Files.h"
#include "apps/viscera/CliText.h"

#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/scene/CsvTable.h"
#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityEstimators.h"
#include "robot/espm/Capture.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"
#include "core/Text.h"

namespace viscera {
namespace {

namespace fs = std::filesystem;
using namespace robot::espm;
namespace encoder = robot::encoder;
using cli::jsonString;

struct DecodeOptions {
  std::string capture, csv, json, framing = "auto", countsPerUnit;
  double lineRate = kLineRate;
  bool noJoints = false;
};

struct SynthOptions {
  std::string joints, out, framing = "dissertation", countsPerUnit, instrumentId = "0";
  double rate = 1000;
  double lineRate = kLineRate;
};

Framing framingOption(const std::string& text) {
  Framing f;
  if (!parseFraming(text, f)) throw Error("--framing: '" + text + "' is not one of dissertation, public, auto");
  return f;
}

double lineRateOption(double rate) {
  if (!(std::isfinite(rate) && rate > 0)) throw Error("--line-rate: " + formatNumber(rate) + " is not a positive number of bit/s");
  // A serial link of the arm's electronics: anything past 10 Gbit/s is a typing mistake.
  if (rate > 1e10) throw Error("--line-rate: " + formatNumber(rate) + " bit/s is beyond any link the arms use (at most 1e10)");
  return rate;
}

// Seven counts per unit, one per encoder; empty text keeps the defaults.
JointScale scaleOption(const std::string& text) {
  JointScale scale;
  if (text.empty()) return scale;
  const auto v = cli::finiteNumbers(text, "--counts-per-unit", kJointChannels, "c1 c2 c3 c4 c5 c6 c7");
  for (int j = 0; j < kJointChannels; ++j) scale.countsPerUnit[j] = v[j];
  try {
    scale.validate();
  } catch (const Error& e) {
    throw Error(std::string("--counts-per-unit: ") + e.what());
  }
  return scale;
}

// Decimal, or hexadecimal with 0x; 32 bits.
uint32_t instrumentIdOption(const std::string& text) {
  const bool hex = text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X');
  const std::string digits = hex ? text.substr(2) : text;
  const char* first = digits.data();
  const char* last = first + digits.size();
  uint64_t value = 0;
  const auto [end, ec] = std::from_chars(first, last, value, hex ? 16 : 10);
  if (digits.empty() || ec != std::errc() || end != last || value > 0xFFFFFFFFull)
    throw Error("--instrument-id: '" + text + "' is not a 32-bit number (decimal, or hexadecimal with 0x)");
  return static_cast<uint32_t>(value);
}

std::string hex32(uint32_t v) {
  char text[12];
  std::snprintf(text, sizeof text, "0x%08X", v);
  return text;
}

void appendColumns(std::string& header, const char* name, int count) {
  for (int i = 1; i <= count; ++i) header += std::string(",") + name + std::to_string(i);
}

// Joint j's velocity (rad/s, m/s for the insertion) from a packet's Rev 6 velocity quadlets: the
// full-cycle estimate with the acceleration term (Eq. II.7), 0 without a measurement.
double jointVelocity(const Packet& p, int j, const JointScale& scale) {
  const encoder::Measurement m = encoder::decodeRev6(p.velocityFirst[j], p.velocitySecond[j]);
  return encoder::fullCycleAccelerationVelocity(m) / scale.countsPerUnit[j];
}

// One row per packet: time, offset, encoder counts and overflow flags, joint values and velocities
// (unless left out), potentiometer positions and parity flags, buttons, instrument id, raw velocity
// quadlets.
std::string packetCsv(const Capture& capture, const robot::JointTrajectory* joints, const JointScale& scale) {
  std::string out = "t,offset";
  appendColumns(out, "enc", kJointChannels);
  appendColumns(out, "overflow", kJointChannels);
  if (joints) {
    appendColumns(out, "q", joints->dof());
    appendColumns(out, "v", joints->dof());
  }
  appendColumns(out, "pot", kJointChannels);
  appendColumns(out, "parity_ok", kJointChannels);
  out += ",buttons,instrument_id";
  appendColumns(out, "vel_a", kJointChannels);
  appendColumns(out, "vel_b", kJointChannels);
  out += '\n';
  for (size_t i = 0; i < capture.samples.size(); ++i) {
    const CaptureSample& s = capture.samples[i];
    const Packet& p = s.packet;
    out += formatNumber(s.time) + ',' + std::to_string(s.offset);
    for (const auto& e : p.encoders) out += ',' + std::to_string(e.count);
    for (const auto& e : p.encoders) out += e.overflow ? ",1" : ",0";
    if (joints) {
      for (int j = 0; j < joints->dof(); ++j) out += ',' + formatNumber(joints->joints(static_cast<int>(i))[j]);
      for (int j = 0; j < joints->dof(); ++j) out += ',' + formatNumber(jointVelocity(p, j, scale));
    }
    for (const auto& pot : p.pots) out += ',' + std::to_string(pot.position);
    for (const auto& pot : p.pots) out += pot.parityOk ? ",1" : ",0";
    out += ',' + hex32(encodeButtons(p.buttons)) + ',' + hex32(p.instrumentId);
    for (uint32_t v : p.velocityFirst) out += ',' + hex32(v);
    for (uint32_t v : p.velocitySecond) out += ',' + hex32(v);
    out += '\n';
  }
  return out;
}

struct PacketCounts {
  uint64_t parityErrors = 0;  // potentiometer readings with a wrong parity bit
  uint64_t overflowPackets = 0;  // packets with any encoder's overflow bit set
};

PacketCounts countPackets(const Capture& capture) {
  PacketCounts c;
  for (const CaptureSample& s : capture.samples) {
    for (const auto& pot : s.packet.pots) c.parityErrors += !pot.parityOk;
    bool overflow = false;
    for (const auto& e : s.packet.encoders) overflow = overflow || e.overflow;
    c.overflowPackets += overflow;
  }
  return c;
}

std::string summaryJson(const Capture& c, const PacketCounts& counts) {
  const DecoderStats& s = c.stats;
  std::ostringstream j;
  j << std::setprecision(12);
  j << "{\n  \"capture\": " << jsonString(c.source) << ",\n  \"framing\": \"" << framingName(c.framing) << "\",\n"
    << "  \"line_rate\": " << c.lineRate << ",\n  \"bytes\": " << s.bytesFed << ",\n  \"packets\": " << c.samples.size()
    << ",\n  \"frames\": " << s.framesOk << ",\n  \"crc_failures\": " << s.crcFailures << ",\n  \"bad_headers\": "
    << s.badHeaders << ",\n  \"rejected_overlap\": " << s.rejectedOverlap << ",\n  \"rejected_unused_bits\": "
    << s.rejectedUnusedBits << ",\n  \"skipped_bytes\": " << s.bytesSkipped << ",\n  \"truncated\": " << s.truncatedFrames
    << ",\n  \"first_time\": " << c.samples.front().time << ",\n  \"last_time\": " << c.samples.back().time
    << ",\n  \"duration\": " << c.duration() << ",\n  \"parity_errors\": " << counts.parityErrors
    << ",\n  \"overflow_packets\": " << counts.overflowPackets << "\n}\n";
  return j.str();
}

int runDecode(const DecodeOptions& o) {
  const CaptureOptions options{framingOption(o.framing), lineRateOption(o.lineRate)};
  const JointScale scale = scaleOption(o.countsPerUnit);
  if (!o.csv.empty()) cli::requireParentFolder(o.csv, "--csv");
  if (!o.json.empty()) cli::requireParentFolder(o.json, "--json");

  const Capture capture = readCapture(o.capture, options);
  const PacketCounts counts = countPackets(capture);
  // Joint values need every PSM encoder without overflow: an error naming the packet otherwise.
  std::unique_ptr<robot::JointTrajectory> joints;
  if (!o.csv.empty() && !o.noJoints) joints = std::make_unique<robot::JointTrajectory>(jointsFromCapture(capture, scale));
  if (!o.csv.empty()) writeFileAtomic(o.csv, packetCsv(capture, joints.get(), scale));
  if (!o.json.empty()) writeFileAtomic(o.json, summaryJson(capture, counts));

  const DecoderStats& s = capture.stats;
  std::cout << o.capture << ": " << capture.samples.size() << " packets (" << framingName(capture.framing)
            << " framing) over " << formatNumber(capture.duration()) << " s, t = "
            << formatNumber(capture.samples.front().time) << " .. " << formatNumber(capture.samples.back().time)
            << " s\n"
            << "  " << s.bytesFed << " bytes: " << s.bytesInFrames << " in good frames, " << s.bytesSkipped
            << " skipped\n"
            << "  " << s.crcFailures << " CRC failures, " << s.badHeaders << " bad headers, " << s.rejectedOverlap
            << " frames refused as overlapping, " << s.rejectedUnusedBits << " with unused bits set, "
            << (s.truncatedFrames ? "a frame truncated at the end" : "no truncated frame") << "\n"
            << "  " << counts.parityErrors << " potentiometer parity errors, " << counts.overflowPackets
            << " packets with an encoder overflow\n";
  return kExitOk;
}

int runSynth(const SynthOptions& o) {
  SynthesisOptions options;
  options.framing = framingOption(o.framing);
  if (options.framing == Framing::Auto) throw Error("--framing: a capture is written in the dissertation or the public framing");
  options.lineRate = lineRateOption(o.lineRate);
  options.scale = scaleOption(o.countsPerUnit);
  options.instrumentId = instrumentIdOption(o.instrumentId);
  options.rate = o.rate;
  cli::requireParentFolder(o.out, "--out");

  const robot::JointTrajectory joints = robot::readJointCsv(o.joints, robot::kPsmDof);
  const robot::SerialChain psm = robot::psmLargeNeedleDriver();
  for (int i = 0; i < joints.size(); ++i) psm.requireWithinLimits(joints.joints(i), SourceLoc{o.joints, joints.line(i)});
  for (int j = 0; j < robot::kPsmDof; ++j) {
    options.potLower[j] = psm.joints()[j].lower;
    options.potUpper[j] = psm.joints()[j].upper;
  }

  // The capture's size follows from the log's span before anything is made: refuse what would not
  // fit a file of kMaxCaptureBytes (packets of up to 128 bytes held in memory meanwhile).
  constexpr double kMaxCaptureBytes = 4.0 * (1ull << 30);
  const double span = joints.size() > 0 ? joints.time(joints.size() - 1) - joints.time(0) : 0.0;
  if (std::isfinite(options.rate) && options.rate > 0 &&
      (span * options.lineRate / 8 > kMaxCaptureBytes || span * options.rate * 128 > kMaxCaptureBytes))
    throw Error(SourceLoc{o.joints}, "the log spans " + formatNumber(span) + " s: its capture at " +
                                         formatNumber(options.rate) + " packets/s and " + formatNumber(options.lineRate) +
                                         " bit/s would exceed 4 GiB (write a shorter log)");

  std::vector<CaptureSample> samples;
  try {
    samples = synthesizeCapture(joints, options);
  } catch (const Error& e) {
    const std::string message = e.what();
    throw Error(message.rfind("rate: ", 0) == 0 ? "--" + message : message);
  }
  // A count beyond the 24-bit counter would reach the capture only as an overflow flag.
  for (const CaptureSample& s : samples)
    for (int j = 0; j < robot::kPsmDof; ++j)
      if (s.packet.encoders[j].overflow)
        throw Error("--counts-per-unit: joint " + std::to_string(j + 1) + " at t = " + formatNumber(s.time) +
                    " s of " + o.joints + " is beyond the 24-bit encoder counter (at most 8388607 counts)");
  writeCapture(o.out, samples, {options.framing, options.lineRate});

  const uint64_t bytes = samples.back().offset + packetFrameBytes(options.framing);
  std::cerr << "wrote " << samples.size() << " packets (" << framingName(options.framing) << " framing, "
            << formatNumber(options.rate) << " packets/s over " << formatNumber(samples.back().time) << " s, "
            << bytes << " bytes) to " << o.out << "\n";
  return kExitOk;
}

}  // namespace

void addEspmCommand(CLI::App& app, std::function<int()>& action) {
  auto* espm = app.add_subcommand("espm", "ESPM captures: the dVRK-S arm's packets on its 20 Mbit/s link");
  espm->require_subcommand(1);

  auto d = std::make_shared<DecodeOptions>();
  auto* decode = espm->add_subcommand("decode", "decode a capture: a summary, and a CSV of its packets");
  decode->footer(
      "A capture is the raw line: frames (magic 0xAC450F28, 32 information quadlets, CRC-16) at any byte offset,\n"
      "idle time as zero bytes; a packet's time is its byte offset * 8 / line rate. Joint values are encoder counts\n"
      "divided by the counts per unit (rad, and m for the insertion, joint 3).");
  decode->add_option("CAPTURE", d->capture, "the capture file")->required();
  decode->add_option("--csv", d->csv, "write one row per packet: t, offset, encoder counts and overflow flags, joints and joint velocities, pots "
                                      "and parity flags, buttons, instrument id, velocity quadlets");
  decode->add_option("--json", d->json, "write the summary as JSON");
  decode->add_option("--framing", d->framing, "dissertation, public or auto (decided from the first frames)")
      ->capture_default_str();
  decode->add_option("--counts-per-unit", d->countsPerUnit,
                     "encoder counts per rad (per m for joint 3) of the 7 encoders (default \"1e5 1e5 1e6 1e5 1e5 1e5 1e5\")");
  decode->add_option("--line-rate", d->lineRate, "bit/s of the link, for packet times")->capture_default_str();
  decode->add_flag("--no-joints", d->noJoints, "leave the joint columns out of the CSV (a capture with encoder overflows "
                                                "has no joint values)");
  decode->callback([d, &action] { action = [d] { return runDecode(*d); }; });

  auto s = std::make_shared<SynthOptions>();
  auto* synth = espm->add_subcommand("synth", "write the capture of an arm following a joint log");
  synth->footer(
      "Packet k starts at byte round(k * line rate / (8 * rate)), idle zero bytes between packets; its joints are\n"
      "the log (t,q1..q6; rad, m for q3) sampled at its time after the log's first sample. Potentiometers read each\n"
      "joint across its PSM limits (0..4095); the jaw reads 0. Velocity quadlets hold the Rev 6 registers of each\n"
      "joint's simulated encoder (one edge per count) read at the packet's time.");
  synth->add_option("--joints", s->joints, "joint log CSV: t,q1,...,q6 within the PSM's limits")->required();
  synth->add_option("--out", s->out, "the capture file to write")->required();
  synth->add_option("--framing", s->framing, "dissertation or public")->capture_default_str();
  synth->add_option("--rate", s->rate, "packets per second")->capture_default_str();
  synth->add_option("--instrument-id", s->instrumentId, "instrument id quadlet (decimal, or hexadecimal with 0x)")
      ->capture_default_str();
  synth->add_option("--counts-per-unit", s->countsPerUnit,
                    "encoder counts per rad (per m for joint 3) of the 7 encoders (default \"1e5 1e5 1e6 1e5 1e5 1e5 1e5\")");
  synth->add_option("--line-rate", s->lineRate, "bit/s of the link")->capture_default_str();
  synth->callback([s, &action] { action = [s] { return runSynth(*s); }; });
}

}  // namespace viscera
