// Executor without gRPC (so this also runs under ThreadSanitizer): tasks run off the caller's
// thread, in order, a few at once; cancelling reaches queued, running and later tasks.
#include "server/service/executor.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "server/core/testing/wait.h"

namespace actopo::service {
namespace {

Executor::CancelFlag Flag() { return std::make_shared<std::atomic<bool>>(false); }

TEST(Executor, RunsEveryTaskWithAtMostItsThreads) {
  std::atomic<int> running{0}, most{0}, done{0};
  {
    Executor work("test", 2);
    for (int i = 0; i < 20; ++i) {
      work.Run(Flag(), [&] {
        const int now = ++running;
        for (int m = most; now > m && !most.compare_exchange_weak(m, now);) {
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        --running;
        ++done;
      });
    }
    // A task counts as done only after its body returns, so `done` reaches 20 a moment before
    // `pending` reaches 0; every task is queued by now, so pending 0 means all have finished.
    ASSERT_TRUE(actopo::testing::WaitUntil([&] { return work.pending() == 0; }));
    EXPECT_EQ(done, 20);
  }
  EXPECT_EQ(done, 20);
  EXPECT_LE(most, 2);
}

// Tasks leave one queue in the order given. With two threads, two tasks taken one after the
// other may still record themselves in either order, so the order is checked on one thread.
TEST(Executor, StartsTasksInTheOrderGiven) {
  std::mutex mu;
  std::vector<int> started;
  {
    Executor work("test", 1);
    for (int i = 0; i < 20; ++i) {
      work.Run(Flag(), [&, i] {
        std::lock_guard<std::mutex> lock(mu);
        started.push_back(i);
      });
    }
    ASSERT_TRUE(actopo::testing::WaitUntil([&] {
      std::lock_guard<std::mutex> lock(mu);
      return started.size() == 20u;
    }));
  }
  ASSERT_EQ(started.size(), 20u);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(started[i], i);
}

TEST(Executor, CancelAllReachesRunningQueuedAndLaterTasks) {
  Executor work("test", 1);
  std::atomic<bool> release{false}, first_started{false};
  const auto running = Flag(), queued = Flag(), later = Flag();
  std::atomic<int> finished{0};
  work.Run(running, [&] {
    first_started = true;
    while (!running->load() && !release) std::this_thread::yield();
    ++finished;
  });
  work.Run(queued, [&] { ++finished; });
  ASSERT_TRUE(actopo::testing::WaitUntil([&] { return first_started.load(); }));
  EXPECT_EQ(work.pending(), 2);
  work.CancelAll();
  EXPECT_TRUE(running->load());
  EXPECT_TRUE(queued->load());
  work.Run(later, [&] { ++finished; });
  EXPECT_TRUE(later->load());
  // Cancelled tasks still run, to finish their calls.
  ASSERT_TRUE(actopo::testing::WaitUntil([&] { return finished == 3; }));
  EXPECT_EQ(finished, 3);
}

TEST(Executor, DestructorCancelsAndWaits) {
  std::atomic<int> finished{0};
  const auto flag = Flag();
  {
    Executor work("test", 1);
    work.Run(flag, [&] {
      while (!flag->load()) std::this_thread::yield();
      ++finished;
    });
    work.Run(Flag(), [&] { ++finished; });
  }
  EXPECT_EQ(finished, 2);
}

}  // namespace
}  // namespace actopo::service
