#pragma once

#include "core/Component.h"
#include "engine/rigid/RigidDynamics.h"
#include "engine/rigid/RigidObject.h"
#include "solvers/linear/LinearSolver.h"

namespace viscera {

class MechanicalSystem;

// The linear solver in `c`'s node; a clear error if there is none.
LinearSolver* findLinearSolver(Component& c);
// Points `problem` at the assembled matrix A: its product and its diagonal (for preconditioners).
void useAssembled(LinearProblem& problem, const BlockSparseMatrix& A);
// Solves (mFact M + kFact (K_damped + uScale K_undamped)) x = rhs at the system's last
// linearisation, with `linear` (assembled into A when it needs a matrix, matrix-free otherwise,
// fixed nodes projected out); x holds the starting guess.
LinearSolveInfo solveStepSystem(const MechanicalSystem& sys, LinearSolver& linear, State& st, BlockSparseMatrix& A,
                                double mFact, double kFact, double uScale, const Eigen::VectorXd& rhs, Eigen::VectorXd& x);

// The Newton iteration settings of SOFA's NewtonRaphsonSolver component (StaticSolver and
// BDFOdeSolver read them): stop at the first criterion met; a step shrinks by lineSearchFactor
// until the residual falls, at most lineSearch trials.
struct NewtonSettings {
  int iterations = 1;
  double absResidual = 1e-5, relInitial = 1e-5, relSuccessive = 1e-5;
  double absCorrection = 0, relCorrection = 0;
  int lineSearch = 5;
  double lineSearchFactor = 0.5;
};
NewtonSettings newtonSettings(const Component& newtonRaphsonSolver);
// The NewtonRaphsonSolver in `c`'s node, or nullptr.
const Component* findNewtonRaphsonSolver(const Component& c);


}  // namespace viscera
