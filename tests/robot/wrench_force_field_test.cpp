// WrenchForceField: a wrench log pushes the nodes where the instrument is, with the force turned
// into the scene frame and converted to the scene's units; free nodes gain exactly the momentum the
// force gives them (v = F t / m under implicit Euler, which has no error for a constant force).
#include <gtest/gtest.h>

#include <fstream>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/TempDir.h"

namespace viscera {
namespace {

using test_support::TempDir;

std::string scene(const std::string& wrench, const std::string& tool, const std::string& extra = "") {
  return R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <Node name="instrument">
    <MechanicalObject name="tool" template="Rigid3d" position=")" + tool + R"( 0 0 0 1"/>
  </Node>
  <Node name="body">
    <EulerImplicitSolver rayleighStiffness="0" rayleighMass="0"/>
    <CGLinearSolver iterations="100" tolerance="1e-14" threshold="1e-30"/>
    <MechanicalObject name="dofs" position="0 0 0  1 0 0  0 1 0"/>
    <UniformMass totalMass="3"/>
    <WrenchForceField filename=")" + wrench + R"(" instrument="@/instrument/tool" radius="0.5" rotation="0 0 90" )" + extra + R"(/>
  </Node>
</Node>)";
}

TEST(WrenchForceField, PushesTheNodesAtTheInstrumentInTheSceneFrame) {
  TempDir dir;
  std::ofstream(dir / "w.csv") << "t,Fx,Fy,Fz,Tx,Ty,Tz\n0,3,0,0,0,0,0\n10,3,0,0,0,0,0\n";
  // The instrument at node 0: all of the force on it. Robot x is scene y (rotation 90 deg about z).
  auto s = buildScene(io::parseSceneText(scene(dir / "w.csv", "0.1 0 0"), "wrench.xml"));
  Simulation sim(*s);
  for (int i = 0; i < 50; ++i) ASSERT_FALSE(sim.step());
  const MechanicalObject& m = *s->all<MechanicalObject>().back();
  const Eigen::Matrix3Xd& v = m.v(sim.state());
  EXPECT_NEAR(v(1, 0), 3.0 * 0.5 / 1.0, 1e-9);  // F t / m with m = 1 kg per node
  EXPECT_NEAR(v(0, 0), 0, 1e-12);
  EXPECT_NEAR(v.col(1).norm() + v.col(2).norm(), 0, 1e-12);
}

TEST(WrenchForceField, FallsBackToTheNearestNodeAndFollowsTheLogInTime) {
  TempDir dir;
  // 0 N at t = 0 rising to 2 N at t = 1 s: the impulse over the first second is 1 N s.
  std::ofstream(dir / "w.csv") << "0,0,0,0,0,0,0\n1,2,0,0,0,0,0\n";
  auto s = buildScene(io::parseSceneText(scene(dir / "w.csv", "0 5 0"), "wrench.xml"));  // far from all, nearest node 2
  Simulation sim(*s);
  for (int i = 0; i < 100; ++i) ASSERT_FALSE(sim.step());
  const Eigen::Matrix3Xd& v = s->all<MechanicalObject>().back()->v(sim.state());
  // Each step applies the force at its end time (implicit Euler): sum of 2 * t_k * 0.01 for
  // t_k = 0.01..1, i.e. 1.01 N s.
  EXPECT_NEAR(v(1, 2), 1.01, 1e-9);
  EXPECT_NEAR(v.col(0).norm() + v.col(1).norm(), 0, 1e-12);
}

TEST(WrenchForceField, ABadLogNamesItsLine) {
  TempDir dir;
  std::ofstream(dir / "w.csv") << "0,0,0,0,0,0,0\n1,2,0,nan,0,0,0\n";
  try {
    auto s = buildScene(io::parseSceneText(scene(dir / "w.csv", "0 0 0"), "wrench.xml"));
    s->init();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("w.csv:2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace viscera
