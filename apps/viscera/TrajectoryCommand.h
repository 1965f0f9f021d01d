// `viscera trajectory`: writes a palpation trajectory CSV (a sphere poking a box-shaped specimen).
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

// Adds the `trajectory` subcommand to `app`. When it is given, parsing sets `action` to the work
// to do (generate and write the file); it returns the exit code and throws viscera::Error for an
// unusable option. Nothing is checked or thrown during parsing itself.
void addTrajectoryCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
