#include "engine/core/Registry.h"

namespace viscera {

void registerObservation(Registry&) {}

}  // namespace viscera
