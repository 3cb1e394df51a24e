// What tiff_writer.cpp and tiff_reader.cpp share: a libtiff handle whose errors and warnings go
// to the handle (not stderr), and the tags libtiff must know to read and write them: GeoTIFF's
// (libgeotiff's tag extender) and GDAL's metadata and nodata.
#pragma once

#include <geotiff/xtiffio.h>  // TIFFTAG_GEOPIXELSCALE, TIFFTAG_GEOTIEPOINTS
#include <tiffio.h>

#include <cstdint>
#include <memory>
#include <string>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the TIFF writer hands libtiff float samples as they lie in memory: little-endian hosts only"
#endif

namespace pcdp::io::detail {

/// The GeoKeys of a raster's coordinate reference system (GeoTIFF 1.1, section 7).
struct GeoKeys {
  int model = 0;        ///< GTModelTypeGeoKey: 0 none (no keys), 1 projected, 2 geographic, 32767 user-defined
  int epsg = 0;         ///< ProjectedCSTypeGeoKey (model 1) or GeographicTypeGeoKey (model 2); 0: none
  std::string citation; ///< GTCitationGeoKey; empty: none
};

constexpr ttag_t kTagGdalMetadata = 42112, kTagGdalNodata = 42113;

/// libtiff's messages for one handle, the first error and the first warning (the first names
/// the rule broken). Nothing is printed.
struct TiffMessages {
  std::string error, warning;
};

struct TiffCloser {
  void operator()(TIFF* t) const;
};
using TiffPtr = std::unique_ptr<TIFF, TiffCloser>;

/// TIFFOpenExt(path, mode) with handlers that collect libtiff's messages into `msgs` (which must
/// outlive the handle), GeoTIFF's and GDAL's tags registered, and at most `max_alloc` bytes for
/// any one allocation libtiff makes (0: libtiff's default). Null when libtiff refuses: msgs.error
/// then says why.
TiffPtr open_tiff(const std::string& path, const char* mode, TiffMessages& msgs, std::uint64_t max_alloc = 0);

}  // namespace pcdp::io::detail
