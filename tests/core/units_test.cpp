// Units: parsing unit expressions, converting into a scene's unit system, and values with units in
// scenes (youngModulus="5 kPa" in a "mm g s" scene is the same as youngModulus="5000").
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

#include "builtin/Builtins.h"
#include "engine/Roles.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "core/Units.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// Relative comparison for converted values.
void expectClose(double got, double want) { EXPECT_NEAR(got, want, 1e-12 * std::abs(want)) << "got " << got << ", want " << want; }

double in(const char* system, double value, const char* unit, Dimension d) {
  return UnitSystem::parse(system).convert(value, parseUnit(unit), d);
}

std::string invalidArgument(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected std::invalid_argument, got: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected std::invalid_argument, nothing thrown";
  return "";
}

TEST(Units, ParseUnitSizesAndDimensions) {
  Unit kPa = parseUnit("kPa");
  expectClose(kPa.si, 1e3);
  EXPECT_EQ(kPa.dim, Dimension::pressure());

  Unit acc = parseUnit("mm/s^2");
  expectClose(acc.si, 1e-3);
  EXPECT_EQ(acc.dim, Dimension::acceleration());

  Unit rho = parseUnit("g/mm^3");
  expectClose(rho.si, 1e-3 / 1e-9);
  EXPECT_EQ(rho.dim, Dimension::density());

  Unit nm = parseUnit("N*m");
  expectClose(nm.si, 1.0);
  EXPECT_EQ(nm.dim, (Dimension{2, 1, -2}));

  Unit hz = parseUnit("1/s");
  expectClose(hz.si, 1.0);
  EXPECT_EQ(hz.dim, Dimension::frequency());

  Unit k = parseUnit("N/mm");
  expectClose(k.si, 1e3);
  EXPECT_EQ(k.dim, Dimension::stiffness());

  EXPECT_EQ(parseUnit("kg*m/s^2").dim, Dimension::force());
  EXPECT_EQ(parseUnit("m s^-1").dim, Dimension::velocity());
  expectClose(parseUnit("min").si, 60.0);
}

TEST(Units, ParseUnitRejectsUnknownAndMalformed) {
  EXPECT_NE(invalidArgument([] { parseUnit("furlong"); }).find("furlong"), std::string::npos);
  EXPECT_NE(invalidArgument([] { parseUnit("kPa/fortnight"); }).find("fortnight"), std::string::npos);
  invalidArgument([] { parseUnit(""); });
  invalidArgument([] { parseUnit("m^"); });
  invalidArgument([] { parseUnit("m^x"); });
}

TEST(Units, DimensionText) {
  EXPECT_EQ(Dimension::pressure().str(), "L^-1 M T^-2");
  EXPECT_EQ(Dimension::none().str(), "1");
  EXPECT_EQ(Dimension::length().str(), "L");
}

TEST(Units, ConversionsIntoMillimetreGramSecond) {
  expectClose(in("mm g s", 5, "kPa", Dimension::pressure()), 5000);
  expectClose(in("mm g s", 9.81, "m/s^2", Dimension::acceleration()), 9810);
  expectClose(in("mm g s", 1, "g/cm^3", Dimension::density()), 1e-3);   // g/mm^3
  expectClose(in("mm g s", 1000, "kg/m^3", Dimension::density()), 1e-3);  // the same density
  expectClose(in("mm g s", 1, "N", Dimension::force()), 1e6);            // g mm / s^2
  expectClose(in("mm g s", 0.1, "ms", Dimension::time()), 1e-4);
  expectClose(in("mm g s", 104.1, "g", Dimension::mass()), 104.1);
  expectClose(in("mm g s", 2, "cm", Dimension::length()), 20);
  expectClose(in("mm g s", 1, "N/m", Dimension::stiffness()), 1e3);  // g / s^2
}

