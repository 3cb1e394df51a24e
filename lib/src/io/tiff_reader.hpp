// A small reader of the float32 GeoTIFFs pcd_pipeline writes (tiff_writer.hpp) and those GDAL
// wrote for it before (COMPRESS=DEFLATE, INTERLEAVE=BAND, strips): enough for `merge` to read
// elevation grids back without linking GDAL, whose hundred-odd shared libraries cost every start
// of the command line tool about 50 ms (docs/performance.md).
//
// It reads little-endian ("II") classic TIFF and BigTIFF, strips or tiles, uncompressed or
// DEFLATE, no predictor, 32-bit IEEE float samples, planar or interleaved; the GeoTIFF pixel
// scale and tie point; and GDAL's metadata tag. Anything else is an InputError naming the file
// and the rule. Every offset and count is checked against the file before use, and each strip or
// tile's rows against what its stored bytes can hold (DEFLATE expands at most 1032 to 1) before it
// is decoded; blocks are inflated (zlib) a row at a time, and a row's memory grows as its data
// arrives, so a damaged or hostile file cannot make it read out of bounds or allocate beyond what
// it holds (a 1 MB file claiming 3500 x 3500 x 22 floats costs a row, 308 kB). A block with offset
// and byte count 0 is not stored (a sparse file, as GDAL's SPARSE_OK and tiff_writer.hpp's tiles
// write them): nodata.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace pcdp::io::detail {

/// What the directory says of the raster.
struct FloatTiffInfo {
  int width = 0, height = 0, bands = 0;
  double pixel_scale[3] = {0, 0, 0};        ///< ModelPixelScaleTag (33550); zeros: absent
  double tiepoint[6] = {0, 0, 0, 0, 0, 0};  ///< ModelTiepointTag (33922), the first tie point
  bool georeferenced = false;               ///< both tags were present
  std::string gdal_metadata;                ///< GDAL_METADATA (42112) XML; empty: absent
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
