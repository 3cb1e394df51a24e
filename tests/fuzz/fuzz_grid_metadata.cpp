// The merge metadata of an elevation grid (GDAL_METADATA XML: PCDP_RESOLUTION, PCDP_BAND,
// PCDP_MIN_SUPPORT), parsed strictly: anything malformed is an InputError, nothing else.
#include <string>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    pcdp::io::parse_grid_metadata(std::string(reinterpret_cast<const char*>(data), size), "fuzz.tif");
  } catch (const pcdp::InputError&) {
  }
  return 0;
}
