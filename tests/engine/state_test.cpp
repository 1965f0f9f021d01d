// The state of a simulation apart from its model: a state captured mid-run and restored into a
// fresh simulation of the same scene continues bit-identically (the 80 s palpation into contact
// and friction, through a file); a state does not go into another model; corrupt files are errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

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

// Everything a run produces, bit for bit: positions, velocities, forces, instrument wrenches.
void expectSameState(const Simulation& a, const Simulation& b) {
  auto ma = a.scene().all<MechanicalObject>(), mb = b.scene().all<MechanicalObject>();
  ASSERT_EQ(ma.size(), mb.size());
  for (size_t i = 0; i < ma.size(); ++i) {
    const MechanicalObject::Live &la = ma[i]->live(a.state()), &lb = mb[i]->live(b.state());
    EXPECT_TRUE(la.x == lb.x) << ma[i]->name() << ": positions differ by " << (la.x - lb.x).cwiseAbs().maxCoeff();
    EXPECT_TRUE(la.v == lb.v) << ma[i]->name() << ": velocities differ";
    EXPECT_TRUE(la.f == lb.f) << ma[i]->name() << ": forces differ";
  }
  auto ra = a.scene().all<RigidObject>(), rb = b.scene().all<RigidObject>();
  ASSERT_EQ(ra.size(), rb.size());
  for (size_t i = 0; i < ra.size(); ++i) {
    const RigidObject::Live &la = ra[i]->live(a.state()), &lb = rb[i]->live(b.state());
    EXPECT_TRUE(la.force == lb.force) << ra[i]->name();
    EXPECT_TRUE(la.torque == lb.torque) << ra[i]->name();
    EXPECT_TRUE(la.p == lb.p) << ra[i]->name();
    EXPECT_EQ(la.contacts, lb.contacts);
  }
}

TEST(State, PalpationSavedAtStep500ContinuesBitIdentically) {
  const SceneDesc desc = readSceneWithoutExports("scenes/gel_phantom.xml");
  const int saveAt = 500, more = 750;
  TempDir tmp;

  // Uninterrupted run, with the state captured on the way.
  auto whole = buildScene(desc);
  Simulation a(*whole);
  RunOptions first;
  first.steps = saveAt;
  first.recordWrench = false;
  ASSERT_TRUE(run(a, first).ok());
  const State mid = a.captureState();
  EXPECT_EQ(mid.steps, saveAt);
  mid.save(tmp / "mid.state");
  RunOptions rest;
  rest.steps = more;
  const RunResult ra = run(a, rest);
  ASSERT_TRUE(ra.ok());
  // The next poke starts before step 1250: the continued run goes through contact with friction.
  ASSERT_GT(ra.instruments.at(0).stepsInContact, 0);

  // A fresh simulation of the same scene, restored from the file.
  auto resumed = buildScene(desc);
  Simulation b(*resumed);
  const State loaded = State::load(tmp / "mid.state");
  EXPECT_TRUE(loaded == mid);
  RunOptions cont = rest;
  cont.initialState = &loaded;
  const RunResult rb = run(b, cont);
  ASSERT_TRUE(rb.ok());
  EXPECT_EQ(b.steps(), saveAt + more);
  EXPECT_EQ(b.time(), a.time());
  expectSameState(a, b);
  EXPECT_TRUE(a.captureState() == b.captureState());
  ASSERT_EQ(ra.instruments[0].history.size(), rb.instruments[0].history.size());
  for (size_t i = 0; i < ra.instruments[0].history.size(); ++i)
    ASSERT_TRUE(ra.instruments[0].history[i].force == rb.instruments[0].history[i].force) << "step " << saveAt + i + 1;
}

