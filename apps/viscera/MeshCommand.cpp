#include "apps/viscera/MeshCommand.h"

namespace viscera {

void addMeshCommand(CLI::App&, std::function<int()>&) {}

}  // namespace viscera