TEST(Units, ConversionsIntoOtherSystems) {
  expectClose(in("m kg s", 5, "kPa", Dimension::pressure()), 5000);
  expectClose(in("cm g s", 5, "kPa", Dimension::pressure()), 50000);  // barye = 0.1 Pa
  expectClose(in("m kg s", 1, "g/cm^3", Dimension::density()), 1000);
  expectClose(in("m kg ms", 1, "N", Dimension::force()), 1e-6);
  // The default system is SI.
  UnitSystem si;
  EXPECT_EQ(si.str(), "m kg s");
  expectClose(si.convert(3, parseUnit("mm"), Dimension::length()), 3e-3);
  expectClose(UnitSystem::parse("mm g s").siOf(Dimension::pressure()), 1.0);
  EXPECT_EQ(UnitSystem::parse("mm g s").str(), "mm g s");
}

TEST(Units, IncompatibleUnitsThrow) {
  UnitSystem mm = UnitSystem::parse("mm g s");
  invalidArgument([&] { mm.convert(5, parseUnit("mm"), Dimension::pressure()); });
  invalidArgument([&] { mm.convert(1, parseUnit("N"), Dimension::mass()); });
  invalidArgument([&] { mm.convert(1, parseUnit("m/s"), Dimension::acceleration()); });
}

TEST(Units, UnitSystemRejectsBadSystems) {
  invalidArgument([] { UnitSystem::parse("mm s g"); });   // order is length mass time
  invalidArgument([] { UnitSystem::parse("mm g"); });
  invalidArgument([] { UnitSystem::parse("mm g s K"); });
  invalidArgument([] { UnitSystem::parse("mm g parsec"); });
  invalidArgument([] { UnitSystem::parse("kPa g s"); });
}

// A tiny cube scene in `units` with the given FEM and mass attributes.
std::string cubeScene(const std::string& units, const std::string& young, const std::string& extraRoot = "",
                      const std::string& mass = "totalMass=\"0.1\"") {
  return "<Node name=\"root\"" + (units.empty() ? std::string() : " units=\"" + units + "\"") + extraRoot +
         ">\n"
         "  <Node name=\"body\">\n"
         "    <EulerImplicitSolver rayleighStiffness=\"0.1\" rayleighMass=\"0.1\"/>\n"
         "    <CGLinearSolver iterations=\"100\" tolerance=\"1e-12\" threshold=\"1e-30\"/>\n"
         "    <RegularGridTopology name=\"grid\" n=\"3 3 3\" min=\"0 0 0\" max=\"10 10 10\"/>\n"
         "    <MechanicalObject name=\"dofs\"/>\n"
         "    <TetrahedronSetTopologyContainer name=\"tetra\"/>\n"
         "    <Hexa2TetraTopologicalMapping input=\"@grid\" output=\"@tetra\" swapping=\"true\"/>\n"
         "    <UniformMass " + mass + "/>\n"
         "    <TetrahedronFEMForceField name=\"fem\" youngModulus=\"" + young + "\" poissonRatio=\"0.4\"/>\n"
         "    <BoxROI name=\"clamp\" box=\"-1 -1 -1 11 11 0.1\"/>\n"
         "    <FixedConstraint indices=\"@clamp.indices\"/>\n"
         "  </Node>\n"
         "</Node>\n";
}

std::unique_ptr<Scene> build(const std::string& text) { return buildScene(io::parseSceneText(text, "units_test.xml")); }

double youngOf(const Scene& s) { return s.all<TetrahedronFEMForceField>().at(0)->attrs().reals("youngModulus").at(0); }

Eigen::Matrix3Xd runSteps(Scene& s, int n) {
  Simulation sim(s);
  for (int i = 0; i < n; ++i) {
    auto f = sim.step();
    EXPECT_FALSE(f) << f->str();
  }
  return s.all<MechanicalObject>().at(0)->x(sim.state());
}

