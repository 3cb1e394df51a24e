#include "pcdp/pipeline/work_share.hpp"

#include "pipeline/ordered_parallel.hpp"

namespace pcdp {

namespace {
class SerialShare final : public WorkShare {
 public:
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    for (std::size_t i = 0; i < n; ++i) task(i);  // the first exception is the lowest index's
  }
};

class ThreadsShare final : public WorkShare {
 public:
  explicit ThreadsShare(unsigned threads) : threads_(threads) {}
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    detail::parallel_for(n, threads_, task);
  }

 private:
  unsigned threads_;
};
}  // namespace

WorkShare& WorkShare::serial() {
  static SerialShare s;  // stateless: one for every caller and thread
  return s;
}

std::unique_ptr<WorkShare> WorkShare::threads(unsigned threads) {
  return std::make_unique<ThreadsShare>(threads < 1 ? 1 : threads);
}

}  // namespace pcdp
