#include "pcdp/io/geotiff.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"
#include "geotiff_crs.hpp"
#include "tiff_reader.hpp"
#include "tiff_writer.hpp"
#include "rename_into_place.hpp"

namespace pcdp::io {

namespace {
constexpr int kFixed = 6;  // elevation variance count min max passes
constexpr int kPerBand = 4;  // index weight mean count, for each kept height band
constexpr int kBands = kFixed + kPerBand * ElevationCell::kBands;  // of the legacy file, and band_name()'s numbering
constexpr int kUserBands = kFixed;  // elevation.tif: elevation variance count min max passes
constexpr int kStateFirst = 2;      // the state file: band_name() 2 .. 21 (count min max passes, the height bands)
constexpr int kStateBands = kBands - kStateFirst;
constexpr const char* kUserContract =
    "bands 1-5 per docs/data_contract.md, 6 passes; the merge state is the .state.tif file beside it";
constexpr const char* kStateContract =
    "merge state: 1 count, 2 min, 3 max, 4 passes, 5-20 the four highest height bands (index, weight, mean, count)";
constexpr int kStripBytes = 64 * 1024;  // at least this much of a band per TIFF strip
constexpr std::uint64_t kStripCells = std::uint64_t{1} << 22;  // larger rasters are written as sparse tiles
constexpr int kTile = 256;
constexpr std::uint64_t kMaxTiles = 65536;  // a raster spans at most this many tiles (4.29e9 cells)

}  // namespace

void check_elevation_extent(std::int64_t ix0, std::int64_t iy0, std::int64_t ix1, std::int64_t iy1, double res,
                            const std::string& product) {
  // Differences in unsigned arithmetic: defined whatever the indices (ix0 <= ix1, iy0 <= iy1).
  const std::uint64_t nx = std::min<std::uint64_t>(static_cast<std::uint64_t>(ix1) - static_cast<std::uint64_t>(ix0), 1ull << 62) + 1;
  const std::uint64_t ny = std::min<std::uint64_t>(static_cast<std::uint64_t>(iy1) - static_cast<std::uint64_t>(iy0), 1ull << 62) + 1;
  const std::uint64_t tiles_x = (nx + kTile - 1) / kTile, tiles_y = (ny + kTile - 1) / kTile;
  if (tiles_x > kMaxTiles || tiles_y > kMaxTiles || tiles_x * tiles_y > kMaxTiles) {
    char size[160];
    std::snprintf(size, sizeof size, "%llu x %llu cells (%.6g m x %.6g m at %.6g m)", static_cast<unsigned long long>(nx),
                  static_cast<unsigned long long>(ny), static_cast<double>(nx) * res, static_cast<double>(ny) * res, res);
    throw InputError(product + ": the observed cells span " + std::string(size) + ", " + std::to_string(tiles_x) +
                     " x " + std::to_string(tiles_y) + " tiles of " + std::to_string(kTile) + " x " +
                     std::to_string(kTile) + "; the limit is " + std::to_string(kMaxTiles) +
                     " tiles (4,294,967,296 cells, e.g. 65,536 x 65,536). Check the poses for a jump, or use a "
                     "coarser resolution or an extent");
  }
}

std::string elevation_state_path(const std::string& path) {
  const std::string ext = ".tif";
  if (path.size() > ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0)
    return path.substr(0, path.size() - ext.size()) + ".state.tif";
  return path + ".state.tif";
}

std::string elevation_geotiff_crs(const std::string& path) {
  const std::string state = elevation_state_path(path);
  std::error_code ec;
  const detail::FloatTiffRows t(std::filesystem::exists(state, ec) ? state : path);
  return detail::crs_of(t.info().geokeys);
}

namespace {
std::string band_name(int b) {
  static const char* const fixed[kFixed] = {"elevation", "variance", "count", "min", "max", "passes"};
  if (b < kFixed) return fixed[b];
  static const char* const per[kPerBand] = {"index", "weight", "mean", "count"};
  return "height_band_" + std::to_string((b - kFixed) / kPerBand) + "_" + per[(b - kFixed) % kPerBand];
}

using detail::rename_into_place;
}  // namespace

std::size_t write_elevation_geotiff(const ElevationGrid& grid, const std::string& path, int deflate_level, const RunTasks& share,
                                   const std::string& crs, const std::string& state_path_in) {
  if (deflate_level < 1 || deflate_level > 12)
    throw std::invalid_argument("DEFLATE level " + std::to_string(deflate_level) + " is outside 1 .. 12");
  const std::string state_path = state_path_in.empty() ? elevation_state_path(path) : state_path_in;
  std::int64_t ix0 = 0, iy0 = 0, ix1 = 0, iy1 = 0;
  if (!grid.bounds(ix0, iy0, ix1, iy1)) ix0 = iy0 = ix1 = iy1 = 0;
  check_elevation_extent(ix0, iy0, ix1, iy1, grid.resolution());
  const int nx = static_cast<int>(ix1 - ix0 + 1), ny = static_cast<int>(iy1 - iy0 + 1);
  // Two files of the same raster: elevation.tif, the user's bands (1-6 of band_name()), and its
  // merge state beside it (bands 3-22: count, min, max, passes and the four kept height bands).
  detail::FloatTiff t;
  t.width = nx;
  t.height = ny;
  t.geokeys = detail::crs_geokeys(crs);
  // Strips of at least 64 KiB, not GDAL's default of about 8 KiB: every strip costs a compressor
  // set-up and a flush, and on the 8-pass bench grid (267 x 400 cells, 22 bands) the default's
  // 1,276 strips took 22 ms to write against 16 ms for 154 (GDAL's writer; the file 7 % smaller). Any TIFF
  // reader reads either; a strip is still a few rows of a wide grid, so memory stays small.
  const int row_bytes = nx * static_cast<int>(sizeof(float));
  t.rows_per_strip = std::min(ny, std::max(1, (kStripBytes + row_bytes - 1) / row_bytes));
  const double res = grid.resolution();
  // North-up: raster (0, 0) is the north-west corner of cell (ix0, iy1). The grid's cell indices
  // are absolute (a run's grid adds its map origin), so the tie point is in true map metres,
  // computed in double: a UTM grid is georeferenced to the nanometre.
  t.pixel_scale[0] = t.pixel_scale[1] = res;
  t.tiepoint[3] = static_cast<double>(ix0) * res;
  t.tiepoint[4] = static_cast<double>(iy1 + 1) * res;
  // Metadata and band names where GDAL keeps them, so gdalinfo and read_elevation_geotiff see
  // them as in files that GDAL writes.
  char band[32], resolution[32];
  std::snprintf(band, sizeof band, "%.17g", grid.band());
  std::snprintf(resolution, sizeof resolution, "%.17g", res);
  const auto metadata = [&](const std::string& contract, int first, int bands) {
    std::vector<std::string> names;
    for (int b = first; b < first + bands; ++b) names.push_back(band_name(b));
    return detail::gdal_metadata({{"PCDP_BAND", band},
                                  {"PCDP_CONTRACT", contract},
                                  {"PCDP_MIN_SUPPORT", std::to_string(grid.min_support())},
                                  {"PCDP_RESOLUTION", resolution}},
                                 names);
  };
  t.gdal_nodata = "nan";

  // The layout (docs/fusion.md): strips, as GDAL writes them, while the raster is at most
  // kStripCells; past that, tiles of kTile x kTile of which only those holding cells are stored,
  // so that the file costs what the grid observed, not its bounding box.
  if (static_cast<std::uint64_t>(nx) * static_cast<std::uint64_t>(ny) > kStripCells) t.tile = kTile;
  const std::size_t bw = t.tile ? static_cast<std::size_t>(kTile) : static_cast<std::size_t>(nx);
  const std::size_t bh = t.tile ? static_cast<std::size_t>(kTile) : static_cast<std::size_t>(t.rows_per_strip);
  const std::size_t across = (static_cast<std::size_t>(nx) + bw - 1) / bw;
  const std::size_t blocks = across * ((static_cast<std::size_t>(ny) + bh - 1) / bh);
  // The cells by block (a counting sort): a block's fill visits only its own cells.
  struct Ref {
    const ElevationCell* c;
    std::uint32_t col, row;  ///< in the raster
  };
  std::vector<std::size_t> start(blocks + 1, 0);
  const auto block_of = [&](std::int64_t ix, std::int64_t iy) {
    return static_cast<std::size_t>(iy1 - iy) / bh * across + static_cast<std::size_t>(ix - ix0) / bw;
  };
  grid.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    if (!c.empty()) ++start[block_of(ix, iy) + 1];
  });
  for (std::size_t s = 0; s < blocks; ++s) start[s + 1] += start[s];
  std::vector<Ref> refs(start[blocks]);
  {
    std::vector<std::size_t> at(start.begin(), start.end() - 1);
    grid.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
      if (!c.empty())
        refs[at[block_of(ix, iy)]++] = {&c, static_cast<std::uint32_t>(ix - ix0), static_cast<std::uint32_t>(iy1 - iy)};
    });
  }

  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Bands in groups that one visit of the cells fills (band_name()'s numbering): 0-1 the surface,
  // 2-5 the cell's count, min, max and passes, then each height band's four. A cell spans several
  // cache lines, so on a grid of two million cells one visit per band (22) took 44 % of the
  // write. Each task holds one block of its group's planes. `offset`: the file's first band.
  std::size_t surfaces = 0;  // counted by the one task that fills the surface
  const auto fill_from = [&](int offset) {
    return [&, offset](int file_first, const detail::Block& blk, std::vector<std::vector<float>>& planes) {
      const int first = file_first + offset;
      if (t.tile && start[blk.index] == start[blk.index + 1]) return false;  // an empty tile: not stored
      for (auto& p : planes) std::fill(p.begin(), p.end(), nan);
      const std::size_t k = first >= kFixed ? static_cast<std::size_t>((first - kFixed) / kPerBand) : 0;
      bool any = false;
      for (std::size_t i = start[blk.index]; i < start[blk.index + 1]; ++i) {
        const ElevationCell& c = *refs[i].c;
        const std::size_t at = (refs[i].row - static_cast<std::size_t>(blk.y0)) * static_cast<std::size_t>(blk.width) +
                               (refs[i].col - static_cast<std::size_t>(blk.x0));
        if (first >= kFixed) {
          const HeightBand& hb = c.bands[k];
          if (hb.empty()) continue;
          planes[0][at] = static_cast<float>(hb.index);
          planes[1][at] = static_cast<float>(hb.w);
          planes[2][at] = static_cast<float>(hb.wz / hb.w);
          planes[3][at] = static_cast<float>(hb.count);
          any = true;
          continue;
        }
        if (first == 0) {
          double e = 0, var = 0;
          if (grid.surface(c, e, var)) {
            planes[0][at] = static_cast<float>(e);
            planes[1][at] = static_cast<float>(var);
            ++surfaces;
          }
          any = true;
          continue;
        }
        planes[0][at] = static_cast<float>(c.count);
        planes[1][at] = c.zmin;
        planes[2][at] = c.zmax;
        planes[3][at] = static_cast<float>(c.passes);
        any = true;
      }
      return any;
    };
  };
  const std::string tmp = path + ".tmp-write.tif", state_tmp = state_path + ".tmp-write.tif";
  try {
    detail::FloatTiff user = t;
    user.bands = kUserBands;
    user.groups = {2, 4};
    user.gdal_metadata = metadata(kUserContract, 0, kUserBands);
    detail::write_float_tiff_blocks(tmp, user, deflate_level, fill_from(0), share);
    detail::FloatTiff state = t;
    state.bands = kStateBands;
    state.groups.push_back(4);
    for (int k = 0; k < ElevationCell::kBands; ++k) state.groups.push_back(kPerBand);
    state.gdal_metadata = metadata(kStateContract, kStateFirst, kStateBands);
    detail::write_float_tiff_blocks(state_tmp, state, deflate_level, fill_from(kStateFirst), share);
  } catch (...) {
    std::remove(tmp.c_str());
    std::remove(state_tmp.c_str());
    throw;
  }
  rename_into_place(state_tmp, state_path);
  rename_into_place(tmp, path);
  return surfaces;
}

