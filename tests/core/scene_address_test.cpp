// Addressing elements and attributes of a scene description ("phantom/fem.youngModulus"): unique,
// anchored and suffix paths, ambiguous and missing addresses listing the candidates, and values
// set by address checked at build with messages naming the address.
#include <gtest/gtest.h>

#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "core/SceneDesc.h"
#include "engine/fem/TetrahedronFEMForceField.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"

using namespace viscera;
using viscera::test_support::errorOf;

namespace {

const char* kTwoBodies = R"(<Node name="root" dt="0.01">
  <Node name="left">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <RegularGridTopology name="grid" n="2 2 2" min="0 0 0" max="1 1 1"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField name="fem" youngModulus="1000" poissonRatio="0.3"/>
  </Node>
  <Node name="right">
    <EulerImplicitSolver/>
    <CGLinearSolver iterations="10"/>
    <RegularGridTopology name="grid" n="2 2 2" min="2 0 0" max="3 1 1"/>
    <MechanicalObject name="dofs"/>
    <UniformMass totalMass="1"/>
    <TetrahedronFEMForceField name="fem" youngModulus="1000" poissonRatio="0.3"/>
    <Node name="inner"><MechanicalObject name="probe" position="0 0 0"/></Node>
  </Node>
</Node>)";

TEST(SceneAddress, PathsNameOneElement) {
  SceneDesc d = io::parseSceneText(kTwoBodies, "two.xml");
  EXPECT_EQ(d.element("left/fem").find("youngModulus")->value, "1000");
  EXPECT_EQ(&d.element("right/fem"), &d.element("/right/fem"));
  EXPECT_EQ(&d.element("right/fem"), &d.element("/root/right/fem"));
  EXPECT_EQ(&d.element("probe"), &d.element("right/inner/probe"));
  EXPECT_EQ(d.element("inner").tag, "Node");
  EXPECT_EQ(&d.element("/"), &d.root);
  // Unnamed components are addressed by their tag.
  EXPECT_EQ(d.element("left/UniformMass").find("totalMass")->value, "1");
  // Set and get.
  d.set("right/fem.youngModulus", "3.2 kPa");
  EXPECT_EQ(d.get("right/fem.youngModulus")->value, "3.2 kPa");
  EXPECT_EQ(d.get("left/fem.youngModulus")->value, "1000");
  EXPECT_EQ(d.get("left/fem.method"), nullptr);  // not written: the default applies
  auto scene = buildScene(d);
  scene->init();
  auto fems = scene->all<TetrahedronFEMForceField>();
  ASSERT_EQ(fems.size(), 2u);
  EXPECT_DOUBLE_EQ(fems[0]->attrs().real("youngModulus"), 1000);
  EXPECT_DOUBLE_EQ(fems[1]->attrs().real("youngModulus"), 3200);  // kPa in SI (m kg s)
}

TEST(SceneAddress, AmbiguousAndMissingAddressesListTheCandidates) {
  SceneDesc d = io::parseSceneText(kTwoBodies, "two.xml");
  std::string e = errorOf([&] { d.set("fem.youngModulus", "1"); });
  EXPECT_NE(e.find("'fem' is ambiguous"), std::string::npos) << e;
  EXPECT_NE(e.find("/left/fem (TetrahedronFEMForceField)"), std::string::npos) << e;
  EXPECT_NE(e.find("/right/fem (TetrahedronFEMForceField)"), std::string::npos) << e;
  e = errorOf([&] { d.set("middle/fem.youngModulus", "1"); });
  EXPECT_NE(e.find("no element 'middle/fem'"), std::string::npos) << e;
  EXPECT_NE(e.find("/left/fem"), std::string::npos) << e;
  e = errorOf([&] { d.set("nothing.youngModulus", "1"); });
  EXPECT_NE(e.find("no element 'nothing'"), std::string::npos) << e;
  EXPECT_NE(e.find("/right/inner/probe"), std::string::npos) << e;  // every element, when no name is close
  e = errorOf([&] { d.set("left/fem", "1"); });
  EXPECT_NE(e.find("names no attribute"), std::string::npos) << e;
}

TEST(SceneAddress, ValuesSetByAddressAreCheckedAtBuildAndNameTheAddress) {
  SceneDesc d = io::parseSceneText(kTwoBodies, "two.xml");
  d.applySetting("left/fem.youngModulus=3 kPaa");
  std::string e = errorOf([&] { buildScene(d); });
  EXPECT_EQ(e.rfind("--set left/fem.youngModulus: TetrahedronFEMForceField.youngModulus:", 0), 0u) << e;

  SceneDesc u = io::parseSceneText(kTwoBodies, "two.xml");
  u.applySetting("left/fem.youngModulous=3 kPa");
  e = errorOf([&] { buildScene(u); });
  EXPECT_NE(e.find("--set left/fem.youngModulous"), std::string::npos) << e;
  EXPECT_NE(e.find("unknown attribute"), std::string::npos) << e;
  EXPECT_NE(e.find("youngModulus"), std::string::npos) << e;  // the candidates

  SceneDesc n = io::parseSceneText(kTwoBodies, "two.xml");
  e = errorOf([&] { n.applySetting("left/fem.youngModulus"); });
  EXPECT_NE(e.find("write ADDRESS=VALUE"), std::string::npos) << e;
  e = errorOf([&] { n.applySetting("fem.youngModulus=2"); });
  EXPECT_EQ(e.rfind("--set fem.youngModulus:", 0), 0u) << e;
  EXPECT_NE(e.find("ambiguous"), std::string::npos) << e;
}

}  // namespace
