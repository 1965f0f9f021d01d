// Every force field of a scene: force = -dE/dx by central finite differences of the potential
// energy, on a random state (SOFA's ForceField test, applied to the whole system).
#include <gtest/gtest.h>

#include <random>

#include "builtin/Builtins.h"
#include "engine/MechanicalSystem.h"
#include "engine/Simulation.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

std::unique_ptr<Scene> buildScene(const std::string& method) {
  const std::string xml = R"(
<Node name="root" dt="0.01" gravity="1 -9.81 2">
  <Node name="body">
    <StaticSolver name="solver"/>
    <RegularGridTopology name="grid" n="3 3 4" min="0 0 0" max="1 1 2"/>
    <MechanicalObject name="dofs"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
    <DiagonalMass massDensity="3"/>
    <TetrahedronFEMForceField name="fem" youngModulus="100" poissonRatio="0.3" method=")" + method + R"("/>
    <ConstantForceField indices="0 5 7" forces="1 2 3  -1 0 4  0.5 0.5 0.5"/>
  </Node>
</Node>)";
  auto scene = buildScene(io::parseSceneText(xml, "energy.xml"));
  scene->init();
  return scene;
}

// Checks every force field separately so a failure names the culprit.
void checkConservative(const std::string& method, double relTol) {
  auto scene = buildScene(method);
  auto* mo = scene->all<MechanicalObject>()[0];
  Simulation sim(*scene);
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  Eigen::Matrix3Xd x = mo->x0;
  // A small random deformation: the corotational forces are conservative only to first order.
  for (int i = 0; i < x.cols(); ++i) x.col(i) += 1e-4 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
  const Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, x.cols());
  std::vector<ForceField*> fields = scene->all<ForceField>();
  ASSERT_EQ(fields.size(), 3u);  // mass (gravity), FEM, constant force
  for (ForceField* ff : fields) {
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, x.cols());
    ff->addForce(sim.state(), x, v, f);
    Eigen::Matrix3Xd g(3, x.cols());
    const double h = 1e-7;
    for (int i = 0; i < x.cols(); ++i)
      for (int a = 0; a < 3; ++a) {
        Eigen::Matrix3Xd xp = x, xm = x;
        xp(a, i) += h;
        xm(a, i) -= h;
        g(a, i) = -(ff->potentialEnergy(xp) - ff->potentialEnergy(xm)) / (2 * h);
      }
    EXPECT_LE((f - g).norm(), relTol * f.norm() + 1e-9)
        << dynamic_cast<Component*>(ff)->typeName() << " (" << method << "): |f| = " << f.norm();
  }
}

}  // namespace

// Gravity and constant forces are exactly conservative; small strain FEM too. The tolerance
// covers the finite-difference error (h = 1e-7 on energies of order 1).
TEST(ForceFieldEnergy, SmallIsConservative) { checkConservative("small", 1e-5); }

// SOFA's corotational forces differ from -dE/dx by terms of the order of the strain (1e-4
// here): the tolerance is a few times the strain.
TEST(ForceFieldEnergy, LargeIsConservativeToFirstOrder) { checkConservative("large", 1e-3); }
TEST(ForceFieldEnergy, PolarIsConservativeToFirstOrder) { checkConservative("polar", 1e-3); }