namespace {
/// `text` as a number, all of it (no junk after it, no blanks), or an error naming the field.
double strict_number(const std::string& text, const std::string& path, const char* field) {
  double v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(v))
    throw InputError(path + ": GDAL metadata item " + field + " = '" + text + "' is not a number (nothing may follow it)");
  return v;
}
}  // namespace

GridMetadata parse_grid_metadata(const std::string& gdal_metadata_xml, const std::string& path) {
  std::string r, bnd, sup;
  bool has_r = false, has_b = false, has_s = false;
  const auto take = [&](const std::string& name, const std::string& value, const char* field, std::string& out, bool& seen) {
    if (name != field) return;
    if (seen) throw InputError(path + ": GDAL metadata item " + field + " is given twice");
    out = value;
    seen = true;
  };
  for (const auto& [name, value] : detail::gdal_metadata_items(gdal_metadata_xml)) {
    take(name, value, "PCDP_RESOLUTION", r, has_r);
    take(name, value, "PCDP_BAND", bnd, has_b);
    take(name, value, "PCDP_MIN_SUPPORT", sup, has_s);
  }
  if (!has_r || !has_b || !has_s)
    throw InputError(path + ": not an elevation grid of pcd_pipeline (GDAL metadata item " +
                     (!has_r ? "PCDP_RESOLUTION" : !has_b ? "PCDP_BAND" : "PCDP_MIN_SUPPORT") + " is missing)");
  GridMetadata m;
  m.resolution = strict_number(r, path, "PCDP_RESOLUTION");
  m.band = strict_number(bnd, path, "PCDP_BAND");
  const double support = strict_number(sup, path, "PCDP_MIN_SUPPORT");
  if (!(m.resolution > 0)) throw InputError(path + ": GDAL metadata item PCDP_RESOLUTION = " + r + ": must be > 0");
  if (!(m.band > 0)) throw InputError(path + ": GDAL metadata item PCDP_BAND = " + bnd + ": must be > 0");
  if (!(support >= 1 && support <= 1000000) || support != std::floor(support))
    throw InputError(path + ": GDAL metadata item PCDP_MIN_SUPPORT = " + sup + ": must be a whole number in 1 .. 1000000");
  m.min_support = static_cast<std::uint32_t>(support);
  return m;
}

