// A search across the ranks of an MPI job (Open MPI from Debian; `mpirun -n N viscera search ...`).
// Rank 0 runs the search: it hands candidates out one at a time to whichever rank is free (itself
// included, on a second thread), receives each result as a results.csv row (17 significant digits,
// so nothing is lost) and writes every output. The other ranks only evaluate. A build without MPI
// (VISCERA_WITH_MPI off) reports so when started under a launcher.
#pragma once

#include <memory>

#include "study/Search.h"

namespace viscera::study {

// Whether this process was started by an MPI launcher (mpirun, srun): read from the environment,
// so that a plain `viscera search` never initialises MPI.
bool launchedByMpi();

class MpiSession {
 public:
  // MPI_Init_thread (only the main thread calls MPI); Error when the build has no MPI.
  MpiSession();
  ~MpiSession();  // MPI_Finalize
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

  // Rank 0: an executor that spreads candidates over every rank. Call stopWorkers() when the
  // search is over (or failed), so that the other ranks return from serve().
  std::unique_ptr<CandidateExecutor> coordinator() const;
  void stopWorkers() const;
  // The other ranks: evaluate candidates until rank 0 says stop.
  void serve(const CandidateExecutor::Evaluate& evaluate) const;

 private:
  int rank_ = 0, size_ = 1;
};

}  // namespace viscera::study
