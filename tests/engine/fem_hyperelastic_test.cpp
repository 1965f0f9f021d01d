// Hyperelastic tetrahedra, checked against answers not computed by the code under test:
// - each law: S = 2 dW/dC and dS/dC : H against central finite differences of W and S, at a
//   random finite strain (relative 1e-6: the differences' truncation and round-off are ~1e-9);
// - the force field on a random deformed mesh: f = -dE/dx and the tangent = df/dx by finite
//   differences (relative 1e-6);
// - a free cube stretched uniformly: the Cauchy stress of Neo-Hookean and Saint Venant-Kirchhoff
//   against the closed forms, through the nodal forces on one face;
// - every law is stress-free at rest.
// SOFA's own numbers for all six laws are checked by its regression scene in the suite test.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "builtin/Builtins.h"
#include "core/Error.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/fem/HyperelasticMaterials.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "solvers/linear/BlockSparseMatrix.h"

using namespace viscera;

namespace {

std::vector<double> parametersOf(const std::string& law) {
  if (law == "MooneyRivlin") return {5000, 7000, 10};
  if (law == "Ogden") return {1500, 3.5, 5000};
  if (law == "ArrudaBoyce") return {3448.2759, 31034.483};
  return {3448.2759, 31034.483};
}

Eigen::Matrix3d symmetricUnit(int i, int j) {
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  E(i, j) += 0.5;
  E(j, i) += 0.5;
  return E;
}

class Laws : public ::testing::TestWithParam<const char*> {};

TEST_P(Laws, StressIsTheEnergyGradientAndItsDerivativeExact) {
  const std::string law = GetParam();
  const auto m = fem::makeHyperelasticMaterial(law, parametersOf(law));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  for (int i = 0; i < 9; ++i) F.data()[i] += u(rng);
  const Eigen::Matrix3d C = F.transpose() * F;
  auto J = [](const Eigen::Matrix3d& c) { return std::sqrt(c.determinant()); };
  const Eigen::Matrix3d S = m->stress(C, J(C));
  const double h = 1e-6;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) {
      const Eigen::Matrix3d E = symmetricUnit(i, j);
      const Eigen::Matrix3d Cp = C + h * E, Cm = C - h * E;
      // W(C + h E) - W(C - h E) = 2 h dW/dC : E = h S : E; S : E = S_ij for a symmetric S.
      const double fd = (m->energy(Cp, J(Cp)) - m->energy(Cm, J(Cm))) / h;
      EXPECT_NEAR(S(i, j), fd, 1e-6 * S.norm() + 1e-9) << law << " S(" << i << "," << j << ")";
      const Eigen::Matrix3d dS = m->stressDerivative(C, J(C), E);
      const Eigen::Matrix3d fdS = (m->stress(Cp, J(Cp)) - m->stress(Cm, J(Cm))) / (2 * h);
      EXPECT_LT((dS - fdS).norm(), 1e-6 * fdS.norm() + 1e-6) << law << " dS along (" << i << "," << j << ")";
    }
  EXPECT_LT(m->stress(Eigen::Matrix3d::Identity(), 1.0).norm(), 1e-9) << law << " is not stress-free at rest";
}

INSTANTIATE_TEST_SUITE_P(Hyperelastic, Laws,
                         ::testing::Values("ArrudaBoyce", "StVenantKirchhoff", "NeoHookean", "MooneyRivlin", "Ogden",
                                           "StableNeoHookean"));

std::unique_ptr<Scene> block(const std::string& law) {
  std::string p;
  for (double v : parametersOf(law)) p += (p.empty() ? "" : " ") + std::to_string(v);
  auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0">
    <StaticSolver/>
    <RegularGridTopology name="grid" n="3 2 2" min="0 0 0" max="2 1 1"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronSetTopologyContainer name="tetra"/>
    <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
    <TetrahedronHyperelasticityFEMForceField name="fem" materialName=")" + law + R"(" ParameterSet=")" + p + R"("/>
  </Node>)", "hyper.xml"));
  scene->init();
  return scene;
}

ForceField& fem(Scene& s) {
  for (ForceField* f : s.all<ForceField>())
    if (dynamic_cast<Component*>(f)->name() == "fem") return *f;
  throw std::runtime_error("no fem");
}

class Field : public ::testing::TestWithParam<const char*> {};

