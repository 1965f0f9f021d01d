// Captures: writing and reading back (times from byte offsets at the line rate), their errors, the
// joint scale, jointsFromCapture, and the synthesis of a capture from a joint trajectory.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <stdexcept>
#include <vector>

#include "robot/encoder/Registers.h"
#include "robot/encoder/VelocityEstimators.h"
#include "robot/espm/Capture.h"
#include "tests/robot/espm/espm_test_support.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

using namespace viscera::robot::espm;
using viscera::robot::JointTrajectory;
using viscera::test_support::errorOf;
using viscera::test_support::TempDir;

namespace encoder = viscera::robot::encoder;

using espm_test::randomPacket;

namespace {

void writeBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace

TEST(EspmCapture, WriteAndReadBackWithTimesFromOffsets) {
  TempDir dir;
  std::mt19937_64 rng(21);
  for (Framing framing : {Framing::Dissertation, Framing::Public}) {
    // 1 kHz: at 20 Mbit/s = 2.5e6 bytes/s each packet starts 2500 bytes after the previous one.
    std::vector<CaptureSample> samples;
    for (int k = 0; k < 200; ++k) samples.push_back({k * 1e-3, 0, randomPacket(rng)});
    const std::string path = dir / (std::string("capture_") + framingName(framing) + ".bin");
    writeCapture(path, samples, {framing, 20e6});
    const Capture c = readCapture(path);  // Auto
    EXPECT_EQ(c.framing, framing);
    ASSERT_EQ(c.samples.size(), samples.size());
    for (int k = 0; k < 200; ++k) {
      EXPECT_EQ(c.samples[k].offset, 2500u * k);
      // offset * 8 / 20e6 = k * 1e-3 up to the rounding of the division (a few ulp).
      EXPECT_NEAR(c.samples[k].time, k * 1e-3, 1e-15);
      EXPECT_EQ(c.samples[k].packet, samples[k].packet);
    }
    EXPECT_NEAR(c.duration(), 0.199, 1e-15);
    EXPECT_EQ(c.stats.bytesSkipped, 199u * (2500 - packetFrameBytes(framing)));
    EXPECT_EQ(c.stats.crcFailures, 0u);
    // A different line rate scales the times: 10 Mbit/s doubles them.
    const Capture slow = readCapture(path, {framing, 10e6});
    EXPECT_NEAR(slow.samples[1].time, 2e-3, 1e-15);
  }
}

TEST(EspmCapture, OverlappingPacketsAndBadTimesAreRefused) {
  std::vector<CaptureSample> samples(2);
  samples[1].time = 20e-6;  // 50 bytes after the first, which takes 134
  EXPECT_NE(errorOf([&] { encodeCapture(samples, {Framing::Dissertation, 20e6}); }).find("starts before packet 0 ends"),
            std::string::npos);
  samples[1].time = -1;
  EXPECT_NE(errorOf([&] { encodeCapture(samples, {Framing::Dissertation, 20e6}); }).find("packet 1"), std::string::npos);
  EXPECT_THROW(encodeCapture(samples, {Framing::Auto, 20e6}), viscera::Error);
}

TEST(EspmCapture, ReadErrorsNameTheFile) {
  TempDir dir;
  const std::string missing = dir / "missing.bin";
  EXPECT_NE(errorOf([&] { readCapture(missing); }).find(missing + ": cannot open"), std::string::npos);

  const std::string empty = dir / "empty.bin";
  writeBytes(empty, {});
  EXPECT_NE(errorOf([&] { readCapture(empty); }).find(empty + ": the capture is empty"), std::string::npos);

  std::mt19937_64 rng(22);
  std::vector<uint8_t> garbage(10000);
  for (auto& b : garbage) b = static_cast<uint8_t>(rng());
  const std::string noise = dir / "noise.bin";
  writeBytes(noise, garbage);
  const std::string e = errorOf([&] { readCapture(noise, {Framing::Dissertation, 20e6}); });
  EXPECT_NE(e.find(noise + ": no valid ESPM packet (10000 bytes"), std::string::npos) << e;

  // Auto with a single packet cannot decide the framing, and says so.
  std::vector<uint8_t> one;
  appendDissertationFrame(one, randomPacket(rng));
  const std::string single = dir / "single.bin";
  writeBytes(single, one);
  EXPECT_NE(errorOf([&] { readCapture(single); }).find("the framing was not detected"), std::string::npos);
  EXPECT_EQ(readCapture(single, {Framing::Dissertation, 20e6}).samples.size(), 1u);

  EXPECT_NE(errorOf([&] { readCapture(single, {Framing::Dissertation, 0}); }).find("line rate"), std::string::npos);
}

TEST(EspmJointScale, CountsAndJointValues) {
  const JointScale scale;
  // 1e5 counts/rad: 0.5 rad is 50000 counts; 1e6 counts/m: 0.1 m of insertion is 100000 counts.
  EXPECT_EQ(scale.toEncoder(0, 0.5).count, 50000);
  EXPECT_EQ(scale.toEncoder(2, 0.1).count, 100000);
  EXPECT_EQ(scale.toEncoder(1, -0.123456).count, -12346);  // rounds to the nearest count
  EXPECT_DOUBLE_EQ(scale.toJoint(2, 100000), 0.1);
  EXPECT_FALSE(scale.toEncoder(0, 83.88607).overflow);  // 8388607 counts: the largest
  // 8388608 counts is one past the 24-bit range: wraps to -8388608 with the overflow bit.
  const EncoderPosition over = scale.toEncoder(0, 83.88608);
  EXPECT_TRUE(over.overflow);
  EXPECT_EQ(over.count, -8388608);
  const EncoderPosition under = scale.toEncoder(0, -83.88609);  // -8388609 wraps to 8388607
  EXPECT_TRUE(under.overflow);
  EXPECT_EQ(under.count, 8388607);
  EXPECT_THROW(scale.toEncoder(0, std::nan("")), std::invalid_argument);

  JointScale withOffset;
  withOffset.offset[3] = 1.0;
  EXPECT_EQ(withOffset.toEncoder(3, 1.25).count, 25000);
  EXPECT_DOUBLE_EQ(withOffset.toJoint(3, 25000), 1.25);

  JointScale bad;
  bad.countsPerUnit[4] = 0;
  EXPECT_NE(errorOf([&] { bad.validate(); }).find("encoder 5"), std::string::npos);
}

TEST(EspmCapture, JointsFromCaptureAndOverflow) {
  Capture c;
  c.source = "arm.bin";
  const JointScale scale;
  for (int k = 0; k < 3; ++k) {
    CaptureSample s;
    s.time = k * 1e-3;
    s.offset = 2500u * k;
    for (int j = 0; j < 7; ++j) s.packet.encoders[j].count = 1000 * (j + 1) * (k + 1);
    c.samples.push_back(s);
  }
  const JointTrajectory joints = jointsFromCapture(c, scale);
  ASSERT_EQ(joints.dof(), 6);
  ASSERT_EQ(joints.size(), 3);
  EXPECT_DOUBLE_EQ(joints.time(2), 2e-3);
  EXPECT_DOUBLE_EQ(joints.joints(1)[0], 2000 / 1e5);  // 0.02 rad
  EXPECT_DOUBLE_EQ(joints.joints(1)[2], 6000 / 1e6);  // 0.006 m
  EXPECT_DOUBLE_EQ(joints.joints(2)[5], 18000 / 1e5);

  c.samples[1].packet.encoders[4].overflow = true;
  EXPECT_EQ(errorOf([&] { jointsFromCapture(c, scale); }),
            "arm.bin: packet at byte offset 2500 (t = 0.001 s): encoder 5 has its overflow bit set, so its count is no "
            "joint position");
  // The jaw (encoder 7) is not a PSM joint: its overflow does not matter here.
  c.samples[1].packet.encoders[4].overflow = false;
  c.samples[1].packet.encoders[6].overflow = true;
  EXPECT_EQ(jointsFromCapture(c, scale).size(), 3);
}

TEST(EspmCapture, SynthesisSamplesTheTrajectoryAtPacketTimes) {
  // Joint 1 ramps from 0 to 1 rad over 1 s, the insertion from 0.1 to 0.2 m; the rest stay still.
  JointTrajectory joints(6);
  Eigen::VectorXd q0(6), q1(6);
  q0 << 0, 0.2, 0.1, -1, 0.5, 0.25;
  q1 << 1, 0.2, 0.2, -1, 0.5, 0.25;
  joints.add(2.0, q0);
  joints.add(3.0, q1);
  SynthesisOptions o;
  o.rate = 1000;
  o.instrumentId = 0xCAFE;
  for (int j = 0; j < 6; ++j) {
    o.potLower[j] = -2;
    o.potUpper[j] = 2;
  }
  const std::vector<CaptureSample> samples = synthesizeCapture(joints, o);
  ASSERT_EQ(samples.size(), 1001u);  // 0, 1, ..., 1000 ms
  const CaptureSample& mid = samples[500];
  EXPECT_EQ(mid.offset, 1'250'000u);  // 0.5 s * 2.5e6 bytes/s
  EXPECT_DOUBLE_EQ(mid.time, 0.5);
  EXPECT_EQ(mid.packet.encoders[0].count, 50000);   // 0.5 rad
  EXPECT_EQ(mid.packet.encoders[2].count, 150000);  // 0.15 m
  EXPECT_EQ(mid.packet.encoders[3].count, -100000);
  EXPECT_EQ(mid.packet.encoders[6].count, 0);       // the jaw
  // Potentiometers span [-2, 2] over 0..4095: 0.5 rad reads round(2.5 / 4 * 4095) = 2559.
  EXPECT_EQ(mid.packet.pots[0].position, 2559);
  EXPECT_EQ(mid.packet.pots[3].position, 1024);  // round(1 / 4 * 4095) = 1023.75 -> 1024
  EXPECT_TRUE(mid.packet.pots[0].parityOk);
  EXPECT_EQ(mid.packet.instrumentId, 0xCAFEu);
  // Velocity quadlets (Rev 6) of the simulated encoders: joint 1 turns at 1 rad/s = 1e5 counts/s and
  // the insertion moves at 0.1 m/s = 1e5 counts/s, so a full cycle (4 counts) takes 40 us = 1966.08
  // clock ticks. Rev 6 drops the low 4 bits of the sum and the edges are quantised to a tick:
  // S is known to 17 ticks, a relative error of 17 / 1966.
  for (int j : {0, 2}) {
    const encoder::Measurement m = encoder::decodeRev6(mid.packet.velocityFirst[j], mid.packet.velocitySecond[j]);
    ASSERT_FALSE(m.overflow) << j;
    const double speed = j == 0 ? 1.0 : 0.1;  // rad/s, m/s
    EXPECT_NEAR(encoder::fullCycleVelocity(m) / o.scale.countsPerUnit[j], speed, speed * 17 / 1966.08) << j;
    EXPECT_NEAR(encoder::fullCycleAccelerationVelocity(m) / o.scale.countsPerUnit[j], speed, speed * 17 / 1966.08) << j;
  }
  // Joints that never move have seen no edge: overflow, no velocity.
  for (int j : {1, 3, 4, 5}) {
    const encoder::Measurement m = encoder::decodeRev6(mid.packet.velocityFirst[j], mid.packet.velocitySecond[j]);
    EXPECT_TRUE(m.overflow) << j;
    EXPECT_EQ(encoder::fullCycleVelocity(m), 0.0) << j;
  }
  EXPECT_EQ(mid.packet.velocityFirst[6], kVelocityFirstNoMeasurement);  // the jaw
  EXPECT_EQ(mid.packet.velocitySecond[6], kVelocitySecondNoMeasurement);

  // Through the bytes and back: the joints come back to within half a count.
  const std::vector<uint8_t> bytes = encodeCapture(samples, {Framing::Dissertation, o.lineRate});
  const JointTrajectory back = jointsFromCapture(decodeCapture(bytes, "synth", {}), o.scale);
  ASSERT_EQ(back.size(), 1001);
  for (int k = 0; k < back.size(); k += 37) {
    const Eigen::VectorXd expected = joints.sample(2.0 + back.time(k));
    for (int j = 0; j < 6; ++j) {
      const double halfCount = 0.5 / o.scale.countsPerUnit[j];  // rounding to the nearest count
      EXPECT_NEAR(back.joints(k)[j], expected[j], halfCount * (1 + 1e-9)) << k << " " << j;
    }
  }
}

TEST(EspmCapture, SynthesisRateMustFitTheLine) {
  JointTrajectory joints(6);
  joints.add(0, Eigen::VectorXd::Zero(6));
  SynthesisOptions o;
  o.rate = 20000;  // 125 bytes per packet < 134
  EXPECT_EQ(errorOf([&] { synthesizeCapture(joints, o); }),
            "rate: 20000 packets/s do not fit on a 20 Mbit/s line: a dissertation-framed packet takes 134 bytes, so at "
            "most 18656 packets/s");
  o.rate = 0;
  EXPECT_NE(errorOf([&] { synthesizeCapture(joints, o); }).find("rate: 0 packets/s"), std::string::npos);
  o.rate = 1000;
  EXPECT_EQ(synthesizeCapture(joints, o).size(), 1u);  // a single sample: one packet
}
