// `viscera force simulate|train|eval|estimate|bench`: force estimation from robot signals (dissertation
// §2.3-2.5) on simulated data with known truth or on real dVRK logs.
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace viscera {

void addForceCommand(CLI::App& app, std::function<int()>& action);

}  // namespace viscera
