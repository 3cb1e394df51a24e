#include "pcdp/work_share.hpp"

namespace pcdp {

namespace {
class SerialShare final : public WorkShare {
 public:
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    for (std::size_t i = 0; i < n; ++i) task(i);  // the first exception is the lowest index's
  }
};
}  // namespace

WorkShare& WorkShare::serial() {
  static SerialShare s;  // stateless: one for every caller and thread
  return s;
}

}  // namespace pcdp