namespace {
/// An elevation grid's file opened for reading: its grid parameters checked, its cells read a
/// row of a strip or tile at a time (FloatTiffRows::for_each_piece), so the memory it takes is a
/// row of a block of each band, and every cell's state checked as it is read.
class GridFile {
 public:
  explicit GridFile(const std::string& path) : path_(state_file(path)), tiff_(path_) {
    const detail::FloatTiffInfo& t = tiff_.info();
    // The merge state: elevation.state.tif beside the grid (20 bands), or a grid of version 0.1.0
    // that holds its state itself (22 bands).
    offset_ = t.bands == kStateBands ? kStateFirst : 0;
    if (t.bands == kUserBands && path_ == path)
      throw InputError(path + ": its merge state " + elevation_state_path(path) +
                       " is missing (fuse_elevation and merge write it beside the grid; copy, convert or re-tile "
                       "both files)");
    if ((t.bands != kBands && t.bands != kStateBands) || !t.georeferenced)
      throw InputError(path_ + ": not an elevation grid of pcd_pipeline (its merge state needs its " +
                       std::to_string(kStateBands) + " bands (or the " + std::to_string(kBands) +
                       " of a grid of earlier versions), its georeferencing and PCDP_* metadata to merge)");
    crs_ = detail::crs_of(t.geokeys);
    const GridMetadata m = parse_grid_metadata(t.gdal_metadata, path_);
    res_ = m.resolution;
    band_ = m.band;
    support_ = m.min_support;
    // The georeferencing states the cell size too: both must say the same (the tie point and the
    // cells would otherwise land on another grid than the metadata's).
    for (int k = 0; k < 2; ++k)
      if (!(std::fabs(t.pixel_scale[k] - res_) <= 1e-9 * res_))
        throw InputError(path_ + ": the GeoTIFF pixel scale (ModelPixelScaleTag) " + format_number(t.pixel_scale[0]) +
                         " x " + format_number(t.pixel_scale[1]) + " m disagrees with GDAL metadata item PCDP_RESOLUTION = " +
                         format_number(res_) + " m");
    // The raster's north-west corner, as GDAL's geotransform has it (pixel-is-area tie point).
    const double x0 = t.tiepoint[3] - t.tiepoint[0] * t.pixel_scale[0], y0 = t.tiepoint[4] + t.tiepoint[1] * t.pixel_scale[1];
    constexpr double kMaxIndex = 4.5e15;  // cell indices stay exact in a double, and far from overflow
    if (!(std::fabs(x0 / res_) < kMaxIndex) || !(std::fabs(y0 / res_) < kMaxIndex))
      throw InputError(path_ + ": the raster's corner (" + std::to_string(x0) + ", " + std::to_string(y0) +
                       ") is not a finite position on its grid");
    ix0_ = std::llround(x0 / res_);
    iy1_ = std::llround(y0 / res_) - 1;
  }

