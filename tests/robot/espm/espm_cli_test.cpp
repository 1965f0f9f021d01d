// `viscera espm synth` and `viscera espm decode`: a joint log through a synthesised capture and
// back, the CSV and JSON outputs, and bad input (exit code 2, the file or option named, nothing
// written).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "robot/espm/Capture.h"
#include "tests/apps/cli_helpers.h"

using namespace viscera_test;
namespace espm = viscera::robot::espm;

namespace {

// A log within the PSM limits: joint 1 ramps 0 -> 1 rad, the insertion 0.05 -> 0.2 m, over 0.5 s.
const char* kJoints =
    "t,q1,q2,q3,q4,q5,q6\n"
    "0,0,-0.5,0.05,2,0.1,-0.1\n"
    "0.5,1,0.5,0.2,-2,-0.1,0.1\n";

void write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::vector<std::string> fields(const std::string& line) {
  std::vector<std::string> f;
  std::string cur;
  for (char c : line) {
    if (c == ',') f.push_back(cur), cur.clear();
    else cur += c;
  }
  f.push_back(cur);
  return f;
}

// Column index of `name` in a CSV header line.
int column(const std::string& header, const std::string& name) {
  const auto f = fields(header);
  for (size_t i = 0; i < f.size(); ++i)
    if (f[i] == name) return static_cast<int>(i);
  return -1;
}

}  // namespace

TEST(EspmCli, SynthThenDecodeGivesTheJointsBack) {
  TempDir dir;
  write(dir / "joints.csv", kJoints);
  const RunResult synth = runViscera({"espm", "synth", "--joints", dir / "joints.csv", "--out", dir / "arm.bin", "--rate",
                                      "500", "--instrument-id", "0xCAFE"});
  ASSERT_EQ(synth.rc, 0) << synth;
  EXPECT_NE(synth.err.find("wrote 251 packets"), std::string::npos) << synth;  // 0, 2, ..., 500 ms
  // 500 packets/s at 2.5e6 bytes/s: one every 5000 bytes; the last one ends at 250 * 5000 + 134.
  EXPECT_EQ(std::filesystem::file_size(dir / "arm.bin"), 1'250'134u);

  const RunResult dec = runViscera({"espm", "decode", dir / "arm.bin", "--csv", dir / "arm.csv", "--json", dir / "arm.json"});
  ASSERT_EQ(dec.rc, 0) << dec;
  EXPECT_NE(dec.out.find("251 packets (dissertation framing) over 0.5 s"), std::string::npos) << dec;
  EXPECT_NE(dec.out.find("0 CRC failures"), std::string::npos) << dec;

  const auto rows = lines(slurp(dir / "arm.csv"));
  ASSERT_EQ(rows.size(), 252u);
  const std::string& header = rows[0];
  EXPECT_EQ(header.substr(0, 22), "t,offset,enc1,enc2,enc");
  const int q1 = column(header, "q1"), pot1 = column(header, "pot1"), id = column(header, "instrument_id");
  const int velA1 = column(header, "vel_a1"), overflow1 = column(header, "overflow1"), vel1 = column(header, "v1");
  ASSERT_GE(vel1, 0);
  ASSERT_GE(q1, 0);
  ASSERT_GE(pot1, 0);
  for (int k = 0; k <= 250; k += 25) {
    const auto f = fields(rows[1 + k]);
    const double t = k * 0.002;
    EXPECT_NEAR(std::stod(f[0]), t, 1e-12);
    EXPECT_EQ(f[1], std::to_string(5000 * k));
    // The log's joints at t by linear interpolation (s = t / 0.5), to half an encoder count:
    // 0.5e-5 rad, 0.5e-6 m for the insertion.
    const double s = t / 0.5;
    const double expected[6] = {s, -0.5 + s, 0.05 + 0.15 * s, 2 - 4 * s, 0.1 - 0.2 * s, -0.1 + 0.2 * s};
    for (int j = 0; j < 6; ++j)
      EXPECT_NEAR(std::stod(f[q1 + j]), expected[j], j == 2 ? 0.5e-6 + 1e-15 : 0.5e-5 + 1e-15) << "row " << k << " q" << j + 1;
    // Pot 1 spans the yaw limits [-1.588, 1.588] rad over 0..4095.
    EXPECT_EQ(std::stoi(f[pot1]), static_cast<int>(std::lround((s + 1.588) / 3.176 * 4095))) << k;
    EXPECT_EQ(f[id], "0x0000CAFE");
    EXPECT_EQ(f[overflow1], "0");
    // Velocities from the simulated encoders' Rev 6 quadlets. The joints move at constant speed:
    // 2 rad/s, 0.3 m/s and -8 rad/s for q1, q3, q4 (2e5, 3e5, 8e5 counts/s), so a full cycle of 4
    // counts takes 983, 655 and 246 ticks of 49.152 MHz; Rev 6 knows it to 17 ticks (low 4 bits
    // dropped, edges on ticks). The first packet has seen no full cycle yet: no measurement, 0.
    const double v1 = std::stod(f[vel1]), v3 = std::stod(f[vel1 + 2]), v4 = std::stod(f[vel1 + 3]);
    if (k == 0) {
      EXPECT_EQ(v1, 0.0);
      EXPECT_EQ(f[velA1], "0xBFFFFFFF");
    } else {
      EXPECT_NEAR(v1, 2.0, 2.0 * 17 / 983.04) << k;
      EXPECT_NEAR(v3, 0.3, 0.3 * 17 / 655.36) << k;
      EXPECT_NEAR(v4, -8.0, 8.0 * 17 / 245.76) << k;
    }
  }
  const std::string json = slurp(dir / "arm.json");
  EXPECT_NE(json.find("\"packets\": 251"), std::string::npos) << json;
  EXPECT_NE(json.find("\"framing\": \"dissertation\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"duration\": 0.5"), std::string::npos) << json;
}

