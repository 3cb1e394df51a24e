#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "pipeline/ordered_parallel.hpp"
#include "pcdp/pipeline/work_share.hpp"

using namespace pcdp;

// The suite's name holds "Threads": scripts/tsan.sh runs these under ThreadSanitizer.
TEST(OrderedParallelThreads, AWaitingWorkerTakesTasksOfTheLastItem) {
  // Three items on two workers: the last one hands 8 tasks to its WorkShare. Its first task waits
  // until another thread has started one of the others, which only a worker with nothing left to
  // produce can do. Without the sharing the wait times out and the test fails (it does not hang).
  std::mutex m;
  std::condition_variable cv;
  std::set<std::thread::id> task_threads;
  std::vector<int> runs(8, 0);
  bool helped = false;
  std::vector<std::size_t> consumed;
  detail::ordered_parallel<std::size_t>(
      3, 2, 3,
      [&](std::size_t k, WorkShare& share) -> std::size_t {
        if (k < 2) return 10 * k;
        const std::thread::id poster = std::this_thread::get_id();
        share.run(8, [&](std::size_t i) {
          std::unique_lock<std::mutex> lock(m);
          ++runs[i];
          task_threads.insert(std::this_thread::get_id());
          if (std::this_thread::get_id() != poster) helped = true;
          cv.notify_all();
          if (i == 0) cv.wait_for(lock, std::chrono::seconds(10), [&] { return helped; });
        });
        return 10 * k;
      },
      [&](std::size_t k, std::size_t v) {
        EXPECT_EQ(v, 10 * k);
        consumed.push_back(k);
      });
  EXPECT_EQ(consumed, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(runs, std::vector<int>(8, 1));  // each task exactly once
  EXPECT_TRUE(helped);
  EXPECT_EQ(task_threads.size(), 2u);
}

TEST(OrderedParallelThreads, TheLowestFailingTaskIsRethrownWhateverTheThreads) {
  // Tasks 5 and 3 throw; the caller sees task 3's error, with one thread or two. On threads it
  // comes once every task has finished (none is left running on a helper); alone, the tasks after
  // the failing one are not run.
  for (unsigned threads : {1u, 2u}) {
    std::atomic<int> ran{0};
    std::string error;
    std::vector<std::size_t> consumed;
    try {
      detail::ordered_parallel<int>(
          2, threads, 2,
          [&](std::size_t k, WorkShare& share) {
            if (k == 1)
              share.run(8, [&](std::size_t i) {
                ++ran;
                if (i == 3 || i == 5) throw std::runtime_error("task " + std::to_string(i));
              });
            return static_cast<int>(k);
          },
          [&](std::size_t k, int) { consumed.push_back(k); });
    } catch (const std::runtime_error& e) {
      error = e.what();
    }
    EXPECT_EQ(error, "task 3") << threads << " thread(s)";
    EXPECT_EQ(ran.load(), threads == 1 ? 4 : 8) << threads << " thread(s)";
    EXPECT_EQ(consumed, std::vector<std::size_t>{0}) << threads << " thread(s)";  // item 1 failed: not consumed
  }
}

TEST(OrderedParallelThreads, ItemsWithoutAWorkShareStillWork) {
  // produce(k) without the second argument (check_consistency's use before) and a single item on
  // two threads (no shortcut any more: the second worker may help it).
  for (std::size_t n : {0u, 1u, 5u}) {
    std::vector<std::size_t> consumed;
    detail::ordered_parallel<std::size_t>(
        n, 2, 2, [](std::size_t k) { return k * k; },
        [&](std::size_t k, std::size_t v) {
          EXPECT_EQ(v, k * k);
          consumed.push_back(k);
        });
    ASSERT_EQ(consumed.size(), n);
    for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(consumed[k], k);
  }
}

TEST(OrderedParallelThreads, ParallelForRunsEachIndexOnceAndRethrowsTheLowestError) {
  for (unsigned threads : {1u, 2u, 3u}) {
    std::vector<std::atomic<int>> hits(1000);
    detail::parallel_for(hits.size(), threads, [&](std::size_t i) { ++hits[i]; });
    for (std::size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << i << ", " << threads << " thread(s)";
    std::string error;
    std::atomic<int> ran{0};
    try {
      detail::parallel_for(100, threads, [&](std::size_t i) {
        ++ran;
        if (i % 40 == 17) throw std::runtime_error("index " + std::to_string(i));  // 17, 57, 97
      });
    } catch (const std::runtime_error& e) {
      error = e.what();
    }
    EXPECT_EQ(error, "index 17") << threads << " thread(s)";
    EXPECT_EQ(ran.load(), 100) << threads << " thread(s)";  // an error does not stop the others
  }
}

TEST(OrderedParallelThreads, SerialWorkShareRunsTasksInOrderAndStopsAtTheFirstError) {
  std::vector<std::size_t> order;
  WorkShare::serial().run(4, [&](std::size_t i) { order.push_back(i); });
  EXPECT_EQ(order, (std::vector<std::size_t>{0, 1, 2, 3}));
  order.clear();
  EXPECT_THROW(WorkShare::serial().run(4,
                                       [&](std::size_t i) {
                                         order.push_back(i);
                                         if (i == 1) throw std::runtime_error("task 1");
                                       }),
               std::runtime_error);
  EXPECT_EQ(order, (std::vector<std::size_t>{0, 1}));
}