  double resolution() const { return res_; }
  double band() const { return band_; }
  std::uint32_t min_support() const { return support_; }
  /// The absolute cell indices of the raster's north-west cell.
  std::int64_t corner_x() const { return ix0_; }
  std::int64_t corner_y() const { return iy1_; }
  /// The file read: the state file beside the grid, or the grid itself (earlier versions).
  const std::string& path() const { return path_; }
  /// Its CRS as elevation_geotiff_crs() states it ("" none).
  const std::string& crs() const { return crs_; }

  /// f(ix, iy, cell) for every cell that holds points, a block (strip or tile) at a time. Every
  /// cell's state is checked first (docs/fusion.md, "merge"): an InputError names the file, the
  /// cell's row and column in the raster, and the rule.
  template <typename F>
  void for_each_cell(F f) {
    constexpr double kMaxCount = 4294967295.0, kMaxBand = 2147483647.0;
    std::vector<std::vector<float>> full(kBands);
    tiff_.for_each_piece([&](const detail::FloatTiffPiece& p) {
      // The bands by band_name()'s numbers; a state file has no surface: nodata.
      const std::vector<std::vector<float>>* bands = &p.bands;
      if (offset_ != 0) {
        for (int b = 0; b < offset_; ++b) full[static_cast<std::size_t>(b)].assign(static_cast<std::size_t>(p.cols), std::numeric_limits<float>::quiet_NaN());
        for (std::size_t b = 0; b < p.bands.size(); ++b) full[b + static_cast<std::size_t>(offset_)] = p.bands[b];
        bands = &full;
      }
      const auto& v = *bands;
      for (int j = 0; j < p.cols; ++j) {
        const std::size_t i = static_cast<std::size_t>(j);
        const int row = p.row, col = p.col0 + j;
        const auto bad = [&](const std::string& rule) {
          throw InputError(path_ + ": cell (row " + std::to_string(row) + ", col " + std::to_string(col) + "): " + rule);
        };
        const auto val = [&](int b) { return format_number(static_cast<double>(v[static_cast<std::size_t>(b)][i])); };
        const auto whole = [&](int b, double lo, double hi) {
          const float x = v[static_cast<std::size_t>(b)][i];
          if (!(x >= lo && x <= hi) || x != std::floor(x))
            bad("band " + std::to_string(file_band(b)) + " (" + band_name(b) + ") = " + val(b) + " is not a whole number in " +
                format_number(lo) + " .. " + format_number(hi));
          return static_cast<double>(x);
        };
        if (std::isnan(v[2][i])) {  // unobserved: nodata in every band
          for (int b = offset_; b < kBands; ++b)
            if (!std::isnan(v[static_cast<std::size_t>(b)][i]))
              bad("band " + std::to_string(file_band(b)) + " (" + band_name(b) + ") = " + val(b) +
                  ", but the count is nodata (an unobserved cell holds nothing)");
          continue;
        }
        ElevationCell c;
        c.count = static_cast<std::uint32_t>(whole(2, 1, kMaxCount));
        c.passes = static_cast<std::uint32_t>(whole(5, 1, c.count));
        c.zmin = v[3][i];
        c.zmax = v[4][i];
        if (!std::isfinite(c.zmin) || !std::isfinite(c.zmax) || !(c.zmin <= c.zmax))
          bad("min " + val(3) + " and max " + val(4) + " must be finite with min <= max");
        if (std::isnan(v[0][i]) != std::isnan(v[1][i]) ||
            (!std::isnan(v[0][i]) && (!std::isfinite(v[0][i]) || !(v[1][i] > 0) || !std::isfinite(v[1][i]))))
          bad("elevation " + val(0) + " and variance " + val(1) +
              " must both be nodata or both finite, the variance > 0");
        double in_bands = 0;
        for (int k = 0; k < ElevationCell::kBands; ++k) {
          const int b0 = kFixed + kPerBand * k;
          int nan = 0;
          for (int q = 0; q < kPerBand; ++q) nan += std::isnan(v[static_cast<std::size_t>(b0 + q)][i]) ? 1 : 0;
          if (nan == kPerBand) continue;  // an empty height band
          const std::string name = "height band " + std::to_string(k);
          if (nan != 0) bad(name + " is partly nodata (its index, weight, mean and count go together)");
          if (k > 0 && c.bands[static_cast<std::size_t>(k - 1)].empty())
            bad(name + " follows an empty one (the kept bands come first, highest first)");
          HeightBand hb;
          hb.index = static_cast<std::int32_t>(whole(b0, -kMaxBand - 1, kMaxBand));
          if (k > 0 && !(hb.index < c.bands[static_cast<std::size_t>(k - 1)].index))
            bad(name + "'s index " + val(b0) + " is not below the band above it (bands are kept highest first)");
          const float w = v[static_cast<std::size_t>(b0 + 1)][i], mean = v[static_cast<std::size_t>(b0 + 2)][i];
          if (!std::isfinite(w) || !(w > 0)) bad(name + "'s weight " + val(b0 + 1) + " must be finite and > 0");
          if (!std::isfinite(mean)) bad(name + "'s mean " + val(b0 + 2) + " must be finite");
          hb.w = w;
          hb.wz = hb.w * static_cast<double>(mean);
          hb.count = static_cast<std::uint32_t>(whole(b0 + 3, 1, c.count));
          in_bands += hb.count;
          c.bands[static_cast<std::size_t>(k)] = hb;
        }
        if (in_bands > c.count)
          bad("the height bands hold " + format_number(in_bands) + " points, more than the cell's count " + val(2));
        f(ix0_ + col, iy1_ - row, c);
      }
    });
  }

