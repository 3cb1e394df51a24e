// The coordinate reference system of an elevation grid: checked against PROJ's database at
// config time (normalize_crs in pcdp/io/geotiff.hpp), written and read as GeoKeys.
#pragma once

#include <string>

#include "tiff_format.hpp"

namespace pcdp::io::detail {

/// The GeoKeys of a normalised CRS (normalize_crs()): "" none; "EPSG:N" a projected CRS
/// (GTModelTypeGeoKey 1, GTRasterTypeGeoKey PixelIsArea, ProjectedCSTypeGeoKey N). Anything
/// else: std::invalid_argument.
GeoKeys crs_geokeys(const std::string& crs);
/// The CRS that GeoKeys state, as normalize_crs() writes it: "EPSG:N" for an EPSG code
/// (projected or geographic), the citation of a user-defined CRS, "" when there are no GeoKeys.
std::string crs_of(const GeoKeys& k);

}  // namespace pcdp::io::detail
