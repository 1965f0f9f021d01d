// The tissue as an observer sees it: the boundary surface of every deformable body that has
// tetrahedra. The depth camera renders these surfaces; measured clouds are scored against them.
#pragma once

#include <vector>

#include "engine/Roles.h"
#include "observation/SurfaceIndex.h"

namespace viscera {

class MechanicalObject;
class Scene;

namespace obs {

struct TissueSurface {
  MechanicalObject* state = nullptr;  // its positions are the surface's vertices
  TriangleList triangles;             // 3 x #triangles, indices into the state's nodes
};

// The tetrahedra of a deformable body: those of the last topology with tetrahedra in its node or
// above (as its force field finds them), provided they index its nodes; nullptr when it has none.
// Initialises the topology if needed.
const TetList* bodyTetrahedra(MechanicalObject& state);

// Every deformable body of the scene with a non-empty boundary, in scene order (its state and its
// topology initialised).
std::vector<TissueSurface> tissueSurfaces(Scene& scene);

}  // namespace obs
}  // namespace viscera