 private:
  std::string path_;
  detail::FloatTiffRows tiff_;
  double res_ = 0, band_ = 0;
  std::uint32_t support_ = 0;
  std::int64_t ix0_ = 0, iy1_ = 0;
  int offset_ = 0;  ///< band_name()'s number of the file's first band
  std::string crs_;

  /// The file that holds the merge state of the grid `path`.
  static std::string state_file(const std::string& path) {
    const std::string state = elevation_state_path(path);
    std::error_code ec;
    return std::filesystem::exists(state, ec) ? state : path;
  }
  /// The file's band number (1-based) of band_name()'s band b.
  int file_band(int b) const { return b - offset_ + 1; }
};
}  // namespace

ElevationGrid read_elevation_geotiff(const std::string& path) {
  GridFile file(path);
  ElevationGrid grid(file.resolution(), file.band(), file.min_support());
  // Keys relative to the raster's corner: a grid far from 0 (UTM at a fine resolution) is held
  // without wrapping its keys, and its cells keep their absolute indices.
  grid.set_key_origin(file.corner_x(), file.corner_y());
  file.for_each_cell([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) { grid.set_cell(ix, iy, c); });
  return grid;
}

void merge_elevation_geotiff(ElevationGrid& grid, const std::string& path, const std::string& grid_name) {
  GridFile file(path);
  // The same tests as ElevationGrid::merge, before any cell is read: a mismatch leaves `grid` as it was.
  if (std::fabs(file.resolution() - grid.resolution()) > 1e-9 || std::fabs(file.band() - grid.band()) > 1e-9 ||
      file.min_support() != grid.min_support())
    throw InputError(file.path() + ": resolution " + format_number(file.resolution()) + " m, band " + format_number(file.band()) +
                     " m and min_support " + std::to_string(file.min_support()) + " differ from " + grid_name + "'s (" +
                     format_number(grid.resolution()) + " m, " + format_number(grid.band()) + " m, " +
                     std::to_string(grid.min_support()) + "); grids merge only on the same grid");
  file.for_each_cell([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    if (!grid.holds(ix, iy))
      throw InputError(file.path() + ": its cell at (" + format_number(static_cast<double>(ix) * grid.resolution()) + ", " +
                       format_number(static_cast<double>(iy) * grid.resolution()) + ") m lies more than 2^30 cells from " +
                       grid_name + "'s (" + format_number(static_cast<double>(grid.key_origin_x()) * grid.resolution()) +
                       ", " + format_number(static_cast<double>(grid.key_origin_y()) * grid.resolution()) +
                       ") m: grids this far apart do not merge into one raster");
    // Counts are 32-bit: a sum past that would wrap (the passes and bands' counts are at most it).
    if (const ElevationCell* have = grid.find(ix, iy); have && std::uint64_t{have->count} + c.count > 4294967295u)
      throw InputError(file.path() + ": the cell at grid index (" + std::to_string(ix) + ", " + std::to_string(iy) +
                       ") would hold " + std::to_string(std::uint64_t{have->count} + c.count) +
                       " points, more than a count can (4294967295)");
    grid.merge_cell(ix, iy, c);
  });
}

