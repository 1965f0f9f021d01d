// A run as a library call: the result's figures against the simulation's own state, run
// observers, the post-solve correction seam, inactive nodes, and runs of scene variants in
// threads (each run gives exactly what it gives alone).
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "builtin/Builtins.h"
#include "engine/Run.h"
#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/RigidObject.h"
#include "io/scene/SceneReader.h"
#include "tests/support/SceneFiles.h"
#include "tests/support/TempDir.h"

using namespace viscera;
using viscera::test_support::readSceneWithoutExports;
using viscera::test_support::TempDir;

namespace {

const char* kDropScene = R"(<Node name="root" dt="0.01" gravity="0 0 -10">
  <Node name="body">
    <EulerImplicitSolver rayleighStiffness="0" rayleighMass="0"/>
    <CGLinearSolver iterations="10" tolerance="1e-12" threshold="1e-30"/>
    <MechanicalObject name="dofs" position="0 0 0  1 0 0"/>
    <UniformMass totalMass="2"/>
  </Node>
</Node>)";

TEST(Run, ResultFiguresMatchTheSimulation) {
  auto scene = buildScene(readSceneWithoutExports("scenes/gel_phantom_coarse.xml"));
  Simulation sim(*scene);
  struct Counter : RunObserver {
    int begun = -1, steps = 0, ended = 0;
    void begin(const Simulation&, int total) override { begun = total; }
    void step(const Simulation&) override { ++steps; }
    void end(const Simulation&, const RunResult&) override { ++ended; }
  } counter;
  RunOptions o;
  o.time = 2.0;  // the scene's time unit (s): 300 steps of 1/150 s
  o.observers.push_back(&counter);
  const RunResult r = run(sim, o);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.steps, 300);
  EXPECT_EQ(counter.begun, 300);
  EXPECT_EQ(counter.steps, 300);
  EXPECT_EQ(counter.ended, 1);
  EXPECT_NEAR(r.simulatedTime(), 2.0, 1e-12);
  EXPECT_EQ(r.units, "mm g s");
  ASSERT_EQ(r.objects.size(), 1u);  // the instrument (Rigid3d) is a RigidObject, not an object
  const MechanicalObject& dofs = *scene->all<MechanicalObject>().at(0);
  EXPECT_EQ(r.objects[0].nodes, 325);
  EXPECT_DOUBLE_EQ(r.objects[0].maxDisplacement, (dofs.x(sim.state()) - dofs.x0).colwise().norm().maxCoeff());
  ASSERT_EQ(r.instruments.size(), 1u);
  const auto& in = r.instruments[0];
  ASSERT_EQ(in.history.size(), 300u);
  double peak = 0;
  long contact = 0;
  for (const auto& w : in.history) {
    peak = std::max(peak, w.force.norm());
    contact += w.contacts > 0;
  }
  EXPECT_EQ(in.peakForce, peak);
  EXPECT_EQ(in.stepsInContact, contact);
  EXPECT_TRUE(in.last.force == scene->all<RigidObject>()[0]->live(sim.state()).force);
  ASSERT_TRUE(r.contact.has_value());
  EXPECT_EQ(r.contact->response, "constraint");
  // The summary and wrench table carry the same figures.
  EXPECT_NE(summaryJson(r, "x.xml").find("\"steps\": 300"), std::string::npos);
  const std::string csv = wrenchCsv(r);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 301);
}

TEST(Run, ACorrectionChangesTheStateBeforeMappingsAndObserversSeeIt) {
  auto scene = buildScene(io::parseSceneText(kDropScene, "drop.xml"));
  Simulation sim(*scene);
  MechanicalObject& dofs = *scene->all<MechanicalObject>()[0];
  // Holds node 1 where it started, after every solve.
  struct Hold : Correction {
    MechanicalObject& m;
    explicit Hold(MechanicalObject& mo) : m(mo) {}
    void correct(State& s, double, int) const override {
      m.x(s).col(1) = m.x0.col(1);
      m.v(s).col(1).setZero();
    }
  } hold(dofs);
  sim.addCorrection(hold);
  struct Watch : RunObserver {
    const MechanicalObject& m;
    double worst = 0;
    explicit Watch(const MechanicalObject& mo) : m(mo) {}
    void step(const Simulation& sim) override { worst = std::max(worst, (m.x(sim.state()).col(1) - m.x0.col(1)).norm()); }
  } watch(dofs);
  RunOptions o;
  o.steps = 50;
  o.observers.push_back(&watch);
  ASSERT_TRUE(run(sim, o).ok());
  EXPECT_EQ(watch.worst, 0.0);
  // Node 0 falls freely: implicit Euler's z after n steps of h under g is -g h^2 n(n+1)/2.
  EXPECT_NEAR(dofs.x(sim.state())(2, 0), -10 * 0.01 * 0.01 * 50 * 51 / 2, 1e-9);
}

