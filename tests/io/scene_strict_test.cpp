// A strict scene reader: what used to be silently ignored or misread is an error with file:line
// (text outside elements, a second root, deep nesting, hexadecimal numbers, a name given twice in
// one node, two ODE solvers integrating one node twice).
#include <gtest/gtest.h>

#include <string>

#include "builtin/Builtins.h"
#include "engine/Simulation.h"
#include "io/scene/SceneReader.h"
#include "tests/support/ErrorOf.h"

using namespace viscera;
using viscera::test_support::errorOf;

namespace {

// Reading, building and initialising `text`; the message of the first error, or "".
std::string problemOf(const std::string& text) {
  return errorOf([&] {
    auto scene = buildScene(io::parseSceneText(text, "strict.xml"));
    Simulation sim(*scene);
  });
}

const std::string kBody = R"(
  <Node name="body">
    <EulerImplicitSolver name="ode"/>
    <CGLinearSolver iterations="10"/>
    <MechanicalObject name="dofs" position="0 0 0"/>
    <UniformMass totalMass="1"/>
  </Node>)";

TEST(SceneStrict, TheControlSceneIsFine) { EXPECT_EQ(problemOf("<Node name=\"root\">" + kBody + "</Node>"), ""); }

TEST(SceneStrict, TextOutsideElementsIsAnError) {
  // A lost '<' turns an element into text.
  std::string e = problemOf("<Node name=\"root\">\n  FixedConstraint indices=\"0\"/>" + kBody + "</Node>");
  EXPECT_EQ(e.rfind("strict.xml:1:", 0), 0u) << e;
  EXPECT_NE(e.find("is a '<' missing?"), std::string::npos) << e;
  e = problemOf("<Node name=\"root\">" + kBody + "</Node>\ntrailing words");
  EXPECT_NE(e.find("outside the root element"), std::string::npos) << e;
  e = problemOf("<Node name=\"root\">" + kBody + "</Node>\n<Node name=\"again\"/>");
  EXPECT_NE(e.find("a second root element <Node>"), std::string::npos) << e;
  EXPECT_EQ(e.rfind("strict.xml:8:", 0), 0u) << e;
}

TEST(SceneStrict, DeepNestingIsRefusedNotFollowed) {
  std::string text;
  for (int i = 0; i < 10000; ++i) text += "<Node>";
  for (int i = 0; i < 10000; ++i) text += "</Node>";
  const std::string e = problemOf(text);
  EXPECT_NE(e.find("nested more than 256 deep"), std::string::npos) << e.substr(0, 200);
}

TEST(SceneStrict, HexadecimalIsNotANumber) {
  std::string text = "<Node name=\"root\">" + kBody + "</Node>";
  text.replace(text.find("<EulerImplicitSolver name=\"ode\"/>"), 33, "<EulerImplicitSolver name=\"ode\" rayleighStiffness=\"0x1F\"/>");
  const std::string e = problemOf(text);
  EXPECT_NE(e.find("EulerImplicitSolver.rayleighStiffness"), std::string::npos) << e;
  EXPECT_NE(e.find("hexadecimal"), std::string::npos) << e;
}

TEST(SceneStrict, ANameGivenTwiceInOneNode) {
  std::string text = "<Node name=\"root\">" + kBody + "</Node>";
  text.replace(text.find("<UniformMass"), 12, "<BoxROI name=\"dofs\" box=\"0 0 0 1 1 1\"/><UniformMass");
  const std::string e = problemOf(text);
  EXPECT_NE(e.find("BoxROI.name: 'dofs' is already the name of the <MechanicalObject> at strict.xml:5"), std::string::npos) << e;
  // The same name in two nodes is fine.
  std::string two = "<Node name=\"root\">" + kBody + kBody + "</Node>";
  two.replace(two.rfind("name=\"body\""), 11, "name=\"other\"");
  EXPECT_EQ(problemOf(two), "");
}

TEST(SceneStrict, TwoOdeSolversInOneNode) {
  std::string text = "<Node name=\"root\">" + kBody + "</Node>";
  text.replace(text.find("<CGLinearSolver"), 15, "<StaticSolver/><CGLinearSolver");
  const std::string e = problemOf(text);
  EXPECT_NE(e.find("a second ODE solver in node /root/body"), std::string::npos) << e;
  EXPECT_NE(e.find("integrated twice"), std::string::npos) << e;
}

}  // namespace
