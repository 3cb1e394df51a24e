// Independent tasks, and who runs them: the plain callback through which formats and models hand
// out work that may run on several threads, without knowing the scheduler. The pipeline passes its
// WorkShare (pcdp/pipeline/work_share.hpp converts to RunTasks); other callers run them in order.
#pragma once

#include <cstddef>
#include <functional>

namespace pcdp {

/// Runs task(0) ... task(n - 1), each exactly once, on the calling thread and perhaps others;
/// returns when every task has run. If tasks throw, the exception of the lowest index that threw
/// is rethrown once no task runs any more. What a task computes must not depend on the thread
/// that runs it.
using RunTasks = std::function<void(std::size_t n, const std::function<void(std::size_t)>& task)>;

/// RunTasks on the calling thread, in order, up to the first task that throws.
inline void run_in_order(std::size_t n, const std::function<void(std::size_t)>& task) {
  for (std::size_t i = 0; i < n; ++i) task(i);
}

}  // namespace pcdp
