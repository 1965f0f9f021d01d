// `viscera search` and `viscera search merge`: see docs/user-guide.md, "Searching parameters".
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addSearchCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
