// `viscera mesh`: see docs/user-guide.md.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

// Adds the `mesh` subcommand to `app`. When it is given, parsing sets `action` to the work to
// do; the action returns the exit code and throws viscera::Error for unusable input.
void addMeshCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
