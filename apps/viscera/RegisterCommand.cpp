#include "apps/viscera/RegisterCommand.h"

namespace viscera {

void addRegisterCommand(CLI::App&, std::function<int()>&) {}

}  // namespace viscera
