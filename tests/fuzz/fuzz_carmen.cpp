#include "fuzz_common.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/import/carmen.hpp"

// A CARMEN log, plain or gzip (zlib reads both): a malformed one must be an InputError, never a
// crash, an overflow or an unbounded allocation; an accepted one gives consistent passes.
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz_file(data, size, ".log");
  try {
    const pcdp::io::ImportedCarmen r = pcdp::io::import_carmen(path);
    if (r.poses.size() != 2 * r.passes.size()) __builtin_trap();
    for (const pcdp::Pass& p : r.passes)
      if (p.size() == 0 || p.bearing.size() != p.size() || p.line_count() != 1) __builtin_trap();
    for (std::size_t k = 1; k < r.poses.size(); ++k)
      if (!(r.poses[k].stamp > r.poses[k - 1].stamp)) __builtin_trap();
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
