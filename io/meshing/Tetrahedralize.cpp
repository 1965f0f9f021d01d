#include "io/surface/SurfaceMesh.h"
