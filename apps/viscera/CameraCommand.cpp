#include "apps/viscera/CameraCommand.h"

namespace viscera {

void addCameraCommand(CLI::App&, std::function<int()>&) {}

}  // namespace viscera