TEST(Run, AnInactiveNodeIsNotSimulatedAndTheRunSaysSo) {
  std::string text = kDropScene;
  text.replace(text.find("<Node name=\"body\">"), 18, "<Node name=\"body\" activated=\"false\">");
  auto scene = buildScene(io::parseSceneText(text, "drop.xml"));
  Simulation sim(*scene);
  EXPECT_TRUE(scene->all<MechanicalObject>().empty());
  bool said = false;
  for (const auto& n : scene->notes()) said |= n.find("'body' is inactive") != std::string::npos;
  EXPECT_TRUE(said);
  RunOptions o;
  o.steps = 5;
  const RunResult r = run(sim, o);
  EXPECT_TRUE(r.ok());
  EXPECT_TRUE(r.objects.empty());
  // A link into an inactive node is an error naming it.
  std::string linked = kDropScene;
  linked.replace(linked.find("<Node name=\"body\">"), 18, "<Node name=\"off\" activated=\"false\"><BoxROI name=\"box\" box=\"-1 -1 -1 1 1 1\"/></Node><Node name=\"body\">");
  linked.replace(linked.find("<UniformMass"), 12, "<FixedConstraint indices=\"@../off/box.indices\"/><UniformMass");
  auto bad = buildScene(io::parseSceneText(linked, "drop.xml"));
  try {
    bad->init();
    FAIL() << "a link into an inactive node resolved";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("inactive node"), std::string::npos) << e.what();
  }
}

// The final positions of a run of `desc` for `steps` steps with one worker thread.
Eigen::Matrix3Xd finalPositions(const SceneDesc& desc, int steps) {
  auto scene = buildScene(desc);
  RunOptions o;
  o.steps = steps;
  o.threads = 1;
  const RunResult r = run(*scene, o);
  EXPECT_TRUE(r.ok());
  return scene->all<MechanicalObject>().at(0)->x(*r.finalState);
}

TEST(Run, VariantsInThreadsGiveExactlyTheirSequentialResults) {
  const SceneDesc base = readSceneWithoutExports("scenes/gel_phantom_coarse.xml");
  SceneDesc stiff = base;
  stiff.set("phantom/fem.youngModulus", "9 kPa");
  const int steps = 400;
  const Eigen::Matrix3Xd soloBase = finalPositions(base, steps), soloStiff = finalPositions(stiff, steps);
  EXPECT_FALSE(soloBase == soloStiff);  // the variant differs

  Eigen::Matrix3Xd a, b;
  std::thread ta([&] { a = finalPositions(base, steps); });
  std::thread tb([&] { b = finalPositions(stiff, steps); });
  ta.join();
  tb.join();
  EXPECT_TRUE(a == soloBase);
  EXPECT_TRUE(b == soloStiff);

  // The same model twice at once.
  Eigen::Matrix3Xd c, d;
  std::thread tc([&] { c = finalPositions(base, steps); });
  std::thread td([&] { d = finalPositions(base, steps); });
  tc.join();
  td.join();
  EXPECT_TRUE(c == soloBase);
  EXPECT_TRUE(d == soloBase);
}

// One built model (the components, their precomputation and the shared compliance at rest), several
// states: simulations of it step at once in threads, or in turn on one thread, and each gives
// exactly what it gives alone.
TEST(Run, OneModelStepsInSeveralSimulationsAtOnce) {
  auto scene = buildScene(readSceneWithoutExports("scenes/gel_phantom_coarse.xml"));
  const int steps = 400;
  RunOptions o;
  o.steps = steps;
  o.threads = 1;
  State alone;
  {
    Simulation sim(*scene);
    const RunResult r = run(sim, o);
    ASSERT_TRUE(r.ok());
    ASSERT_GT(r.instruments.at(0).stepsInContact, 0);  // the instrument reaches the tissue
    alone = sim.captureState();
  }
  Simulation a(*scene), b(*scene);
  std::thread ta([&] { run(a, o); });
  std::thread tb([&] { run(b, o); });
  ta.join();
  tb.join();
  EXPECT_TRUE(a.captureState() == alone);
  EXPECT_TRUE(b.captureState() == alone);

  // In turn on one thread, a step each: the states do not leak into each other.
  Simulation c(*scene), d(*scene);
  for (int i = 0; i < steps; ++i) {
    ASSERT_FALSE(c.step());
    ASSERT_FALSE(d.step());
  }
  EXPECT_TRUE(c.captureState() == alone);
  EXPECT_TRUE(d.captureState() == alone);
}

// A scene's observers write its outputs: a second simulation of a scene that has some is refused.
TEST(Run, AModelWithOutputsServesOneSimulationAtATime) {
  auto scene = buildScene(io::parseSceneText(kDropScene, "drop.xml"));
  ASSERT_TRUE(scene->all<Observer>().empty());
  Simulation one(*scene), two(*scene);  // no outputs: fine
  auto exporting = buildScene(io::readScene(std::string(VISCERA_SOURCE_DIR) + "/scenes/gel_phantom_coarse.xml"));
  TempDir tmp;
  exporting->setOutputDirectory(tmp.path().string());
  ASSERT_FALSE(exporting->all<Observer>().empty());
  {
    Simulation first(*exporting);
    try {
      Simulation second(*exporting);
      FAIL() << "a second simulation of a scene with an exporter was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("already serves another simulation"), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW({ Simulation again(*exporting); });  // the first one has ended
}

}  // namespace
