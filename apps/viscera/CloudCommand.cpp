#include "apps/viscera/CloudCommand.h"

namespace viscera {

void addCloudCommand(CLI::App&, std::function<int()>&) {}

}  // namespace viscera
