// Fuzz target of the text tables: the input's first byte picks the reader (modulo 4: '0' a
// trajectory, '1' a joint log of six joints, '2' a transform, '3' a numeric CSV with columns t and
// x), the rest is the file's text. Bad input must end in viscera::Error, nothing else.
#include <cstdint>
#include <string>

#include "io/scene/CsvTable.h"
#include "io/scene/Transform.h"
#include "motion/Trajectory.h"
#include "robot/kinematics/JointTrajectory.h"
#include "tests/fuzz/FuzzInput.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  viscera_fuzz::expectOnlyInputErrors([&] {
    switch (data[0] % 4) {
      case 0: viscera::motion::parseTrajectoryCsv(text, "fuzz.csv"); break;
      case 1: viscera::robot::parseJointCsv(text, "fuzz.csv", 6); break;
      case 2: viscera::parseTransform(text, "fuzz.txt"); break;
      default: viscera::io::parseNumericCsv(text, "fuzz.csv", {"t", "x"}); break;
    }
  });
  return 0;
}
