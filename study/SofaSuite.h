// SOFA's example scenes and state-regression suite run here: each scene is loaded unchanged, run,
// and (for the regression list) compared with the states SOFA itself computed for it.
//
// The regression list (RegressionStateScenes.regression-tests) holds a reference-folder line and
// lines "SCENE STEPS EPSILON MAPPED LAST_ONLY". For SCENE, SOFA wrote one gzip text file per dumped
// MechanicalObject, REFDIR/SCENE.reference_<k>_<name>_mstate.txt.gz, with blocks "T= t", "X= ..."
// (every node's x y z) and "V= ...". SOFA's own criterion (its Regression_test): per compared step
// and object, e = the mean over all scalar components of |reference - here|, for X and for V; the
// sum of (e_X + e_V) / nodes over the compared steps, averaged over the objects, passes when it is
// at most EPSILON. That is lenient (divided twice by the size), so the largest node distance to
// the reference is reported beside it.
#pragma once

#include <string>
#include <vector>

namespace viscera::study {

struct RegressionEntry {
  std::string scene;  // relative to the examples folder
  int steps = 0;
  double epsilon = 0;
  bool mapped = false;    // compare MechanicalObjects under mappings too
  bool lastOnly = true;   // compare the last dumped step only
  int line = 0;           // in the list file
};

struct RegressionList {
  std::string file;
  std::string referenceDir;  // where SCENE.reference_* live (the list's folder line, resolved)
  std::vector<RegressionEntry> entries;
};

// Reads a list in SOFA's format. A reference folder starting with $REGRESSION_DIR takes that
// environment variable, else `regressionDir` (when given), else the folder `regression` beside
// the list's folder. Throws viscera::Error with file:line for malformed lines.
RegressionList readRegressionList(const std::string& path, const std::string& regressionDir = "");

// One dumped step of a reference: time, positions and velocities (x y z per node, in node order;
// Rigid3d states have 7 and 6 values per node).
struct ReferenceFrame {
  double t = 0;
  std::vector<double> x, v;
  // The most significant digits any X or V value of the dump is printed with (SOFA prints six):
  // a state is compared with the reference at that precision.
  int digits = 17;
};
// Reads a SOFA state dump (.txt.gz or plain text). Throws viscera::Error naming the file and line.
std::vector<ReferenceFrame> readStateDump(const std::string& path);

struct SuiteResult {
  enum class Status { Passed, Differs, Runs, Needs, Error, Diverged, NoReference };
  std::string scene;
  Status status = Status::Error;
  std::string detail;  // Needs: the component or attribute; Error, Diverged: the message
  int steps = 0;
  double seconds = 0;
  // Regression scenes: SOFA's criterion, its threshold, the largest node distance (positions)
  // over the compared steps and objects, and how many objects were compared.
  double sofaError = 0, epsilon = 0, maxDistance = 0;
  int objects = 0;
  // With orderRuns > 0: the scene run again that many times, its constraint solve visiting the
  // constraints in other orders (ConstraintSolver::shuffleOrder). SOFA's criterion against the
  // reference over all runs (this one included), and the largest it gives between this run and
  // another: how far the order of the solver's sweeps alone moves the result.
  int orderRuns = 0;
  double orderErrorMin = 0, orderErrorMax = 0, orderSpread = 0;
};
const char* statusName(SuiteResult::Status s);

// Loads and runs one regression scene and compares it with its references; a scene with a
// constraint solver is then run `orderRuns` more times with its constraints in other orders.
SuiteResult runRegressionScene(const RegressionList& list, const RegressionEntry& entry, const std::string& examplesDir,
                               int orderRuns = 0);
// Loads one scene and runs it `steps` steps (the examples check).
SuiteResult runExampleScene(const std::string& path, int steps);

// The example scenes under `dir`: every .scn and .xml file but include fragments (a root node
// named "Group"), sorted.
std::vector<std::string> exampleScenes(const std::string& dir);

}  // namespace viscera::study
