// `viscera velocity compare`: the encoder velocity bench of a quadrature encoder pair in simulation.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

// Adds the `velocity` subcommand (with its `compare` subcommand) to `app`. When it is given,
// parsing sets `action` to the work to do; it returns the exit code and throws viscera::Error for
// an unusable option. Nothing is checked or thrown during parsing itself.
void addVelocityCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
