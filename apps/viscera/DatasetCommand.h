// `viscera dataset make` and `viscera dataset check`: see docs/user-guide.md, "Datasets".
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addDatasetCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
