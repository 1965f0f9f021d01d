#include "observation/Tissue.h"

#include "core/Scene.h"
#include "engine/Roles.h"
#include "engine/mechanics/MechanicalObject.h"

namespace viscera::obs {

const TetList* bodyTetrahedra(MechanicalObject& state) {
  for (const Node* n = &state.node(); n; n = n->parent()) {
    const auto& comps = n->components();
    for (auto it = comps.rbegin(); it != comps.rend(); ++it) {
      auto* topo = dynamic_cast<Topology*>(it->get());
      if (!topo) continue;
      state.scene().initComponent(**it);
      const TetList& tets = topo->tetrahedra();
      if (tets.cols() == 0) continue;
      return tets.maxCoeff() < state.size() && tets.minCoeff() >= 0 ? &tets : nullptr;
    }
  }
  return nullptr;
}

std::vector<TissueSurface> tissueSurfaces(Scene& scene) {
  std::vector<TissueSurface> out;
  for (MechanicalObject* state : scene.all<MechanicalObject>()) {
    scene.initComponent(*state);
    const TetList* tets = bodyTetrahedra(*state);
    if (!tets) continue;
    TissueSurface s{state, boundaryTriangles(*tets, state->xInit)};
    if (s.triangles.cols() > 0) out.push_back(std::move(s));
  }
  return out;
}

}  // namespace viscera::obs
