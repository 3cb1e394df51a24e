// Work inside one pass that threads with nothing else to do may share.
//
// The pipeline runs passes on worker threads, one pass per thread. With few passes left, a worker
// may have no pass to take while another is still busy with the last one (8 passes on 2 threads
// end with one pass running alone). A stage whose per-pass computation divides into independent
// tasks hands them to WorkShare::run: the calling thread runs them, and a waiting worker takes
// some. What a task computes must not depend on which thread runs it, so the results stay
// identical whatever the thread count.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>

#include "pcdp/core/tasks.hpp"

namespace pcdp {

class WorkShare {
 public:
  virtual ~WorkShare() = default;
  /// Runs task(0) ... task(n - 1), each exactly once, on the calling thread and perhaps on
  /// threads that would otherwise wait; returns when every task has run. If tasks throw, the
  /// exception of the lowest index that threw is rethrown once no task runs any more (the tasks
  /// after it may or may not have run).
  virtual void run(std::size_t n, const std::function<void(std::size_t)>& task) = 0;
  /// Runs the tasks in order on the calling thread, up to the first that throws.
  static WorkShare& serial();
  /// Runs each run()'s tasks on the calling thread and threads - 1 threads started for it (a
  /// thread that finishes a task takes the next); every task runs even when one throws. For
  /// callers outside a pipeline run, e.g. writing a merged elevation grid with threads.
  static std::unique_ptr<WorkShare> threads(unsigned threads);
  /// The tasks of a format or a model (pcdp/core/tasks.hpp) run through this WorkShare.
  operator RunTasks() {
    return [this](std::size_t n, const std::function<void(std::size_t)>& task) { run(n, task); };
  }
};

}  // namespace pcdp
