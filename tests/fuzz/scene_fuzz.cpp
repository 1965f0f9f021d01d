// Fuzz target of the scene reader and builder: the input is a scene's XML. It is parsed, built and
// initialised, and a scene of at most 1,500 nodes runs two steps (a larger grid is refused or
// slow by design, not by fault: bounded here so that each input takes milliseconds, even under
// the sanitizers). Files the
// scene names are looked up in the folder VISCERA_FUZZ_SCENE_DIR (`make test` points it at the
// study fixtures, so that a contact scene finds its trajectory; unset, a folder that does not
// exist); exporters and cameras write to a folder of this process. A grid beyond the builder's limit
// is built too (it must be refused before anything is allocated). Bad input must end in
// viscera::Error, nothing else.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "builtin/Builtins.h"
#include "core/SceneDesc.h"
#include "engine/Simulation.h"
#include "engine/mechanics/MechanicalObject.h"
#include "io/scene/SceneReader.h"
#include "tests/fuzz/FuzzInput.h"

namespace {

constexpr double kMaxNodes = 1500;

// The largest node count a RegularGridTopology of the description asks for (0 when none parse).
double largestGrid(const viscera::ElementDesc& el) {
  double most = 0;
  if (el.tag == "RegularGridTopology")
    if (const viscera::AttrDesc* n = el.find("n")) {
      double count = 1, v = 0;
      int read = 0;
      for (size_t at = 0; at < n->value.size() && read < 3;) {
        char* end = nullptr;
        v = std::strtod(n->value.c_str() + at, &end);
        if (end == n->value.c_str() + at) break;
        count *= v;
        ++read;
        at = static_cast<size_t>(end - n->value.c_str());
      }
      most = count;
    }
  for (const auto& c : el.children) most = std::max(most, largestGrid(c));
  return most;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  viscera_fuzz::expectOnlyInputErrors([&] {
    static const std::string file = std::string(std::getenv("VISCERA_FUZZ_SCENE_DIR") ? std::getenv("VISCERA_FUZZ_SCENE_DIR")
                                                                                       : "/nonexistent") + "/fuzz.xml";
    const viscera::SceneDesc desc = viscera::io::parseSceneText(text, file);
    const double grid = largestGrid(desc.root);
    if (!(grid <= kMaxNodes) && !(grid > 1e7)) return;
    auto scene = viscera::buildScene(desc);
    scene->setOutputDirectory(viscera_fuzz::asFile(nullptr, 0, "-out") + ".d");
    viscera::Simulation sim(*scene);
    for (const auto* mo : scene->all<viscera::MechanicalObject>())
      if (mo->size() > kMaxNodes) return;
    for (int i = 0; i < 2; ++i)
      if (sim.step()) break;
  });
  return 0;
}
