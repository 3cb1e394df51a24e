// Runs produce(k) for k = 0..n-1 on `threads` worker threads and consume(k, result) on the calling
// thread in order of k, with at most `window` results produced ahead of the one being consumed
// (bounded memory). An exception thrown by produce(k) is rethrown on the calling thread when k's
// turn comes, so the error a run reports does not depend on the thread count; nothing after it is
// consumed. With threads <= 1 everything runs inline on the calling thread.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace pcdp::detail {

template <class T, class Produce, class Consume>
void ordered_parallel(std::size_t n, unsigned threads, std::size_t window, Produce produce, Consume consume) {
  if (threads <= 1 || n <= 1) {
    for (std::size_t k = 0; k < n; ++k) consume(k, produce(k));
    return;
  }
  struct Slot {
    std::optional<T> value;
    std::exception_ptr error;
  };
  std::mutex m;
  std::condition_variable cv;
  std::map<std::size_t, Slot> done;
  std::size_t next = 0, consumed = 0;
  bool stop = false;
  const auto worker = [&] {
    for (;;) {
      std::size_t k;
      {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [&] { return stop || next >= n || next < consumed + window; });
        if (stop || next >= n) return;
        k = next++;
      }
      Slot s;
      try {
        s.value.emplace(produce(k));
      } catch (...) {
        s.error = std::current_exception();
      }
      {
        std::lock_guard<std::mutex> lock(m);
        done.emplace(k, std::move(s));
      }
      cv.notify_all();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t) pool.emplace_back(worker);
  const auto finish = [&] {
    {
      std::lock_guard<std::mutex> lock(m);
      stop = true;
    }
    cv.notify_all();
    for (auto& t : pool) t.join();
  };
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

}  // namespace pcdp::detail
