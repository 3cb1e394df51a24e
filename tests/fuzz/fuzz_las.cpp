#include <stdexcept>

#include "fuzz_common.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/las.hpp"

// The LAS reader: header, VLRs (GeoKeys, WKT), counts against the file size, the points.
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz_file(data, size, ".las");
  try {
    pcdp::io::read_las(path);
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
