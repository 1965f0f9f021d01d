#include "apps/viscera/DistanceCommand.h"

namespace viscera {

void addDistanceCommand(CLI::App&, std::function<int()>&) {}

}  // namespace viscera
