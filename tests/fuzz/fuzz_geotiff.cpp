#include <stdexcept>

#include "fuzz_common.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz_file(data, size, ".tif");
  try {
    pcdp::io::read_elevation_geotiff(path);  // TIFF directory, strips or tiles, DEFLATE, metadata, cells
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
