// Work done beside the caller, in order: a run's exporters hand their frames to one so that
// encoding, compressing and writing them overlap the next steps instead of stalling them.
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace viscera {

class BackgroundQueue {
 public:
  // At most `capacity` tasks wait; submit() blocks beyond that (memory stays bounded).
  explicit BackgroundQueue(size_t capacity = 4);
  // Finishes the tasks waiting, ignoring their errors (flush() reports them).
  ~BackgroundQueue();
  BackgroundQueue(const BackgroundQueue&) = delete;
  BackgroundQueue& operator=(const BackgroundQueue&) = delete;

  // Runs `task` after the ones before it. Rethrows the error of an earlier task, if one failed
  // (that task's successors are dropped).
  void submit(std::function<void()> task);
  // Waits until every task submitted has run; rethrows the first error.
  void flush();

 private:
  void loop();
  void rethrow();
  size_t capacity_;
  std::mutex m_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> tasks_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread worker_;
};

}  // namespace viscera
