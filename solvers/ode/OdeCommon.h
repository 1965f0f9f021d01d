#pragma once

#include "engine/core/Component.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

// The linear solver in `c`'s node; a clear error if there is none.
LinearSolver* findLinearSolver(Component& c);

}  // namespace viscera
