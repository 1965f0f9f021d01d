#pragma once

#include "core/Component.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

// The linear solver in `c`'s node; a clear error if there is none.
LinearSolver* findLinearSolver(Component& c);


}  // namespace viscera