TEST(Units, YoungModulusWithUnitEqualsPlainNumberInScene) {
  auto withUnit = build(cubeScene("mm g s", "5 kPa"));
  auto plain = build(cubeScene("mm g s", "5000"));
  expectClose(youngOf(*withUnit), 5000);
  expectClose(youngOf(*plain), 5000);
  // The same simulation, bit for bit.
  Eigen::Matrix3Xd a = runSteps(*withUnit, 10), b = runSteps(*plain, 10);
  EXPECT_EQ(a, b);
  EXPECT_GT((a - withUnit->all<MechanicalObject>().at(0)->x0).norm(), 0.0);  // it moved under gravity
  // And a different value does change it (the comparison above is not vacuous).
  auto stiffer = build(cubeScene("mm g s", "50 kPa"));
  EXPECT_GT((runSteps(*stiffer, 10) - a).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Units, ValuesWithUnitsInOtherSystems) {
  expectClose(youngOf(*build(cubeScene("cm g s", "5 kPa"))), 50000);
  expectClose(youngOf(*build(cubeScene("", "5 kPa"))), 5000);
  expectClose(youngOf(*build(cubeScene("", "5kPa"))), 5000);  // glued to the number
  expectClose(youngOf(*build(cubeScene("m kg s", "0.005 MPa"))), 5000);
}

TEST(Units, RootSettingsInSceneUnits) {
  // Default gravity is 9.81 m/s^2 expressed in the scene's units; dt may carry a unit.
  auto mm = build(cubeScene("mm g s", "5 kPa", " dt=\"0.1 ms\""));
  expectClose(mm->gravity().y(), -9810);
  EXPECT_EQ(mm->gravity().x(), 0);
  expectClose(mm->dt(), 1e-4);
  EXPECT_EQ(mm->units().str(), "mm g s");

  auto si = build(cubeScene("", "5000"));
  expectClose(si->gravity().y(), -9.81);
  expectClose(si->dt(), 0.01);

  auto g = build(cubeScene("mm g s", "5 kPa", " gravity=\"0 0 -9.81 m/s^2\""));
  expectClose(g->gravity().z(), -9810);

  // Masses: "104.1 g" is 104.1 in mm g s and 0.1041 in SI.
  auto m1 = build(cubeScene("mm g s", "5 kPa", "", "totalMass=\"104.1 g\""));
  auto m2 = build(cubeScene("", "5000", "", "totalMass=\"104.1 g\""));
  m1->init();
  m2->init();
  expectClose(m1->all<Mass>().at(0)->nodeMass().sum(), 104.1);
  expectClose(m2->all<Mass>().at(0)->nodeMass().sum(), 0.1041);
}

TEST(Units, SceneErrorsNameTheAttribute) {
  auto msg = [](const std::string& text) -> std::string {
    try {
      build(text);
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  };
  std::string e1 = msg(cubeScene("mm g s", "5 mm"));
  EXPECT_NE(e1.find("units_test.xml:10:"), std::string::npos) << e1;
  EXPECT_NE(e1.find("TetrahedronFEMForceField.youngModulus"), std::string::npos) << e1;
  std::string e2 = msg(cubeScene("mm g s", "5 psi"));
  EXPECT_NE(e2.find("psi"), std::string::npos) << e2;
  std::string e3 = msg(cubeScene("mm s g", "5000"));
  EXPECT_NE(e3.find("units_test.xml:1:"), std::string::npos) << e3;
  EXPECT_NE(e3.find("Node.units"), std::string::npos) << e3;
  // A unit on a dimensionless attribute.
  std::string text = cubeScene("mm g s", "5000");
  text.replace(text.find("poissonRatio=\"0.4\""), 18, "poissonRatio=\"0.4 kPa\"");
  std::string e4 = msg(text);
  EXPECT_NE(e4.find("TetrahedronFEMForceField.poissonRatio"), std::string::npos) << e4;
}

TEST(Units, GelPhantomSceneIsInKilopascals) {
  auto s = buildScene(io::readScene(std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml"));
  expectClose(youngOf(*s), 5000);
  expectClose(s->dt(), 1.0 / 150.0);
  EXPECT_EQ(s->units().str(), "mm g s");
}

}  // namespace
