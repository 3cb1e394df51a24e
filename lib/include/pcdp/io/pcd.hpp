// PCD v0.7 reading and writing (ascii, binary, binary_compressed), with strict checks and error
// messages that name the file, the header line or field, and the rule broken.
//
// Own implementation rather than pcl::PCDReader: the reader must reject truncated files and
// headers that claim more points than the file holds *before* allocating, and say exactly what is
// wrong; it also keeps PCL out of the core library. Round-trip tests check it against PCL.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "pcdp/core/field.hpp"

namespace pcdp::io {

/// A PCD field (name, TYPE, SIZE, COUNT): the core type, so that a pass can carry fields through.
using PcdField = pcdp::Field;

enum class PcdData { kAscii, kBinary, kBinaryCompressed };

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t width = 0;
  std::uint64_t height = 1;
  std::uint64_t points = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};
  /// From the comment "# map_origin X Y Z" (pcd_pipeline's products of a georeferenced run: map
  /// coordinates are x y z + map_origin); 0 without it.
  double map_origin[3] = {0, 0, 0};
  PcdData data = PcdData::kBinary;
  std::size_t data_offset = 0;  ///< byte offset of the data section in the file

  std::size_t point_bytes() const;
  int field_index(const std::string& name) const;  ///< -1 when absent
};

/// A PCD file held column by column: columns[i] holds fields[i] for every point, packed
/// (points * size * count bytes), in the file's point order.
struct PcdTable {
  PcdHeader header;
  std::vector<std::vector<std::uint8_t>> columns;
};

/// Reads and checks the header only. Throws InputError naming the file, the header line and the
/// rule: the path must be a regular file; each key appears once; at most 10,000 fields, names unique
/// ('_' excepted); every size (WIDTH x HEIGHT, SIZE x COUNT summed, points x point bytes) in checked
/// 64-bit arithmetic and within what the file's data section could hold in any encoding.
PcdHeader read_pcd_header(const std::string& path);
/// Reads the whole file. Throws InputError (file, header line or point, rule), also when memory runs
/// out. The ascii reader grows its columns with the points read, never by the header's claim.
PcdTable read_pcd(const std::string& path);

/// Decodes one numeric value of a field to double.
double field_value(const PcdField& f, const std::uint8_t* p);

/// Every value of field `k` (an index into header.fields) of a table, decoded to double.
std::vector<double> column_values(const PcdTable& t, std::size_t k);

/// Streaming writer of a binary PCD whose point count is known only at the end: the body goes
/// to `path + ".body"` and close() writes the header and body to `path`. Both are temporary
/// names chosen by the caller; nothing is renamed into place here.
class PcdWriter {
 public:
  PcdWriter(std::string path, std::vector<PcdField> fields);
  ~PcdWriter();
  PcdWriter(const PcdWriter&) = delete;
  PcdWriter& operator=(const PcdWriter&) = delete;

  const std::vector<PcdField>& fields() const { return fields_; }
  std::size_t point_bytes() const { return point_bytes_; }
  /// Appends `n` points from a row-major buffer of n * point_bytes() bytes.
  void append(const std::uint8_t* rows, std::size_t n);
  /// The map origin the points' x y z are relative to (pcdp/core/georef.hpp), written as the header
  /// comment "# map_origin X Y Z" when not 0 (PCL and other readers skip comment lines).
  void set_map_origin(double x, double y, double z) {
    map_origin_[0] = x;
    map_origin_[1] = y;
    map_origin_[2] = z;
  }
  /// The VIEWPOINT to write: tx ty tz qw qx qy qz (the sensor's pose in the cloud's frame);
  /// 0 0 0 1 0 0 0 unless set.
  void set_viewpoint(const double (&vp)[7]) { std::copy(vp, vp + 7, viewpoint_); }
  /// Writes the final file (WIDTH = points, HEIGHT = 1 unless `height` divides it).
  void close(std::uint64_t height = 1);
  std::uint64_t points() const { return points_; }

 private:
  std::string path_;
  std::string body_path_;
  std::vector<PcdField> fields_;
  std::size_t point_bytes_ = 0;
  std::uint64_t points_ = 0;
  double map_origin_[3] = {0, 0, 0};
  double viewpoint_[7] = {0, 0, 0, 1, 0, 0, 0};
  std::FILE* body_ = nullptr;
};

/// LZF decompression (the binary_compressed codec). Returns false when the input is corrupt or
/// does not decode to exactly `out_size` bytes.
bool lzf_decompress(const std::uint8_t* in, std::size_t in_size, std::uint8_t* out, std::size_t out_size);

}  // namespace pcdp::io
