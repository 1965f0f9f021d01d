#include "io/pointcloud/CloudIo.h"
