#include "engine/core/Registry.h"

namespace viscera {

void registerMappings(Registry&) {}

}  // namespace viscera
