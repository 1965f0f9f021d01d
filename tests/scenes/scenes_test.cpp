// Every scene shipped in scenes/ (found at test time, so new scenes are covered without editing this
// file) loads, runs 20 steps without failure, and writes a .pvd index with the .vtu files it names
// into the output folder, not next to the scene.
#include "builtin/Builtins.h"
#include "tests/support/TempDir.h"
#include <gtest/gtest.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "engine/Simulation.h"
#include "core/Scene.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/mesh/Exodus.h"
#include "io/scene/SceneReader.h"
#include "learning/nn/Stepper.h"

namespace fs = std::filesystem;
using namespace viscera;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

using viscera::test_support::TempDir;

std::vector<fs::path> shippedScenes() {
  std::vector<fs::path> v;
  for (const auto& e : fs::directory_iterator(fs::path(VISCERA_SOURCE_DIR) / "scenes"))
    if (e.is_regular_file() && (e.path().extension() == ".xml" || e.path().extension() == ".scn")) v.push_back(e.path());
  std::sort(v.begin(), v.end());
  return v;
}

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> s;
  for (const auto& e : fs::directory_iterator(dir)) s.insert(e.path().filename().string());
  return s;
}

TEST(Scenes, ThereAreScenes) { EXPECT_GE(shippedScenes().size(), 3u); }

TEST(Scenes, EveryShippedSceneRuns20StepsAndExports) {
  const auto before = listing(fs::path(VISCERA_SOURCE_DIR) / "scenes");
  for (const fs::path& path : shippedScenes()) {
    SCOPED_TRACE(path.string());
    if (!viscera::learning::torchAvailable() && slurp(path).find("<Learned") != std::string::npos) continue;  // needs LibTorch
    TempDir tmp;
    const fs::path out = tmp.path() / "out";
    std::unique_ptr<Scene> scene;
    try {
      scene = buildScene(io::readScene(path.string()));
    } catch (const std::exception& e) {
      ADD_FAILURE() << "does not load: " << e.what();
      continue;
    }
    scene->setOutputDirectory(out.string());
    std::unique_ptr<Simulation> sim;
    try {
      sim = std::make_unique<Simulation>(*scene);
      sim->begin();
      // Two simulated seconds (at least 20 steps, at most 1000): long enough for the palpation
      // scenes' instrument to reach the tissue.
      const int steps = std::clamp(static_cast<int>(std::ceil(2.0 / scene->dt())), 20, 1000);
      for (int i = 0; i < steps; ++i) {
        auto failure = sim->step();
        ASSERT_FALSE(failure) << failure->str();
      }
      sim->end();
      EXPECT_EQ(sim->steps(), steps);
      EXPECT_NEAR(sim->time(), scene->startTime() + steps * scene->dt(), 1e-12 * std::max(1.0, sim->time()));
    } catch (const std::exception& e) {
      ADD_FAILURE() << "fails: " << e.what();
      continue;
    }

    // The state is finite and something moved (every shipped scene is loaded).
    auto states = scene->all<MechanicalObject>();
    ASSERT_FALSE(states.empty());
    double moved = 0;
    for (const auto* s : states) {
      EXPECT_TRUE(s->x(sim->state()).allFinite()) << s->name();
      EXPECT_TRUE(s->v(sim->state()).allFinite()) << s->name();
      if (s->size()) moved = std::max(moved, (s->x(sim->state()) - s->x0).colwise().norm().maxCoeff());
    }
    EXPECT_GT(moved, 0.0);

    // A .pvd index and .vtu files, every file the index names existing; or an Exodus series with
    // a frame for each export step.
    ASSERT_TRUE(fs::is_directory(out)) << "nothing written to " << out;
    int pvd = 0, vtu = 0, exo = 0;
    for (const auto& e : fs::directory_iterator(out)) {
      if (e.path().extension() == ".vtu") {
        ++vtu;
        EXPECT_GT(fs::file_size(e.path()), 0u) << e.path();
      }
      if (e.path().extension() == ".exo") {
        ++exo;
        const viscera::io::ExodusReader series(e.path().string());
        EXPECT_GE(series.times().size(), 2u) << e.path();
        EXPECT_GT(series.mesh().tets.cols(), 0) << e.path();
      }
      if (e.path().extension() != ".pvd") continue;
      ++pvd;
      const std::string index = slurp(e.path());
      std::regex file(R"(file\s*=\s*"([^"]+)\")");
      int named = 0;
      for (std::sregex_iterator it(index.begin(), index.end(), file), end; it != end; ++it, ++named)
        EXPECT_TRUE(fs::exists(out / (*it)[1].str())) << e.path() << " names missing " << (*it)[1];
      EXPECT_GT(named, 0) << e.path() << " names no file:\n" << index;
    }
    EXPECT_EQ(pvd >= 1, vtu >= 1);
    EXPECT_GE(vtu + exo, 1);
  }
  // Nothing was written next to the scenes: exporters honour the output folder.
  EXPECT_EQ(listing(fs::path(VISCERA_SOURCE_DIR) / "scenes"), before);
}

}  // namespace