TEST(State, RestoringIntoTheSameSimulationRewindsIt) {
  auto scene = buildScene(readSceneWithoutExports("scenes/gel_phantom_coarse.xml"));
  Simulation sim(*scene);
  RunOptions o;
  o.steps = 200;
  run(sim, o);
  const State s200 = sim.captureState();
  o.steps = 150;
  run(sim, o);
  const State s350 = sim.captureState();
  EXPECT_TRUE(s200 != s350);
  sim.restoreState(s200);
  EXPECT_TRUE(sim.captureState() == s200);
  run(sim, o);
  EXPECT_TRUE(sim.captureState() == s350);
}

// Plastic strains are state: with SOFA's plasticity on (every strain creeps), a state captured
// mid-run and restored continues bit-identically, and the run differs from the elastic one.
TEST(State, PlasticStrainsAreStateAndRewindWithIt) {
  SceneDesc desc = readSceneWithoutExports("scenes/gel_phantom_coarse.xml");
  auto elastic = buildScene(desc);
  std::function<bool(ElementDesc&)> plastic = [&](ElementDesc& e) {
    if (e.tag == "TetrahedronFEMForceField") {
      e.set("plasticMaxThreshold", "1e9");
      e.set("plasticYieldThreshold", "0");
      e.set("plasticCreep", "0.05");
      return true;
    }
    return std::any_of(e.children.begin(), e.children.end(), plastic);
  };
  ASSERT_TRUE(plastic(desc.root));
  auto scene = buildScene(desc);
  Simulation sim(*scene), ref(*elastic);
  RunOptions o;
  o.steps = 200;
  o.recordWrench = false;
  run(sim, o);
  run(ref, o);
  const State s200 = sim.captureState();
  o.steps = 150;
  run(sim, o);
  const State s350 = sim.captureState();
  sim.restoreState(s200);
  run(sim, o);
  EXPECT_TRUE(sim.captureState() == s350);
  const auto a = sim.scene().all<MechanicalObject>(), b = ref.scene().all<MechanicalObject>();
  ASSERT_EQ(a.size(), b.size());
  double moved = 0;
  for (size_t i = 0; i < a.size(); ++i) moved = std::max(moved, (a[i]->x(sim.state()) - b[i]->x(ref.state())).cwiseAbs().maxCoeff());
  EXPECT_GT(moved, 1e-3);  // mm: plasticity changed the run
}

TEST(State, AStateOfAnotherModelIsRefusedAndChangesNothing) {
  auto coarse = buildScene(readSceneWithoutExports("scenes/gel_phantom_coarse.xml"));
  auto fine = buildScene(readSceneWithoutExports("scenes/gel_phantom.xml"));
  Simulation a(*coarse), b(*fine);
  const State sb = b.captureState(), sa = a.captureState();
  try {
    a.restoreState(sb);
    FAIL() << "a state of the 25x9x9 phantom went into the 13x5x5 one";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit this model"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(a.captureState() == sa);

  // Same structure, other parameters: fine (a variant continues from the state of another).
  SceneDesc stiff = readSceneWithoutExports("scenes/gel_phantom_coarse.xml");
  stiff.set("phantom/fem.youngModulus", "8 kPa");
  auto variant = buildScene(stiff);
  Simulation c(*variant);
  EXPECT_NO_THROW(c.restoreState(sa));
}

TEST(State, FilesThatAreNotStatesAreErrorsNamingTheFile) {
  TempDir tmp;
  auto scene = buildScene(readSceneWithoutExports("scenes/gel_phantom_coarse.xml"));
  Simulation sim(*scene);
  sim.captureState().save(tmp / "ok.state");
  std::string bytes;
  {
    std::ifstream in(tmp / "ok.state", std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto write = [&](const std::string& name, const std::string& content) {
    std::ofstream(tmp / name, std::ios::binary) << content;
    return std::string(tmp / name);
  };
  for (const std::string& f : {write("empty.state", ""), write("text.state", "hello world, not a state"),
                               write("cut.state", bytes.substr(0, bytes.size() / 2)),
                               write("long.state", bytes + "x")}) {
    try {
      State::load(f);
      FAIL() << f << " loaded";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(State::load(tmp / "missing.state"), Error);
}

}  // namespace
