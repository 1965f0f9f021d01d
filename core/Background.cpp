#include "core/Background.h"

namespace viscera {

BackgroundQueue::BackgroundQueue(size_t capacity) : capacity_(capacity < 1 ? 1 : capacity), worker_([this] { loop(); }) {}

BackgroundQueue::~BackgroundQueue() {
  {
    std::unique_lock<std::mutex> lock(m_);
    changed_.wait(lock, [this] { return (tasks_.empty() && !busy_) || error_; });
    stop_ = true;
  }
  changed_.notify_all();
  worker_.join();
}

void BackgroundQueue::submit(std::function<void()> task) {
  std::unique_lock<std::mutex> lock(m_);
  changed_.wait(lock, [this] { return tasks_.size() < capacity_ || error_; });
  rethrow();
  tasks_.push_back(std::move(task));
  changed_.notify_all();
}

void BackgroundQueue::flush() {
  std::unique_lock<std::mutex> lock(m_);
  changed_.wait(lock, [this] { return (tasks_.empty() && !busy_) || error_; });
  rethrow();
}

void BackgroundQueue::rethrow() {
  if (!error_) return;
  std::exception_ptr e = error_;
  error_ = nullptr;  // reported once
  std::rethrow_exception(e);
}

void BackgroundQueue::loop() {
  std::unique_lock<std::mutex> lock(m_);
  for (;;) {
    changed_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
    if (tasks_.empty()) return;  // stopping, nothing left
    std::function<void()> task = std::move(tasks_.front());
    tasks_.pop_front();
    busy_ = true;
    lock.unlock();
    std::exception_ptr failed;
    try {
      task();
    } catch (...) {
      failed = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (failed && !error_) {
      error_ = failed;
      tasks_.clear();  // what came after a failed frame is not written
    }
    changed_.notify_all();
  }
}

}  // namespace viscera
