// What a learned component binds to in its scene: the body it acts on, as the rest mesh a model is
// checked against, and the instrument it follows.
#pragma once

#include <memory>
#include <string>

#include "core/Component.h"
#include "core/Error.h"
#include "learning/data/Rollout.h"

namespace viscera {

class MechanicalObject;
class SphereCollisionModel;

namespace learning {

// The body's rest mesh: its rest positions, the tetrahedra of its topology and the nodes its
// projective constraints hold. Throws `c`'s error when the body has no tetrahedra.
RestMesh boundRestMesh(Component& c, MechanicalObject& body);

// The instrument `c` follows: its `instrument` link, else the scene's only SphereCollisionModel
// (initialised). Throws `c`'s error naming the attribute otherwise.
SphereCollisionModel& boundInstrument(Component& c);

// boundModel's parts that need the scene: the folder, the error naming it, the units' check.
std::string resolvedModelFolder(const Component& c);
Error modelFileError(const Error& e, const Component& c);
void checkModelUnits(const Component& c, const std::string& units);

// The model folder named by `c`'s `model` attribute (relative to the scene), loaded and checked
// against the body's rest mesh and the scene's units; errors name the attribute.
template <class Model>
std::shared_ptr<const Model> boundModel(Component& c, const RestMesh& mesh, const std::string& bodyName) {
  std::shared_ptr<const Model> model;
  try {
    model = std::make_shared<const Model>(Model::load(resolvedModelFolder(c)));
  } catch (const Error& e) {
    throw modelFileError(e, c);
  }
  try {
    model->checkMesh(mesh, "the body '" + bodyName + "'");
  } catch (const Error& e) {
    throw c.error("model", e.what());
  }
  checkModelUnits(c, model->units());
  return model;
}

}  // namespace learning
}  // namespace viscera
