// `viscera espm`: decode ESPM captures (dVRK-S arm packets) and synthesise them from joint logs.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

// Adds the `espm` subcommand (with `decode` and `synth`) to `app`. When one is given, parsing sets
// `action` to the work to do; it returns the exit code and throws viscera::Error for an unusable
// option or input file. Nothing is checked or thrown during parsing itself.
void addEspmCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
