// EspmDriver: a capture synthesised from the example joint log, with some packets corrupted on the
// line, replays the same tool-tip motion as the joint log itself (PsmJointDriver), to the encoder
// quantisation; the corrupt packets are dropped and counted; a limit violation names the packet.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "robot/espm/Capture.h"
#include "robot/kinematics/JointTrajectory.h"
#include "robot/kinematics/PsmKinematics.h"
#include "tests/support/ErrorOf.h"
#include "tests/support/TempDir.h"

using viscera::test_support::errorOf;
using viscera::test_support::TempDir;
namespace espm = viscera::robot::espm;

namespace {

std::string source(const std::string& rel) { return std::string(VISCERA_SOURCE_DIR) + "/" + rel; }

void write(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

std::string scene(const std::string& driver) {
  return R"(<Node name="root" gravity="0 0 0" dt="0.01" units="mm g s">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d"/>
    )" + driver + R"(
  </Node>
</Node>
)";
}

espm::SynthesisOptions synthesis() {
  espm::SynthesisOptions o;
  const auto psm = viscera::robot::psmLargeNeedleDriver();
  for (int j = 0; j < 6; ++j) {
    o.potLower[j] = psm.joints()[j].lower;
    o.potUpper[j] = psm.joints()[j].upper;
  }
  return o;
}

TEST(EspmDriver, CaptureReplaysTheJointLogToTheEncoderResolution) {
  TempDir dir("viscera_espm_driver");
  const auto log = viscera::robot::readJointCsv(source("scenes/psm_palpation_joints.csv"), 6);
  std::vector<uint8_t> bytes = espm::encodeCapture(espm::synthesizeCapture(log, synthesis()), {espm::Framing::Dissertation});
  // Corrupt 25 packets (one bit each, in the information quadlets) spread over the capture.
  const size_t period = 20e6 / 8 / 1000;  // bytes per packet slot at 1 kHz
  for (int k = 0; k < 25; ++k) bytes[(40 * k + 7) * period + 4 + 17 * k % 128] ^= 0x10;
  {
    std::ofstream f(dir / "arm.espm", std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  std::filesystem::copy_file(source("scenes/psm_to_phantom.txt"), dir / "psm.txt");
  std::filesystem::copy_file(source("scenes/psm_palpation_joints.csv"), dir / "joints.csv");
  write(dir / "espm.xml", scene(R"(<EspmDriver name="arm" filename="arm.espm" transform="psm.txt"/>)"));
  write(dir / "joints.xml", scene(R"(<PsmJointDriver name="arm" filename="joints.csv" transform="psm.txt"/>)"));

  auto fromCapture = viscera::buildScene(viscera::io::readScene(dir / "espm.xml"));
  auto fromLog = viscera::buildScene(viscera::io::readScene(dir / "joints.xml"));
  viscera::Simulation a(*fromCapture), b(*fromLog);
  viscera::FieldValue crc, packets;
  const viscera::Component& driver = *fromCapture->all<viscera::Component>().back();
  ASSERT_TRUE(driver.field("crcErrors", crc));
  ASSERT_TRUE(driver.field("packets", packets));
  EXPECT_EQ(crc.values[0], 25);
  EXPECT_EQ(packets.values[0], std::floor(log.end() * 1000) + 1 - 25);

  const auto& ta = fromCapture->all<viscera::RigidObject>().front()->live(a.state());
  const auto& tb = fromLog->all<viscera::RigidObject>().front()->live(b.state());
  double worst = 0;
  for (int k = 0; k < 1500; ++k) {
    ASSERT_FALSE(a.step().has_value());
    ASSERT_FALSE(b.step().has_value());
    worst = std::max(worst, (ta.p - tb.p).norm());
  }
  // Counts of 1e-5 rad and 1 um: half a count on each joint moves the tip by at most
  // sum |dp/dq_j| / 2 count, about 3 um with the ~0.12 m lever; a dropped packet is bridged by
  // interpolating its neighbours 2 ms apart, within the same linear piece of the 30 Hz log
  // except near a knot. 10 um bounds both.
  EXPECT_LT(worst, 0.010);  // mm
  EXPECT_GT(worst, 0.0);    // quantised, not the log itself
}

TEST(EspmDriver, JointOutsideTheLimitsNamesThePacket) {
  TempDir dir("viscera_espm_driver");
  viscera::robot::JointTrajectory log(6);
  Eigen::VectorXd q(6);
  q << 0, 0, 0.12, 0, 0, 0;
  log.add(0, q);
  q[1] = 1.2;  // pitch limit is 0.925 rad
  log.add(0.002, q);
  espm::SynthesisOptions o = synthesis();
  o.potLower.fill(-2);
  o.potUpper.fill(2);
  espm::writeCapture(dir / "arm.espm", espm::synthesizeCapture(log, o), {espm::Framing::Public});
  write(dir / "espm.xml", scene(R"(<EspmDriver name="arm" filename="arm.espm" framing="public"/>)"));
  const std::string msg = errorOf([&] { viscera::buildScene(viscera::io::readScene(dir / "espm.xml"))->init(); });
  EXPECT_NE(msg.find(dir / "arm.espm: packet at byte 5000 (t = 0.002 s): joint 2 'outer_pitch' = 1.2 rad is outside [-0.925, 0.925] rad"),
            std::string::npos) << msg;
  EXPECT_NE(msg.find("EspmDriver.filename"), std::string::npos) << msg;
}

TEST(EspmDriver, GarbageFileIsAnError) {
  TempDir dir("viscera_espm_driver");
  write(dir / "arm.espm", std::string(5000, 'x'));
  write(dir / "espm.xml", scene(R"(<EspmDriver name="arm" filename="arm.espm"/>)"));
  const std::string msg = errorOf([&] { viscera::buildScene(viscera::io::readScene(dir / "espm.xml"))->init(); });
  EXPECT_EQ(msg.rfind(dir / "arm.espm", 0), 0u) << msg;
  EXPECT_NE(msg.find("EspmDriver.filename"), std::string::npos) << msg;
}

}  // namespace
