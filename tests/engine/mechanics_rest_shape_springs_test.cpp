// RestShapeSpringsForceField against its definition: force -k (x - x0), K = -k I (checked by
// finite differences through addDForce), energy 1/2 k |x - x0|^2; and a block on springs settles
// where the springs carry its load.
#include <gtest/gtest.h>

#include "builtin/Builtins.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

namespace {

using namespace viscera;

const char* kScene = R"(<Node name="root" dt="0.01" gravity="0 0 0">
  <Node name="body">
    <EulerImplicitSolver rayleighStiffness="0" rayleighMass="1"/>
    <CGLinearSolver iterations="100" tolerance="1e-14" threshold="1e-30"/>
    <MechanicalObject name="dofs" position="0 0 0  1 0 0  0 1 0"/>
    <UniformMass totalMass="3"/>
    <RestShapeSpringsForceField name="springs" points="0 2" stiffness="10 20"/>
    <ConstantForceField indices="0 2" forces="0 0 -1  0 0 -2"/>
  </Node>
</Node>)";

TEST(RestShapeSprings, ForceStiffnessAndEnergyFollowTheDefinition) {
  auto scene = buildScene(io::parseSceneText(kScene, "springs.xml"));
  scene->init();
  ForceField* springs = nullptr;
  for (ForceField* f : scene->all<ForceField>())
    if (dynamic_cast<Component*>(f)->name() == "springs") springs = f;
  ASSERT_NE(springs, nullptr);
  Simulation sim(*scene);
  State& s = sim.state();
  Eigen::Matrix3Xd x = springs->mstate().x0;
  x.col(0) += Eigen::Vector3d(0.1, -0.2, 0.3);
  x.col(2) += Eigen::Vector3d(0.0, 0.5, 0.0);
  Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 3), v = Eigen::Matrix3Xd::Zero(3, 3);
  springs->addForce(s, x, v, f);
  EXPECT_TRUE(f.col(0).isApprox(-10 * Eigen::Vector3d(0.1, -0.2, 0.3)));
  EXPECT_TRUE(f.col(1).isZero());
  EXPECT_TRUE(f.col(2).isApprox(-20 * Eigen::Vector3d(0.0, 0.5, 0.0)));
  EXPECT_NEAR(springs->potentialEnergy(x), 0.5 * 10 * 0.14 + 0.5 * 20 * 0.25, 1e-12);
  // K dx against a central difference of the force.
  const Eigen::Matrix3Xd dx = Eigen::Matrix3Xd::Random(3, 3);
  Eigen::Matrix3Xd df = Eigen::Matrix3Xd::Zero(3, 3), fp = Eigen::Matrix3Xd::Zero(3, 3), fm = fp;
  springs->addDForce(s, dx, df, 1.0);
  const double h = 1e-6;
  springs->addForce(s, x + h * dx, v, fp);
  springs->addForce(s, x - h * dx, v, fm);
  EXPECT_LT((df - (fp - fm) / (2 * h)).cwiseAbs().maxCoeff(), 1e-8);
}

// Static equilibrium: each loaded node settles at x0 + F / k (damped implicit steps).
TEST(RestShapeSprings, LoadedNodesSettleWhereTheSpringsCarryTheLoad) {
  auto scene = buildScene(io::parseSceneText(kScene, "springs.xml"));
  Simulation sim(*scene);
  for (int i = 0; i < 3000; ++i) ASSERT_FALSE(sim.step());
  const MechanicalObject& m = *scene->all<MechanicalObject>().front();
  EXPECT_NEAR(m.x(sim.state())(2, 0), -1.0 / 10, 1e-6);
  EXPECT_NEAR(m.x(sim.state())(2, 2), -2.0 / 20, 1e-6);
}

}  // namespace
