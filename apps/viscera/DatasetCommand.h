// `viscera dataset make` and `viscera dataset check`: see docs/user-guide.md, "Datasets".
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "apps/viscera/CameraCommand.h"

namespace CLI {
class App;
}

namespace viscera {

// What `viscera dataset make` takes (also used by `viscera audit bench` to make its cases).
struct DatasetMakeOptions {
  std::string scene, out, forceNoise = "0", torqueNoise = "0";
  std::vector<std::string> sets;
  double time = 0;
  int steps = -1;
  unsigned seed = 1;
  bool noWrench = false, quiet = false;
  CameraOptionSet camera;
};

// Runs the scene with its instrument and depth camera and writes the dataset folder `out` (which
// must not exist): written under a temporary name, checked, then renamed. Returns the exit code.
int makeDataset(const DatasetMakeOptions& o);

void addDatasetCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
