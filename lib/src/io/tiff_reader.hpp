// A reader of float32 GeoTIFFs through libtiff: those pcd_pipeline writes (tiff_writer.hpp) and
// those GDAL wrote for it before or re-tiled since (COMPRESS=DEFLATE or none, INTERLEAVE=BAND or
// PIXEL, strips or tiles, classic TIFF or BigTIFF, a COG): `merge` reads elevation grids back
// without linking GDAL, whose hundred-odd shared libraries cost every start of the command line
// tool about 50 ms (docs/performance.md).
//
// libtiff parses the file (the maintained parser: merge reads files from other machines); its
// messages go to the handle, never to stderr, and come back as an InputError naming the file and
// the strip or tile. On top of libtiff this reader asks for 32-bit IEEE float samples, DEFLATE or
// no compression, no predictor; the GeoTIFF pixel scale and tie point, the GeoKeys and GDAL's
// metadata tag. Every block is checked against the file before it is decoded (it lies in the
// file; its bytes can hold its rows: DEFLATE expands at most 1032 to 1). Strips are decoded a row
// at a time (libtiff's scanline reader, a handle per band of a band-interleaved file), so a
// damaged or hostile file claiming a huge strip costs a row (a 1 MB file claiming 3500 x 3500 x 22
// floats: 308 kB); a tile is decoded whole (its size checked against the file's first). A block
// with offset and byte count 0 is not stored (a sparse file, as GDAL's SPARSE_OK and
// tiff_writer.hpp's tiles write them): nodata.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "tiff_format.hpp"

namespace pcdp::io::detail {

/// What the directory says of the raster.
struct FloatTiffInfo {
  int width = 0, height = 0, bands = 0;
  double pixel_scale[3] = {0, 0, 0};        ///< ModelPixelScaleTag (33550); zeros: absent
  double tiepoint[6] = {0, 0, 0, 0, 0, 0};  ///< ModelTiepointTag (33922), the first tie point
  bool georeferenced = false;               ///< both tags were present
  std::string gdal_metadata;                ///< GDAL_METADATA (42112) XML; empty: absent
  GeoKeys geokeys;                          ///< model 0: no GeoKey directory
};

/// One row of one block (strip or tile): `cols` pixels from (row, col0), every band's samples.
struct FloatTiffPiece {
  int row = 0, col0 = 0, cols = 0;
  std::vector<std::vector<float>> bands;
};

/// The raster a strip of rows at a time (a row of tiles, in a tiled file), every band, or a row of
/// a block at a time (for_each_piece): not the raster, so a caller can convert rows as they come.
class FloatTiffRows {
 public:
  /// Opens `path` and reads and checks its directory. Throws InputError naming `path`.
  explicit FloatTiffRows(const std::string& path);
  ~FloatTiffRows();
  FloatTiffRows(const FloatTiffRows&) = delete;
  FloatTiffRows& operator=(const FloatTiffRows&) = delete;

  const FloatTiffInfo& info() const;
  /// The next strip of rows (or row of tiles), top first: rows `first` .. `first + count - 1`,
  /// band b's in `rows[b]` (count * width floats, row `first` first). False after the last.
  /// Throws InputError naming the file and the strip or tile when one is damaged.
  /// Blocks not stored (offset and byte count 0: a sparse file) read as NaN.
  bool next(int& first, int& count, std::vector<std::vector<float>>& rows);
  /// f(piece) for every row of every stored block, a block at a time (rows of blocks from the
  /// top, blocks left to right, rows down): memory is a row of a block of each band, however
  /// large the strips or tiles, the raster, or the claims of a damaged file; a block's memory
  /// grows as its data arrives. Blocks not stored (sparse) are skipped. Continues after next().
  void for_each_piece(const std::function<void(const FloatTiffPiece&)>& f);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct FloatTiffData : FloatTiffInfo {
  std::vector<std::vector<float>> planes;  ///< one per band, width * height, row 0 first
};

/// Reads the whole raster (FloatTiffRows, every strip). Throws InputError naming `path` and
/// what is wrong.
FloatTiffData read_float_tiff(const std::string& path);

/// The dataset items (no `sample` attribute) of GDAL_METADATA XML, name and value, the value
/// unescaped twice as GDAL's reader does (gdal_metadata() in tiff_writer.hpp escapes it twice).
std::vector<std::pair<std::string, std::string>> gdal_metadata_items(const std::string& xml);

}  // namespace pcdp::io::detail
