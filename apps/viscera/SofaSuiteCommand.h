// `viscera sofa-suite`: SOFA's example scenes and state-regression suite, loaded and run unchanged
// (see docs/user-guide.md, "SOFA scenes").
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addSofaSuiteCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
