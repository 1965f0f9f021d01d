#include "learning/components/Binding.h"

#include <algorithm>

#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/collision/Collision.h"
#include "engine/mechanics/MechanicalObject.h"
#include "engine/rigid/Placement.h"
#include "observation/Tissue.h"

namespace viscera::learning {

RestMesh boundRestMesh(Component& c, MechanicalObject& body) {
  RestMesh mesh;
  mesh.points = body.x0;
  const TetList* tets = obs::bodyTetrahedra(body);
  if (!tets) throw c.error("the body '" + body.name() + "' has no tetrahedra; learned components work on a tetrahedral mesh");
  mesh.tets = *tets;
  for (ProjectiveConstraint* p : c.scene().all<ProjectiveConstraint>()) {
    if (auto* comp = dynamic_cast<Component*>(p)) c.scene().initComponent(*comp);
    if (&p->mstate() == &body) mesh.fixed.insert(mesh.fixed.end(), p->fixedNodes().begin(), p->fixedNodes().end());
  }
  std::sort(mesh.fixed.begin(), mesh.fixed.end());
  mesh.fixed.erase(std::unique(mesh.fixed.begin(), mesh.fixed.end()), mesh.fixed.end());
  return mesh;
}

SphereCollisionModel& boundInstrument(Component& c) {
  SphereCollisionModel* sphere = nullptr;
  if (Component* linked = c.linkedComponent("instrument")) {
    sphere = dynamic_cast<SphereCollisionModel*>(linked);
    if (!sphere) throw c.error("instrument", "'" + linked->name() + "' is a " + linked->typeName() + ", not a SphereCollisionModel");
  } else {
    const auto spheres = c.scene().all<SphereCollisionModel>();
    if (spheres.size() != 1)
      throw c.error("instrument", "the scene has " + std::to_string(spheres.size()) +
                                      " SphereCollisionModels on instruments; link the one the model follows");
    sphere = spheres.front();
  }
  c.scene().initComponent(*sphere);
  return *sphere;
}

std::string resolvedModelFolder(const Component& c) { return c.scene().resolvePath(c.attrs().str("model")); }

Error modelFileError(const Error& e, const Component& c) { return fileErrorFor(e, c, "model"); }

void checkModelUnits(const Component& c, const std::string& units) {
  if (units != c.scene().units().str())
    throw c.error("model", "the model works in " + units + ", the scene in " + c.scene().units().str());
}

}  // namespace viscera::learning
