// Trilinear hexahedra (HexahedronFEMForceField, SOFA's element force fields on hexahedra) and the
// FEM mass: the patch test of uniaxial stress, rigid motions that must give no force, and the
// consistent mass of a box against its closed form. SOFA's own cantilever results are compared in
// tests/study/sofa_suite_test.cpp.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// One unit cube (a 2 x 2 x 2 grid) with `body` in its node.
std::unique_ptr<Scene> cube(const std::string& body) {
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0">
  <RegularGridTopology name="grid" n="2 2 2" min="0 0 0" max="1 1 1"/>
  <MechanicalObject name="dofs"/>
  )" + body + R"(
</Node>)",
                                             "hexa.xml"));
  scene->init();
  return scene;
}

ForceField& forceField(Scene& s) {
  for (auto* f : s.all<ForceField>())
    if (dynamic_cast<Component*>(f)->typeName() != "UniformMass") return *f;
  throw std::runtime_error("no force field");
}

const std::vector<std::string> kFields = {
    R"(<HexahedronFEMForceField youngModulus="1000" poissonRatio="0" method="small"/>)",
    R"(<HexahedronFEMForceField youngModulus="1000" poissonRatio="0" method="large"/>)",
    R"(<HexahedronFEMForceField youngModulus="1000" poissonRatio="0" method="polar"/>)",
    R"(<LinearSmallStrainFEMForceField template="Vec3,Hexahedron" youngModulus="1000" poissonRatio="0"/>)",
    R"(<CorotationalFEMForceField template="Vec3,Hexahedron" youngModulus="1000" poissonRatio="0"/>)",
};

}  // namespace

TEST(HexahedronFEM, UniaxialStretchGivesTheExactTractionOnEachFace) {
  // u_x = eps x with nu = 0 is a state of uniaxial stress sigma_xx = E eps: the nodal forces on
  // the face x = 1 sum to -E eps (area 1), those on x = 0 to +E eps, and nothing acts sideways.
  // Trilinear elements represent a linear field exactly, so this holds to round-off.
  const double E = 1000, eps = 1e-3;
  for (const auto& field : kFields) {
    auto scene = cube(field);
    Simulation sim(*scene);
    ForceField& ff = forceField(*scene);
    const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
    Eigen::Matrix3Xd x = mo.x0;
    x.row(0) *= 1 + eps;
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 8);
    ff.addForce(sim.state(), x, Eigen::Matrix3Xd::Zero(3, 8), f);
    double right = 0, left = 0;
    for (int i = 0; i < 8; ++i) (mo.x0(0, i) > 0.5 ? right : left) += f(0, i);
    EXPECT_NEAR(right, -E * eps, 1e-9) << field;
    EXPECT_NEAR(left, E * eps, 1e-9) << field;
    EXPECT_LT(f.bottomRows(2).cwiseAbs().maxCoeff(), 1e-9) << field;
    // Each corner node of a face carries a quarter.
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(std::abs(f(0, i)), E * eps / 4, 1e-9) << field;
  }
}

TEST(HexahedronFEM, RigidMotionsGiveNoForceInTheCorotationalMethods) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (size_t k = 1; k < kFields.size(); ++k) {
    if (k == 3) continue;  // the small-strain field is not invariant to finite rotations
    auto scene = cube(kFields[k]);
    Simulation sim(*scene);
    ForceField& ff = forceField(*scene);
    const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
    Eigen::Matrix3Xd x = (R * mo.x0).colwise() + Eigen::Vector3d(5, -2, 1);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 8);
    ff.addForce(sim.state(), x, Eigen::Matrix3Xd::Zero(3, 8), f);
    EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-10) << kFields[k];
  }
  // Translations give no force in any method.
  for (const auto& field : kFields) {
    auto scene = cube(field);
    Simulation sim(*scene);
    const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 8);
    forceField(*scene).addForce(sim.state(), mo.x0.colwise() + Eigen::Vector3d(1, 2, 3), Eigen::Matrix3Xd::Zero(3, 8), f);
    EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-10) << field;
  }
}

TEST(HexahedronFEM, StiffnessIsTheDerivativeOfTheForceForSmallStrain) {
  // Finite differences of the linear field's force against addDForce (exact for a linear field).
  auto scene = cube(kFields[0]);
  Simulation sim(*scene);
  State& s = sim.state();
  ForceField& ff = forceField(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  const Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, 8);
  Eigen::Matrix3Xd f0 = v, f1 = v, df = v;
  ff.addForce(s, mo.x0, v, f0);
  const Eigen::Matrix3Xd dx = Eigen::Matrix3Xd::Random(3, 8) * 1e-3;
  ff.addForce(s, mo.x0 + dx, v, f1);
  ff.addDForce(s, dx, df, 1.0);
  EXPECT_LT((f1 - f0 - df).cwiseAbs().maxCoeff(), 1e-10);
}

TEST(FEMMass, IsTheConsistentMassOfATrilinearBox) {
  // On a box the trilinear mass matrix is a tensor product of the 1-D one (rho L / 6 [2 1; 1 2]):
  // M_ij = rho V / 216 prod_k (2 if nodes i and j share coordinate k, else 1).
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root">
  <RegularGridTopology name="grid" n="2 2 2" min="0 0 0" max="2 1 3"/>
  <MechanicalObject name="dofs"/>
  <NodalMassDensity property="5"/>
  <FEMMass template="Vec3,Hexahedron"/>
</Node>)",
                                             "mass.xml"));
  scene->init();
  const Mass& mass = *scene->all<Mass>().front();
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  ASSERT_TRUE(mass.consistent());
  const double rhoV = 5 * 6;
  for (int j = 0; j < 8; ++j) {
    Eigen::Matrix3Xd dx = Eigen::Matrix3Xd::Zero(3, 8), out = dx;
    dx(1, j) = 1;
    mass.addMdx(dx, out, 1.0);
    for (int i = 0; i < 8; ++i) {
      double expected = rhoV / 216;
      for (int k = 0; k < 3; ++k) expected *= mo.x0(k, i) == mo.x0(k, j) ? 2 : 1;
      EXPECT_NEAR(out(1, i), expected, 1e-12) << i << " " << j;
    }
    EXPECT_NEAR(mass.nodeMass()[j], rhoV / 8, 1e-12);
  }
}
