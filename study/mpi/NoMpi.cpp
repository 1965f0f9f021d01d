// Distributed.h in a build without MPI: a launcher is detected and refused with a clear message.

#include "core/Error.h"
#include "study/Distributed.h"

namespace viscera::study {

MpiSession::MpiSession() {
  throw Error("this viscera was built without MPI (VISCERA_WITH_MPI=OFF); run the search with --jobs, or --shard "
              "and `viscera search merge`, or rebuild with libopenmpi-dev installed");
}
MpiSession::~MpiSession() = default;
std::unique_ptr<CandidateExecutor> MpiSession::coordinator() const { return nullptr; }
void MpiSession::stopWorkers() const {}
void MpiSession::serve(const CandidateExecutor::Evaluate&) const {}

}  // namespace viscera::study