void check_distinct_grids(const std::vector<std::string>& grids) {
  namespace fs = std::filesystem;
  // Size and a hash of the bytes, read in pieces; equal hashes are compared byte for byte.
  struct Seen {
    std::uintmax_t size;
    std::uint64_t hash;
  };
  const auto hash_of = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) throw InputError(p + ": cannot open");
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a
    std::vector<char> buf(1 << 16);
    while (in.read(buf.data(), static_cast<std::streamsize>(buf.size())) || in.gcount() > 0) {
      for (std::streamsize i = 0; i < in.gcount(); ++i) h = (h ^ static_cast<unsigned char>(buf[static_cast<std::size_t>(i)])) * 1099511628211ull;
      if (!in) break;
    }
    return h;
  };
  const auto same_bytes = [](const std::string& a, const std::string& b) {
    std::ifstream x(a, std::ios::binary), y(b, std::ios::binary);
    return std::equal(std::istreambuf_iterator<char>(x), {}, std::istreambuf_iterator<char>(y), {});
  };
  std::vector<Seen> seen;
  // The files merge reads: each grid's merge state (or the grid itself, from earlier versions).
  std::vector<std::string> paths;
  for (const std::string& p : grids) {
    const std::string state = elevation_state_path(p);
    std::error_code ec;
    paths.push_back(fs::exists(state, ec) ? state : p);
  }
  for (std::size_t k = 0; k < paths.size(); ++k) {
    require_regular_file(paths[k], "GeoTIFF");  // before any read: a FIFO would block
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(paths[k], ec);
    if (ec) throw InputError(paths[k] + ": cannot read (" + ec.message() + ")");
    for (std::size_t j = 0; j < k; ++j)
      if (fs::equivalent(paths[j], paths[k], ec))
        throw InputError("merge: '" + paths[j] + "' and '" + paths[k] +
                         "' are the same file: a grid merged with itself counts its passes twice");
    seen.push_back({size, hash_of(paths[k])});
    for (std::size_t j = 0; j < k; ++j)
      if (seen[j].size == size && seen[j].hash == seen[k].hash && same_bytes(paths[j], paths[k]))
        throw InputError("merge: '" + paths[j] + "' and '" + paths[k] +
                         "' hold the same bytes: the same grid given twice would count its passes twice");
  }
}

}  // namespace pcdp::io