TEST_P(Field, ForceIsMinusTheEnergyGradientAndTheTangentItsDerivative) {
  const std::string law = GetParam();
  auto scene = block(law);
  Simulation sim(*scene);
  const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
  ForceField& ff = fem(*scene);
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  Eigen::Matrix3Xd x = mo.x0;
  for (int i = 0; i < x.cols(); ++i) x.col(i) += 0.05 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
  const Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, x.cols());
  State& st = sim.state();
  Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, x.cols());
  ff.addForce(st, x, v, f);
  const double h = 1e-6;
  // f = -dE/dx.
  for (int i = 0; i < x.cols(); ++i)
    for (int a = 0; a < 3; ++a) {
      Eigen::Matrix3Xd xp = x, xm = x;
      xp(a, i) += h;
      xm(a, i) -= h;
      const double g = -(ff.potentialEnergy(xp) - ff.potentialEnergy(xm)) / (2 * h);
      EXPECT_NEAR(f(a, i), g, 1e-6 * f.norm()) << law << " node " << i << " axis " << a;
    }
  // K dx (matrix-free and assembled) = the change of f along dx.
  Eigen::Matrix3Xd dx(3, x.cols());
  for (int i = 0; i < dx.cols(); ++i) dx.col(i) = Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
  Eigen::Matrix3Xd Kdx = Eigen::Matrix3Xd::Zero(3, x.cols());
  ff.addDForce(st, dx, Kdx, 1.0);
  State scratch = sim.captureState();
  Eigen::Matrix3Xd fp = Eigen::Matrix3Xd::Zero(3, x.cols()), fm = fp;
  ff.addForce(scratch, x + h * dx, v, fp);
  ff.addForce(scratch, x - h * dx, v, fm);
  const Eigen::Matrix3Xd fd = (fp - fm) / (2 * h);
  EXPECT_LT((Kdx - fd).norm(), 1e-6 * fd.norm()) << law;
  std::vector<std::pair<int, int>> pairs;
  ff.stiffnessPattern(pairs);
  BlockSparseMatrix K;
  K.setPattern(static_cast<int>(x.cols()), pairs);
  K.setZero();
  ff.addStiffness(st, K, 1.0);
  Eigen::VectorXd assembled(3 * x.cols());
  K.multiply(Eigen::Map<const Eigen::VectorXd>(dx.data(), dx.size()), assembled);
  EXPECT_LT((Eigen::Map<const Eigen::VectorXd>(Kdx.data(), Kdx.size()) - assembled).norm(), 1e-9 * fd.norm()) << law;
}

INSTANTIATE_TEST_SUITE_P(Hyperelastic, Field,
                         ::testing::Values("ArrudaBoyce", "StVenantKirchhoff", "NeoHookean", "MooneyRivlin", "Ogden",
                                           "StableNeoHookean"));

// A cube stretched to F = diag(s, t, t): the force on its x = 1 face sums to the first
// Piola-Kirchhoff traction P_xx times the face's rest area (1), with P = F S. Neo-Hookean:
// S_xx = mu (1 - 1/s^2) + lambda ln(J) / s^2; Saint Venant-Kirchhoff: S_xx = mu (s^2 - 1) +
// lambda/2 (s^2 + 2 t^2 - 3), both with J = s t^2.
TEST(HyperelasticField, UniformStretchGivesTheClosedFormTraction) {
  const double s = 1.3, t = 0.9, mu = 3000, lambda = 20000;
  for (const std::string law : {"NeoHookean", "StVenantKirchhoff"}) {
    auto scene = buildScene(io::parseSceneText(R"(<Node name="root" gravity="0 0 0">
      <RegularGridTopology name="grid" n="3 3 3" min="0 0 0" max="1 1 1"/>
      <MechanicalObject name="dofs"/>
      <TetrahedronSetTopologyContainer name="tetra"/>
      <Hexa2TetraTopologicalMapping input="@grid" output="@tetra" swapping="true"/>
      <TetrahedronHyperelasticityFEMForceField name="fem" materialName=")" + law + R"(" ParameterSet="3000 20000"/>
    </Node>)", "stretch.xml"));
    scene->init();
    const MechanicalObject& mo = *scene->all<MechanicalObject>().front();
    Eigen::Matrix3Xd x = mo.x0;
    x.row(0) *= s;
    x.row(1) *= t;
    x.row(2) *= t;
    Simulation sim(*scene);
    State& st = sim.state();
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, x.cols());
    fem(*scene).addForce(st, x, Eigen::Matrix3Xd::Zero(3, x.cols()), f);
    const double J = s * t * t;
    const double Sxx = law == "NeoHookean" ? mu * (1 - 1 / (s * s)) + lambda * std::log(J) / (s * s)
                                           : mu * (s * s - 1) + lambda / 2 * (s * s + 2 * t * t - 3);
    double face = 0;
    for (int i = 0; i < x.cols(); ++i)
      if (mo.x0(0, i) == 1.0) face += f(0, i);
    // The internal force on the face balances the traction: f = -P_xx A.
    EXPECT_NEAR(-face, s * Sxx, 1e-9 * std::abs(s * Sxx)) << law;
    // Uniform strain: interior nodes feel no net force.
    for (int i = 0; i < x.cols(); ++i)
      if ((mo.x0.col(i).array() > 0).all() && (mo.x0.col(i).array() < 1).all())
        EXPECT_LT(f.col(i).norm(), 1e-9 * std::abs(s * Sxx)) << law << " interior node " << i;
  }
}

TEST(HyperelasticField, BadParametersAreNamed) {
  try {
    block("MooneyRivlin");
  } catch (const Error& e) {
    FAIL() << e.what();
  }
  auto errorOf = [](const std::string& attrs) {
    try {
      auto scene = buildScene(io::parseSceneText(R"(<Node name="root"><RegularGridTopology name="grid" n="2 2 2"/>
        <MechanicalObject/><TetrahedronSetTopologyContainer name="tetra"/>
        <Hexa2TetraTopologicalMapping input="@grid" output="@tetra"/>
        <TetrahedronHyperelasticityFEMForceField )" + attrs + "/></Node>", "bad.xml"));
      scene->init();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(errorOf(R"(materialName="MooneyRivlin" ParameterSet="1 2")")
                .find("ParameterSet: MooneyRivlin takes 3 parameters (c1 c2 k0), got 2"),
            std::string::npos);
  EXPECT_NE(errorOf(R"(materialName="Costa" ParameterSet="1 2")").find("materialName"), std::string::npos);
}

}  // namespace
