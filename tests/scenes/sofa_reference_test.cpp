// SOFA's own cantilever scenes (../shared/data/sofa-reference/beam_{large,small,polar}.scn), read
// unchanged and run for 100 steps, must reproduce SOFA's node positions (beam_*.100steps.vtk) to
// 2e-4; and the three methods must differ from each other by more than that, so that each match is
// a real check of its method.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

namespace fs = std::filesystem;
using namespace viscera;

namespace {

constexpr double kTol = 2e-4;
const std::array<std::string, 3> kMethods = {"large", "small", "polar"};

std::string refDir() { return std::string(VISCERA_SHARED_DIR) + "/data/sofa-reference/"; }

// The POINTS of a legacy ASCII VTK file, 3 x n.
Eigen::Matrix3Xd readVtkPoints(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::string tok;
  while (in >> tok && tok != "POINTS") {
  }
  if (tok != "POINTS") throw std::runtime_error(path + ": no POINTS");
  long n = 0;
  std::string type;
  in >> n >> type;
  if (!in || n <= 0) throw std::runtime_error(path + ": bad POINTS header");
  Eigen::Matrix3Xd p(3, n);
  for (long i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a)
      if (!(in >> p(a, i))) throw std::runtime_error(path + ": fewer than " + std::to_string(n) + " points");
  return p;
}

struct Result {
  Eigen::Matrix3Xd ours, sofa;
  std::vector<std::string> notes;
  std::string failure;
};

// Runs one method's scene, once per process (ctest runs each test in its own process).
Result runMethod(const std::string& method) {
  Result res;
  std::string t = (fs::temp_directory_path() / "viscera_sofa_XXXXXX").string();
  if (!::mkdtemp(t.data())) throw std::runtime_error("mkdtemp failed");
  try {
    res.sofa = readVtkPoints(refDir() + "beam_" + method + ".100steps.vtk");
    auto scene = buildScene(io::readScene(refDir() + "beam_" + method + ".scn"));
    scene->setOutputDirectory(t);
    res.notes = scene->notes();
    Simulation sim(*scene);
    for (int i = 0; i < 100 && res.failure.empty(); ++i)
      if (auto f = sim.step()) res.failure = f->str();
    sim.end();
    auto states = scene->all<MechanicalObject>();
    if (states.size() != 1) res.failure += " expected one MechanicalObject, got " + std::to_string(states.size());
    else res.ours = states[0]->x(sim.state());
  } catch (const std::exception& e) {
    res.failure = e.what();
  }
  std::error_code ec;
  fs::remove_all(t, ec);
  return res;
}

const Result& result(const std::string& method) {
  static std::map<std::string, Result> cache;
  auto it = cache.find(method);
  if (it == cache.end()) it = cache.emplace(method, runMethod(method)).first;
  return it->second;
}

double maxAbsDiff(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  if (a.cols() != b.cols()) return INFINITY;
  return (a - b).cwiseAbs().maxCoeff();
}

class SofaReference : public testing::TestWithParam<std::string> {};

TEST_P(SofaReference, MatchesSofaAfter100Steps) {
  const Result& r = result(GetParam());
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  ASSERT_EQ(r.sofa.cols(), 500);
  ASSERT_EQ(r.ours.cols(), 500);
  Eigen::Index worst = 0;
  const double d = (r.ours - r.sofa).cwiseAbs().colwise().maxCoeff().maxCoeff(&worst);
  EXPECT_LE(d, kTol) << "largest difference at node " << worst << ": ours " << r.ours.col(worst).transpose() << ", SOFA "
                     << r.sofa.col(worst).transpose();
  // The beam did bend (the reference is not the rest state).
  EXPECT_GT((r.sofa.col(499) - Eigen::Vector3d(5, 5, 40)).norm(), 1.0);
}

TEST_P(SofaReference, ReadsTheSofaSceneWithNotesOnly) {
  // RequiredPlugin, DefaultAnimationLoop, TetrahedronSetTopologyModifier and computeGlobalMatrix
  // are accepted with notes.
  const Result& r = result(GetParam());
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  std::string all;
  for (const auto& n : r.notes) all += n + "\n";
  EXPECT_NE(all.find("RequiredPlugin"), std::string::npos) << all;
  EXPECT_NE(all.find("DefaultAnimationLoop"), std::string::npos) << all;
  EXPECT_NE(all.find("computeGlobalMatrix"), std::string::npos) << all;
}

INSTANTIATE_TEST_SUITE_P(Beam, SofaReference, testing::ValuesIn(kMethods),
                         [](const testing::TestParamInfo<std::string>& i) { return i.param; });

TEST(SofaReferenceMethods, DifferFromEachOtherByMoreThanTheTolerance) {
  for (size_t a = 0; a < kMethods.size(); ++a)
    for (size_t b = a + 1; b < kMethods.size(); ++b) {
      const Result& ra = result(kMethods[a]);
      const Result& rb = result(kMethods[b]);
      SCOPED_TRACE(kMethods[a] + " vs " + kMethods[b]);
      // SOFA's own results differ, and so do ours ...
      EXPECT_GT(maxAbsDiff(ra.sofa, rb.sofa), 10 * kTol);
      ASSERT_TRUE(ra.failure.empty() && rb.failure.empty());
      EXPECT_GT(maxAbsDiff(ra.ours, rb.ours), 10 * kTol);
      // ... so our result for one method does not match SOFA's for another.
      EXPECT_GT(maxAbsDiff(ra.ours, rb.sofa), 10 * kTol);
      EXPECT_GT(maxAbsDiff(rb.ours, ra.sofa), 10 * kTol);
    }
}

}  // namespace
