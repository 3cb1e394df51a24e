// Runs produce(k) for k = 0..n-1 on `threads` worker threads and consume(k, result) on the calling
// thread in order of k, with at most `window` results produced ahead of the one being consumed
// (bounded memory). An exception thrown by produce(k) is rethrown on the calling thread when k's
// turn comes, so the error a run reports does not depend on the thread count; nothing after it is
// consumed. With threads <= 1 everything runs inline on the calling thread.
//
// produce may take a WorkShare& as its second argument (work_share.hpp): the tasks it hands to
// WorkShare::run are run by the producing thread and by workers that have no k to take (all
// taken, or the window is full), so the last items of a run do not run alone while the other
// workers wait.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <type_traits>
#include <vector>

#include "pcdp/pipeline/work_share.hpp"

namespace pcdp::detail {

/// The tasks handed to WorkShare::run by producing threads, and the lock and condition the
/// workers of ordered_parallel share with them.
class SharedTasks final : public WorkShare {
 public:
  std::mutex m;
  std::condition_variable cv;

  /// With `lock` (on m) held: whether a task waits for a thread.
  bool waiting() const { return !jobs_.empty(); }
  /// With `lock` held: claims a waiting task and runs it, the lock released meanwhile. False
  /// when none waits.
  bool help(std::unique_lock<std::mutex>& lock) {
    if (jobs_.empty()) return false;
    Job& job = *jobs_.front();
    const std::size_t i = claim(job);
    lock.unlock();
    run_task(job, i);
    lock.lock();
    return true;
  }

  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    if (n == 0) return;
    Job job;
    job.task = &task;
    job.n = n;
    {
      std::lock_guard<std::mutex> lock(m);
      jobs_.push_back(&job);
    }
    cv.notify_all();
    for (;;) {  // this job's tasks, until every one is claimed
      std::size_t i;
      {
        std::lock_guard<std::mutex> lock(m);
        if (job.claimed == job.n) break;
        i = claim(job);
      }
      run_task(job, i);
    }
    std::unique_lock<std::mutex> lock(m);
    cv.wait(lock, [&] { return job.finished == job.n; });  // the ones other threads took
    if (job.error) std::rethrow_exception(job.error);
  }

 private:
  struct Job {
    const std::function<void(std::size_t)>* task = nullptr;
    std::size_t n = 0, claimed = 0, finished = 0;
    std::size_t error_index = ~std::size_t{0};
    std::exception_ptr error;
  };
  // With the lock held: the job's next task; the job leaves the queue with its last.
  std::size_t claim(Job& job) {
    const std::size_t i = job.claimed++;
    if (job.claimed == job.n) jobs_.erase(std::find(jobs_.begin(), jobs_.end(), &job));
    return i;
  }
  void run_task(Job& job, std::size_t i) {
    std::exception_ptr e;
    try {
      (*job.task)(i);
    } catch (...) {
      e = std::current_exception();
    }
    bool last;
    {
      std::lock_guard<std::mutex> lock(m);
      if (e && i < job.error_index) {
        job.error_index = i;
        job.error = e;
      }
      last = ++job.finished == job.n;  // once its poster sees this, the job is gone
    }
    if (last) cv.notify_all();
  }
  std::deque<Job*> jobs_;  // jobs with tasks not yet claimed, oldest first
};

template <class T, class Produce, class Consume>
void ordered_parallel(std::size_t n, unsigned threads, std::size_t window, Produce produce, Consume consume) {
  const auto call = [&](std::size_t k, WorkShare& share) -> T {
    if constexpr (std::is_invocable_v<Produce&, std::size_t, WorkShare&>)
      return produce(k, share);
    else
      return produce(k);
  };
  if (threads <= 1) {
    for (std::size_t k = 0; k < n; ++k) consume(k, call(k, WorkShare::serial()));
    return;
  }
  struct Slot {
    std::optional<T> value;
    std::exception_ptr error;
  };
  SharedTasks shared;
  std::mutex& m = shared.m;
  std::condition_variable& cv = shared.cv;
  std::map<std::size_t, Slot> done;
  std::size_t next = 0, consumed = 0, producing = 0;
  bool stop = false;
  const auto worker = [&] {
    std::unique_lock<std::mutex> lock(m);
    for (;;) {
      const auto can_produce = [&] { return next < n && next < consumed + window; };
      cv.wait(lock, [&] { return stop || can_produce() || shared.waiting() || (next >= n && producing == 0); });
      if (stop) return;
      if (can_produce()) {  // an item of its own before a share of another's
        const std::size_t k = next++;
        ++producing;
        lock.unlock();
        Slot s;
        try {
          s.value.emplace(call(k, shared));
        } catch (...) {
          s.error = std::current_exception();
        }
        lock.lock();
        done.emplace(k, std::move(s));
        --producing;
        cv.notify_all();
        continue;
      }
      if (shared.help(lock)) continue;
      return;  // every item produced: no task can come any more
    }
  };
  std::vector<std::thread> pool;
  const auto finish = [&] {
    {
      std::lock_guard<std::mutex> lock(m);
      stop = true;
    }
    cv.notify_all();
    for (auto& t : pool) t.join();
  };
  try {  // a thread that cannot start (no memory): the started ones stop and join, then it throws
    pool.reserve(threads);
    for (unsigned t = 0; t < threads; ++t) pool.emplace_back(worker);
  } catch (...) {
    finish();
    throw;
  }
  try {
    for (std::size_t k = 0; k < n; ++k) {
      Slot s;
      {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [&] { return done.count(k) != 0; });
        s = std::move(done.at(k));
        done.erase(k);
        consumed = k + 1;
      }
      cv.notify_all();
      if (s.error) std::rethrow_exception(s.error);
      consume(k, std::move(*s.value));
    }
  } catch (...) {
    finish();
    throw;
  }
  finish();
}

/// Runs task(i) for i = 0..n-1, each once, on the calling thread and threads - 1 others; a thread
/// that finishes one takes the next (pieces of unequal cost balance). Nothing is handed between
/// threads per piece: callers keep each piece's result in its own slot and read them in order
/// afterwards. If tasks throw, the exception of the lowest i is rethrown once all have finished.
template <class Task>
void parallel_for(std::size_t n, unsigned threads, Task task) {
  std::atomic<std::size_t> next{0};
  std::mutex m;
  std::size_t error_index = ~std::size_t{0};
  std::exception_ptr error;
  const auto work = [&] {
    for (std::size_t i; (i = next.fetch_add(1, std::memory_order_relaxed)) < n;) {
      try {
        task(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(m);
        if (i < error_index) {
          error_index = i;
          error = std::current_exception();
        }
      }
    }
  };
  std::vector<std::thread> pool;
  try {  // a thread that cannot start (no memory): the started ones finish, then it throws
    pool.reserve(threads);
    for (unsigned t = 1; t < threads && t < n; ++t) pool.emplace_back(work);
  } catch (...) {
    next.store(n);
    for (auto& t : pool) t.join();
    throw;
  }
  work();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace pcdp::detail
