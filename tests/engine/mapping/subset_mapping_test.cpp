// SubsetMapping: each point of the output follows the input node it was paired with, by index or
// by place; a point at no node is refused.
#include <gtest/gtest.h>

#include <string>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"

using namespace viscera;

namespace {

// Three free nodes falling from rest, and a mapped state of two of them.
std::string scene(const std::string& mapped, const std::string& mapping) {
  return R"(<Node name="root" dt="0.1" gravity="0 0 -10">
  <Node name="body">
    <EulerImplicitSolver/><CGLinearSolver iterations="10" tolerance="1e-12" threshold="1e-20"/>
    <MechanicalObject name="dofs" position="0 0 0  1 0 0  2 0 0"/>
    <UniformMass vertexMass="1"/>
    <Node name="sub"><MechanicalObject name="sub" position=")" + mapped + R"("/>)" + mapping + R"(</Node>
  </Node>
</Node>)";
}

MechanicalObject& named(Scene& s, const std::string& n) {
  for (MechanicalObject* m : s.all<MechanicalObject>())
    if (m->name() == n) return *m;
  throw std::out_of_range(n);
}

}  // namespace

TEST(SubsetMapping, PointsFollowTheirNodesByPlaceOrByIndex) {
  for (const std::string mapping : {std::string("<SubsetMapping/>"), std::string(R"(<SubsetMapping indices="2 0"/>)")}) {
    auto s = buildScene(io::parseSceneText(scene("2 0 0  0 0 0", mapping), "subset.xml"));
    Simulation sim(*s);
    for (int i = 0; i < 3; ++i) ASSERT_FALSE(sim.step());
    const MechanicalObject &body = named(*s, "dofs"), &sub = named(*s, "sub");
    EXPECT_EQ(sub.x(sim.state()).col(0), body.x(sim.state()).col(2)) << mapping;
    EXPECT_EQ(sub.x(sim.state()).col(1), body.x(sim.state()).col(0)) << mapping;
    EXPECT_EQ(sub.v(sim.state()).col(0), body.v(sim.state()).col(2)) << mapping;
    EXPECT_LT(body.x(sim.state())(2, 0), -0.5);  // it fell
  }
}

TEST(SubsetMapping, APointAtNoNodeIsRefused) {
  std::string why;
  try {
    buildScene(io::parseSceneText(scene("0.5 0 0", "<SubsetMapping/>"), "subset.xml"))->init();
  } catch (const Error& e) {
    why = e.what();
  }
  EXPECT_NE(why.find("SubsetMapping.radius"), std::string::npos) << why;
}
