// LAS (ASPRS LIDAR Data Exchange Format) 1.2, 1.3 and 1.4: a strict reader of point data record
// formats 0-3 and 6-8 (uncompressed; LAZ is refused), and a writer of LAS 1.2 point format 1.
//
// Own implementation: no Debian library reads LAS. The reader checks every header field against
// the specification and the file's size before it allocates, in checked 64-bit arithmetic, and its
// messages name the file, the header field (or VLR, or point index) and the rule broken.
//
// Coordinates are X * scale + offset in the file's units. LAS does not say which unit: the CRS
// does. The reader takes the linear unit from the GeoTIFF keys VLR (LASF_Projection 34735:
// ProjLinearUnitsGeoKey, else VerticalUnitsGeoKey) or, failing that, from the OGC WKT VLR (2112,
// the last linear UNIT of the projected CRS); a file without either has an unknown unit.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"

namespace pcdp::io {

struct LasHeader {
  int version_major = 1;
  int version_minor = 2;
  std::uint16_t header_size = 0;
  std::uint32_t offset_to_points = 0;
  std::uint32_t vlr_count = 0;
  int point_format = 0;             ///< 0-3 or 6-8
  std::uint16_t record_length = 0;  ///< bytes per point: at least the format's size (more: extra bytes)
  std::uint64_t points = 0;         ///< the 1.4 64-bit count when present, else the legacy 32-bit one
  double scale[3] = {0, 0, 0};
  double offset[3] = {0, 0, 0};
  double min[3] = {0, 0, 0};        ///< as the header states them
  double max[3] = {0, 0, 0};
  std::string unit_name;            ///< "metre", "foot", "US survey foot", ... or "" when the file does not say
  double unit_to_metre = 0.0;       ///< metres per file unit; 0 when unknown
  std::string unit_source;          ///< where the unit was read ("GeoKey ProjLinearUnitsGeoKey = 9002", "WKT UNIT[...]")
};

struct LasCloud {
  LasHeader header;
  std::vector<Eigen::Vector3d> xyz;        ///< file units
  std::vector<float> intensity;            ///< the LAS intensity, one per point
  std::vector<std::uint8_t> classification;  ///< the ASPRS class, one per point
};

/// The smallest record of a point data format (0-3, 6-8), or 0 for any other format.
std::size_t las_point_size(int format);

/// True when the file starts with the LAS signature "LASF" (no other check).
bool has_las_signature(const std::string& path);

/// Reads and checks the header and the VLRs only. Throws InputError (file, field, rule).
LasHeader read_las_header(const std::string& path);
/// Reads the whole file. Throws InputError (file, field or point index, rule).
LasCloud read_las(const std::string& path);

/// Points to write as LAS or PLY: x y z in map units and, optionally, intensity and a label per
/// point (empty vectors when absent).
struct CloudOut {
  std::vector<Eigen::Vector3d> xyz;
  std::vector<float> intensity;
  std::vector<std::uint8_t> label;
};

/// LAS 1.2, point data record format 1 (28 bytes), scale 0.001 (mm), offset the bounding box's
/// centre rounded to a metre; intensity clamped to 0..65535; label in the user data byte,
/// classification 1 (unclassified). Points with a non-finite coordinate are not written (LAS has no
/// "no point"); returns the number written. Throws LasSpanError, before writing, when the cloud
/// spans more than an int32 of millimetres (+-2,147 km about the centre), OutputError when it
/// cannot be written.
std::uint64_t write_las(const std::string& path, const CloudOut& cloud);

/// The cloud is wider than a LAS file holds: `first` and `second` (indices into CloudOut::xyz) lie
/// `span` metres apart along `axis` (0 x, 1 y, 2 z). An OutputError: the caller that knows where
/// the points came from names them.
class LasSpanError : public OutputError {
 public:
  LasSpanError(const std::string& what, std::size_t a, std::size_t b, double metres, int along)
      : OutputError(what), first(a), second(b), span(metres), axis(along) {}
  std::size_t first, second;
  double span;
  int axis;
};
/// Binary little-endian PLY: double x y z, then float intensity and uchar label when present.
void write_ply(const std::string& path, const CloudOut& cloud);

enum class CloudFormat { kPcd, kPly, kLas };
/// The format an output path asks for by its extension (.pcd, .ply, .las, any case). Throws
/// ConfigError naming `what` (the option), the extension and the supported ones otherwise.
CloudFormat cloud_format_of(const std::string& path, const std::string& what);

}  // namespace pcdp::io
