// The MPI side of Distributed.h. Messages: rank 0 sends a candidate's values (kWork, doubles) or an
// empty kStop; a rank answers with the result row (kResult) or the message of an input error
// (kError). Rank 0 polls with MPI_Iprobe between its own evaluations, which run on a thread that
// never calls MPI (MPI_THREAD_FUNNELED).
#include <mpi.h>

#include <chrono>
#include <deque>
#include <future>
#include <map>
#include <string>
#include <thread>

#include "core/Error.h"
#include "study/Distributed.h"

namespace viscera::study {

namespace {

enum Tag : int { kWork = 1, kStop = 2, kResult = 3, kError = 4 };

std::string receiveText(int source, int tag, MPI_Status& status) {
  int n = 0;
  MPI_Get_count(&status, MPI_CHAR, &n);
  std::string text(static_cast<size_t>(n), '\0');
  MPI_Recv(text.data(), n, MPI_CHAR, source, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return text;
}

void sendWork(int rank, const std::vector<double>& values) {
  MPI_Send(values.data(), static_cast<int>(values.size()), MPI_DOUBLE, rank, kWork, MPI_COMM_WORLD);
}

class Coordinator : public CandidateExecutor {
 public:
  explicit Coordinator(int size) : size_(size) {}

  void run(const std::vector<std::vector<double>>& todo, const Evaluate& evaluate, const Done& done) override {
    std::deque<size_t> queue;
    for (size_t i = 0; i < todo.size(); ++i) queue.push_back(i);
    std::map<int, size_t> busy;  // rank -> candidate
    std::string failure;
    for (int r = 1; r < size_ && !queue.empty(); ++r) {
      sendWork(r, todo[queue.front()]);
      busy[r] = queue.front();
      queue.pop_front();
    }
    std::future<CandidateResult> local;
    bool localBusy = false;
    while (!busy.empty() || localBusy || (!queue.empty() && failure.empty())) {
      if (!localBusy && !queue.empty() && failure.empty()) {
        const size_t i = queue.front();
        queue.pop_front();
        local = std::async(std::launch::async, [&evaluate, &todo, i] { return evaluate(todo[i]); });
        localBusy = true;
      }
      bool progressed = false;
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (flag) {
        progressed = true;
        const int from = status.MPI_SOURCE;
        const std::string text = receiveText(from, status.MPI_TAG, status);
        busy.erase(from);
        if (status.MPI_TAG == kError) {
          if (failure.empty()) failure = text;
        } else {
          CandidateResult r;
          try {
            r = parseResult(text, todo.front().size());
          } catch (const std::exception& e) {
            throw Error(std::string("rank ") + std::to_string(from) + " sent a malformed result (" + e.what() + ")");
          }
          done(std::move(r));
        }
        if (!queue.empty() && failure.empty()) {
          sendWork(from, todo[queue.front()]);
          busy[from] = queue.front();
          queue.pop_front();
        }
      }
      if (localBusy && local.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        progressed = true;
        localBusy = false;
        try {
          done(local.get());
        } catch (const Error& e) {
          if (failure.empty()) failure = e.what();
        }
      }
      if (!progressed) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (!failure.empty()) throw Error(failure);
  }

 private:
  int size_;
};

}  // namespace

MpiSession::MpiSession() {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiSession::~MpiSession() { MPI_Finalize(); }

std::unique_ptr<CandidateExecutor> MpiSession::coordinator() const { return std::make_unique<Coordinator>(size_); }

void MpiSession::stopWorkers() const {
  for (int r = 1; r < size_; ++r) MPI_Send(nullptr, 0, MPI_CHAR, r, kStop, MPI_COMM_WORLD);
}

void MpiSession::serve(const CandidateExecutor::Evaluate& evaluate) const {
  for (;;) {
    MPI_Status status;
    MPI_Probe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
    if (status.MPI_TAG == kStop) {
      MPI_Recv(nullptr, 0, MPI_CHAR, 0, kStop, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      return;
    }
    int n = 0;
    MPI_Get_count(&status, MPI_DOUBLE, &n);
    std::vector<double> values(static_cast<size_t>(n));
    MPI_Recv(values.data(), n, MPI_DOUBLE, 0, kWork, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    std::string reply;
    int tag = kResult;
    try {
      reply = formatResult(evaluate(values));
    } catch (const Error& e) {
      reply = e.what();
      tag = kError;
    }
    MPI_Send(reply.data(), static_cast<int>(reply.size()), MPI_CHAR, 0, tag, MPI_COMM_WORLD);
  }
}

}  // namespace viscera::study