TEST(EspmCli, PublicFramingAndCountsPerUnit) {
  TempDir dir;
  write(dir / "joints.csv", kJoints);
  ASSERT_EQ(runViscera({"espm", "synth", "--joints", dir / "joints.csv", "--out", dir / "pub.bin", "--framing", "public",
                        "--counts-per-unit", "1e4 1e4 1e5 1e4 1e4 1e4 1e4"})
                .rc,
            0);
  // Read with the library: public frames, the counts at the coarser scale (0.5 rad = 5000 counts
  // at t = 0.25 s, where joint 1 is halfway).
  const espm::Capture c = espm::readCapture(dir / "pub.bin");
  EXPECT_EQ(c.framing, espm::Framing::Public);
  ASSERT_EQ(c.samples.size(), 501u);
  EXPECT_EQ(c.samples[250].packet.encoders[0].count, 5000);
  EXPECT_EQ(c.samples[250].packet.encoders[2].count, 12500);  // 0.125 m * 1e5

  // Decoded with the same scale: the joint column is back in rad.
  const RunResult dec = runViscera({"espm", "decode", dir / "pub.bin", "--framing", "public", "--csv", dir / "pub.csv",
                                    "--counts-per-unit", "1e4 1e4 1e5 1e4 1e4 1e4 1e4"});
  ASSERT_EQ(dec.rc, 0) << dec;
  const auto rows = lines(slurp(dir / "pub.csv"));
  EXPECT_DOUBLE_EQ(std::stod(fields(rows[251])[column(rows[0], "q1")]), 0.5);
}

TEST(EspmCli, EncoderOverflowNeedsNoJoints) {
  TempDir dir;
  std::vector<espm::CaptureSample> samples(3);
  for (int k = 0; k < 3; ++k) samples[k].time = k * 1e-3;
  samples[2].packet.encoders[1].overflow = true;
  espm::writeCapture(dir / "ovf.bin", samples, {espm::Framing::Dissertation, 20e6});
  const RunResult r = runViscera({"espm", "decode", dir / "ovf.bin", "--csv", dir / "ovf.csv"});
  EXPECT_EQ(r.rc, 2) << r;
  EXPECT_NE(r.err.find("ovf.bin: packet at byte offset 5000 (t = 0.002 s): encoder 2 has its overflow bit set"),
            std::string::npos)
      << r;
  EXPECT_FALSE(std::filesystem::exists(dir / "ovf.csv"));
  const RunResult ok = runViscera({"espm", "decode", dir / "ovf.bin", "--csv", dir / "ovf.csv", "--no-joints"});
  ASSERT_EQ(ok.rc, 0) << ok;
  EXPECT_NE(ok.out.find("1 packets with an encoder overflow"), std::string::npos) << ok;
  const auto rows = lines(slurp(dir / "ovf.csv"));
  EXPECT_EQ(column(rows[0], "q1"), -1);
  EXPECT_EQ(fields(rows[3])[column(rows[0], "overflow2")], "1");
}

TEST(EspmCli, BadInputExitsWithTwoAndWritesNothing) {
  TempDir dir;
  write(dir / "joints.csv", kJoints);
  // Missing capture.
  RunResult r = runViscera({"espm", "decode", dir / "missing.bin", "--csv", dir / "out.csv"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find(dir / "missing.bin"), std::string::npos) << r;
  // Bytes that hold no packet.
  std::string noise(4000, '\0');
  for (size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<char>((i * 2654435761u) >> 13);
  write(dir / "noise.bin", noise);
  r = runViscera({"espm", "decode", dir / "noise.bin", "--csv", dir / "out.csv", "--framing", "dissertation"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find(dir / "noise.bin" + ": no valid ESPM packet"), std::string::npos) << r;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.csv"));
  // Options.
  r = runViscera({"espm", "decode", dir / "noise.bin", "--framing", "ieee1394"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--framing"), std::string::npos) << r;
  r = runViscera({"espm", "synth", "--joints", dir / "joints.csv", "--out", dir / "x.bin", "--rate", "20000"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--rate: 20000 packets/s do not fit"), std::string::npos) << r;
  r = runViscera({"espm", "synth", "--joints", dir / "joints.csv", "--out", dir / "x.bin", "--instrument-id", "12ab"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--instrument-id"), std::string::npos) << r;
  r = runViscera({"espm", "synth", "--joints", dir / "joints.csv", "--out", dir / "x.bin", "--framing", "auto"});
  EXPECT_EQ(r.rc, 2);
  // A joint outside the PSM limits: the CSV line is named.
  write(dir / "far.csv", "t,q1,q2,q3,q4,q5,q6\n0,0,0,0.1,0,0,0\n# a comment\n1,0,0,0.3,0,0,0\n");
  r = runViscera({"espm", "synth", "--joints", dir / "far.csv", "--out", dir / "x.bin"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find(dir / "far.csv" + ":4: joint 3 'outer_insertion' = 0.3 m is outside [0, 0.24] m"),
            std::string::npos)
      << r;
  // A missing joint log.
  r = runViscera({"espm", "synth", "--joints", dir / "nope.csv", "--out", dir / "x.bin"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find(dir / "nope.csv"), std::string::npos) << r;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.bin"));
}
