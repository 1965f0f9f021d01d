#pragma once

#include "core/Component.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

// The linear solver in `c`'s node; a clear error if there is none.
LinearSolver* findLinearSolver(Component& c);

// True when `c`'s node holds a rigid body and no deformable one: a SOFA instrument node with its
// own solver. Driven rigid bodies are not integrated, so the solver stays idle (with a note).
bool idleInRigidNode(Component& c);

}  // namespace viscera
