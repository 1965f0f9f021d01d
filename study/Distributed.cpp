#include "study/Distributed.h"

#include <cstdlib>

namespace viscera::study {

// Open MPI's mpirun sets OMPI_COMM_WORLD_SIZE; PMI and PMIx launchers (srun, hydra) theirs.
bool launchedByMpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(v)) return true;
  return false;
}

}  // namespace viscera::study
