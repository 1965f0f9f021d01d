// `viscera learn record`: see docs/user-guide.md, "Rollouts".
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addLearnCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
