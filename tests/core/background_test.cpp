// BackgroundQueue: tasks run in order beside the caller, at most `capacity` wait, and the first
// error comes back to the caller (once).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/Background.h"

using viscera::BackgroundQueue;

TEST(BackgroundQueue, RunsTasksInOrderAndFlushWaitsForThem) {
  std::vector<int> done;
  BackgroundQueue q(2);
  for (int i = 0; i < 50; ++i) q.submit([&done, i] { done.push_back(i); });
  q.flush();
  ASSERT_EQ(done.size(), 50u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(done[i], i);
}

TEST(BackgroundQueue, SubmitBlocksWhileTheQueueIsFull) {
  std::atomic<bool> release{false};
  std::atomic<int> started{0};
  BackgroundQueue q(1);
  q.submit([&] {
    ++started;
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  });
  while (started == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  q.submit([] {});  // waits in the queue (capacity 1)
  std::atomic<bool> third{false};
  std::thread t([&] {
    q.submit([] {});
    third = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(third);  // blocked: the queue is full
  release = true;
  t.join();
  EXPECT_TRUE(third);
  q.flush();
}

TEST(BackgroundQueue, TheFirstErrorComesBackOnceAndDropsWhatFollowed) {
  std::atomic<int> ran{0};
  std::atomic<bool> go{false};
  BackgroundQueue q(8);
  q.submit([&] {
    while (!go) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ++ran;
  });
  q.submit([] { throw std::runtime_error("disk full"); });
  q.submit([&] { ++ran; });  // dropped: it follows the failed one
  go = true;
  try {
    q.flush();
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "disk full");
  }
  EXPECT_EQ(ran, 1);
  EXPECT_NO_THROW(q.flush());  // reported once
  q.submit([&] { ++ran; });    // the queue goes on
  q.flush();
  EXPECT_EQ(ran, 2);
}
