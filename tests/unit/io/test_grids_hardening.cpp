// Elevation grids, their writers and the TIFF reader against hostile sizes and states (issue 33,
// items 3, 6, 7 and 13): memory follows the observed cells, not their bounding box (run in a
// child process under an address-space limit that the old dense code exceeds by gigabytes); a
// raster past the limit is an InputError naming the size; the reader allocates as data arrives;
// merge refuses every invalid cell state, junk metadata, a pixel scale that disagrees with it,
// count overflow and the same grid twice, naming the file, the cell and the rule.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "io/tiff_reader.hpp"
#include "io/tiff_writer.hpp"
#include "pcdp/fusion/elevation.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
constexpr int kBands = 22;
const float kNan = std::numeric_limits<float>::quiet_NaN();

std::string bytes_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}

/// Runs f() in a child process whose address space may grow by at most `extra` bytes; returns
/// f()'s result, 90 on std::bad_alloc, 91 on another exception (printed), 92+ on a signal.
int in_child_with_memory_limit(std::size_t extra, const std::function<int()>& f) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    std::size_t pages = 0;
    if (std::FILE* s = std::fopen("/proc/self/statm", "r")) {
      if (std::fscanf(s, "%zu", &pages) != 1) pages = 0;
      std::fclose(s);
    }
    rlimit r{};
    r.rlim_cur = r.rlim_max = pages * static_cast<std::size_t>(sysconf(_SC_PAGESIZE)) + extra;
    setrlimit(RLIMIT_AS, &r);
    int code = 0;
    try {
      code = f();
    } catch (const std::bad_alloc&) {
      code = 90;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "child: %s\n", e.what());
      code = 91;
    }
    std::fflush(nullptr);
    _exit(code);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 92 + WTERMSIG(status);
}

/// A cell with a surface: three points at z.
void observe(ElevationGrid& g, double x, double y, double z) {
  for (int k = 0; k < 3; ++k) g.add(x, y, z + 0.001 * k, 1e-4, k);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// ---- a 22-band grid file of 1 x 2 cells (the layout before elevation.state.tif, which merge still
// reads), written with the plain writer, any values ----------

struct GridSpec {
  std::vector<float> v = std::vector<float>(2 * kBands, kNan);  ///< band-major: band b, col c at 2b + c
  std::vector<std::pair<std::string, std::string>> metadata = {
      {"PCDP_BAND", "0.050000000000000003"}, {"PCDP_MIN_SUPPORT", "2"}, {"PCDP_RESOLUTION", "0.10000000000000001"}};
  double pixel_scale = 0.1;
  float& at(int band, int col) { return v[static_cast<std::size_t>(2 * band + col)]; }
};

/// Column 1 holds a valid observed cell: 5 points in 2 passes, top band 10 (3 points), band 9 (2).
GridSpec valid_spec() {
  GridSpec s;
  const float cell[kBands] = {0.52f, 1e-5f, 5, 0.45f, 0.54f, 2, 10, 3e4f, 0.53f, 3, 9, 2e4f, 0.47f, 2,
                              kNan,  kNan,  kNan, kNan, kNan, kNan, kNan, kNan};
  for (int b = 0; b < kBands; ++b) s.at(b, 1) = cell[b];
  return s;
}

void write_grid(const std::string& path, const GridSpec& s) {
  io::detail::FloatTiff t;
  t.width = 2;
  t.height = 1;
  t.bands = kBands;
  t.pixel_scale[0] = t.pixel_scale[1] = s.pixel_scale;
  t.tiepoint[3] = 1.0;
  t.tiepoint[4] = 2.0;
  t.gdal_metadata = io::detail::gdal_metadata(s.metadata, {});
  t.gdal_nodata = "nan";
  const std::vector<float> v = s.v;
  io::detail::write_float_tiff(
      path, t, 1,
      [&](int first, std::vector<std::vector<float>>& planes) {
        for (std::size_t j = 0; j < planes.size(); ++j)
          for (std::size_t c = 0; c < 2; ++c) planes[j][c] = v[2 * (static_cast<std::size_t>(first) + j) + c];
      },
      run_in_order);
}
}  // namespace

// Item 3: two observed cells 5 km apart (50,000 cells at 0.1 m, a bounding box of 2.5 billion
// cells: the dense writer took 60 GB per group of bands) cost what they observed: the GeoTIFF is
// sparse tiles that GDAL reads (values and nodata), our reader reads it back, the picture is
// downsampled; all under 512 MB more address space.
TEST(GridsHardening, FarApartCellsCostWhatTheyObserveInEveryProduct) {
  PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED();
  const std::string dir = test::fresh_dir();
  ElevationGrid g(0.1, 0.05);
  observe(g, 0.05, 0.05, 1.0);
  observe(g, 5000.05, 5000.05, 2.0);
  const std::string tif = dir + "/far.tif", png = dir + "/far.png";
  const int code = in_child_with_memory_limit(std::size_t{512} << 20, [&] {
    if (io::write_elevation_geotiff(g, tif) != 2) return 1;
    if (io::write_elevation_png(g, png) != 25) return 2;  // 50,001 cells across: 25 x 25 a pixel
    const ElevationGrid back = io::read_elevation_geotiff(tif);
    return back.size() == 2 ? 0 : 3;
  });
  ASSERT_EQ(code, 0) << "90: out of memory under the limit";
  // The tile directory (8 bytes a tile and band: 196 x 196 tiles) and two tiles.
  EXPECT_LT(bytes_of(tif).size(), std::size_t{8} << 20);
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(tif.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetRasterXSize(), 50001);
  EXPECT_EQ(ds->GetRasterYSize(), 50001);
  int bx = 0, by = 0;
  ds->GetRasterBand(1)->GetBlockSize(&bx, &by);
  EXPECT_EQ(bx, 256);
  EXPECT_EQ(by, 256);
  float v = 0;
  // The south-west cell (row 50000, col 0), the north-east one (row 0, col 50000), a cell of an
  // empty tile between them: nodata.
  ASSERT_EQ(ds->GetRasterBand(3)->RasterIO(GF_Read, 0, 50000, 1, 1, &v, 1, 1, GDT_Float32, 0, 0), CE_None);
  EXPECT_EQ(v, 3.0f);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 50000, 0, 1, 1, &v, 1, 1, GDT_Float32, 0, 0), CE_None);
  EXPECT_NEAR(v, 2.001, 1e-4);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 25000, 25000, 1, 1, &v, 1, 1, GDT_Float32, 0, 0), CE_None);
  EXPECT_TRUE(std::isnan(v));
  GDALClose(ds);
  // Read back through our reader: the same cells.
  const ElevationGrid back = io::read_elevation_geotiff(tif);
  ASSERT_EQ(back.size(), 2u);
  const ElevationCell* c = back.find(50000, 50000);
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->count, 3u);
}

// Item 3: a grid whose bounding box exceeds the limit (65,536 tiles of 256 x 256 cells) is an
// InputError naming the product and the size, before anything is allocated.
TEST(GridsHardening, ARasterPastTheLimitIsAnInputErrorNamingTheSize) {
  const std::string dir = test::fresh_dir();
  ElevationGrid g(0.001, 0.05);
  observe(g, 0.0005, 0.0005, 1.0);
  observe(g, 20000.0005, 0.0005, 1.0);  // 20,000,001 cells across: 78,126 tiles
  const std::string e = error_of([&] { io::write_elevation_geotiff(g, dir + "/big.tif"); });
  EXPECT_NE(e.find("elevation.tif"), std::string::npos) << e;
  EXPECT_NE(e.find("20000001 x 1 cells"), std::string::npos) << e;
  EXPECT_NE(e.find("65536 tiles"), std::string::npos) << e;
  EXPECT_FALSE(std::filesystem::exists(dir + "/big.tif"));
  // The picture has no such limit: it is downsampled.
  EXPECT_GT(io::write_elevation_png(g, dir + "/big.png"), 1);
}

// Ordinary grids keep their layout: strips written block by block are the bytes the whole-plane
// writer writes.
TEST(GridsHardening, StripsWrittenBlockByBlockAreTheWholePlaneBytes) {
  const std::string dir = test::fresh_dir();
  io::detail::FloatTiff t;
  t.width = 13;
  t.height = 10;
  t.bands = 5;
  t.rows_per_strip = 4;
  t.groups = {2, 3};
  const auto value = [](int b, int col, int row) {
    return (col + row) % 4 == 0 ? kNan : static_cast<float>(100 * b + 10 * row + col);
  };
  io::detail::write_float_tiff(
      dir + "/planes.tif", t, 1,
      [&](int first, std::vector<std::vector<float>>& planes) {
        for (std::size_t j = 0; j < planes.size(); ++j)
          for (std::size_t i = 0; i < planes[j].size(); ++i)
            planes[j][i] = value(first + static_cast<int>(j), static_cast<int>(i % 13), static_cast<int>(i / 13));
      },
      run_in_order);
  io::detail::write_float_tiff_blocks(
      dir + "/blocks.tif", t, 1,
      [&](int first, const io::detail::Block& b, std::vector<std::vector<float>>& planes) {
        for (std::size_t j = 0; j < planes.size(); ++j)
          for (std::size_t i = 0; i < planes[j].size(); ++i)
            planes[j][i] = value(first + static_cast<int>(j), b.x0 + static_cast<int>(i) % b.width,
                                 b.y0 + static_cast<int>(i) / b.width);
        return true;
      },
      run_in_order);
  EXPECT_EQ(bytes_of(dir + "/planes.tif"), bytes_of(dir + "/blocks.tif"));
}

// Item 7: a 1 MB file claiming 3500 x 3500 x 22 floats in one pixel-interleaved DEFLATE strip
// (1.08 GB; the old reader allocated that twice before decoding) is read a row at a time: the
// first rows arrive, then the damage is an InputError, all under 64 MB more address space.
TEST(GridsHardening, TheReaderAllocatesAsTheDataArrives) {
  PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED();
  const std::string dir = test::fresh_dir();
  const std::string path = dir + "/claims.tif";
  // A zlib stream of 3 rows of zeros (a stored block is enough: the reader inflates it), then
  // junk up to 1 MB.
  const std::uint32_t w = 3500, h = 3500, spp = 22;
  const std::uint32_t row_bytes = w * spp * 4;
  std::string strip = "\x78\x01";
  for (int r = 0; r < 3; ++r) {
    for (std::uint32_t left = row_bytes; left > 0;) {
      const std::uint16_t n = static_cast<std::uint16_t>(std::min<std::uint32_t>(left, 65535));
      strip += '\0';  // a stored block, not the last
      strip.append(reinterpret_cast<const char*>(&n), 2);
      const std::uint16_t nn = static_cast<std::uint16_t>(~n);
      strip.append(reinterpret_cast<const char*>(&nn), 2);
      strip.append(n, '\0');
      left -= n;
    }
  }
  strip.resize(std::size_t{1} << 20, '\xff');  // 0xff: an invalid block type
  std::string f = "II";
  const auto u16 = [&](std::uint16_t x) { f.append(reinterpret_cast<const char*>(&x), 2); };
  const auto u32 = [&](std::uint32_t x) { f.append(reinterpret_cast<const char*>(&x), 4); };
  u16(42);
  u32(8);
  struct E {
    std::uint16_t tag, type;
    std::uint32_t count, value;
  };
  const std::uint32_t extra = 8 + 2 + 12 * 10 + 4;  // the per-sample arrays follow the directory
  const std::uint32_t strip_at = extra + 2 * 2 * spp;
  const E entries[] = {{256, 4, 1, w},         {257, 4, 1, h},     {258, 3, spp, extra},
                       {259, 3, 1, 8},         {273, 4, 1, strip_at}, {277, 3, 1, spp},
                       {278, 4, 1, h},         {279, 4, 1, static_cast<std::uint32_t>(strip.size())},
                       {284, 3, 1, 1},         {339, 3, spp, extra + 2 * spp}};
  u16(10);
  for (const E& e : entries) {
    u16(e.tag);
    u16(e.type);
    u32(e.count);
    u32(e.value);
  }
  u32(0);
  for (std::uint32_t i = 0; i < spp; ++i) u16(32);
  for (std::uint32_t i = 0; i < spp; ++i) u16(3);
  ASSERT_EQ(f.size(), strip_at);
  test::write_text(path, f + strip);
  const int code = in_child_with_memory_limit(std::size_t{64} << 20, [&] {
    io::detail::FloatTiffRows rows(path);
    int seen = 0;
    const std::string e = error_of([&] {
      rows.for_each_piece([&](const io::detail::FloatTiffPiece& p) {
        if (p.cols != static_cast<int>(w) || p.bands.size() != spp || p.bands[21][0] != 0.0f) throw std::logic_error("piece");
        ++seen;
      });
    });
    // libtiff's inflate meets the junk block right after the third row's data: two or three rows.
    if (seen < 2 || seen > 3) {
      std::fprintf(stderr, "seen %d: %s\n", seen, e.c_str());
      return 1;
    }
    if (e.find(path + ": strip 0 cannot be decoded") == std::string::npos) return 2;
    // The same through the strip-of-rows interface.
    io::detail::FloatTiffRows again(path);
    std::vector<std::vector<float>> out;
    int first = 0, count = 0;
    if (error_of([&] { again.next(first, count, out); }).find("strip 0") == std::string::npos) return 3;
    return 0;
  });
  EXPECT_EQ(code, 0) << "90: out of memory under the limit";
}

// Item 7: a stored block whose bytes cannot hold the rows it claims is refused before its rows
// are allocated (DEFLATE expands at most 1032 to 1).
TEST(GridsHardening, ABlockTooSmallForItsRowsIsRefusedBeforeDecoding) {
  const std::string dir = test::fresh_dir();
  GridSpec s = valid_spec();
  write_grid(dir + "/ok.tif", s);
  std::string b = bytes_of(dir + "/ok.tif");
  // ImageWidth (the first entry) claimed 2^24: every strip then holds too few bytes.
  std::uint32_t ifd = 0;
  std::memcpy(&ifd, b.data() + 4, 4);
  const std::uint32_t wide = 1u << 24;
  std::memcpy(&b[ifd + 2 + 8], &wide, 4);
  const std::uint16_t long_type = 4;  // libtiff writes a small width as a SHORT
  std::memcpy(&b[ifd + 2 + 2], &long_type, 2);
  test::write_text(dir + "/wide.tif", b);
  const std::string e = error_of([&] { io::read_elevation_geotiff(dir + "/wide.tif"); });
  EXPECT_NE(e.find("strip 0 holds"), std::string::npos) << e;
  EXPECT_NE(e.find("too few for 1 rows of 16777216"), std::string::npos) << e;
}

// Item 6: every invalid cell state is refused, naming the file, the cell (row, col) and the rule.
TEST(GridsHardening, MergeRefusesEveryInvalidCellStateNamingFileCellAndRule) {
  const std::string dir = test::fresh_dir();
  write_grid(dir + "/valid.tif", valid_spec());
  {
    const ElevationGrid g = io::read_elevation_geotiff(dir + "/valid.tif");
    ASSERT_EQ(g.size(), 1u);
  }
  struct Case {
    const char* name;
    std::function<void(GridSpec&)> damage;
    const char* rule;
  };
  const float inf = std::numeric_limits<float>::infinity();
  const Case cases[] = {
      {"count_negative", [](GridSpec& s) { s.at(2, 1) = -5; }, "band 3 (count) = -5 is not a whole number in 1 .."},
      {"count_zero", [](GridSpec& s) { s.at(2, 1) = 0; }, "band 3 (count) = 0 is not a whole number"},
      {"count_inf", [&](GridSpec& s) { s.at(2, 1) = inf; }, "band 3 (count)"},
      {"count_fraction", [](GridSpec& s) { s.at(2, 1) = 5.5f; }, "band 3 (count) = 5.5"},
      {"passes_zero", [](GridSpec& s) { s.at(5, 1) = 0; }, "band 6 (passes) = 0 is not a whole number in 1 .. 5"},
      {"passes_nan", [](GridSpec& s) { s.at(5, 1) = kNan; }, "band 6 (passes)"},
      {"passes_over_count", [](GridSpec& s) { s.at(5, 1) = 6; }, "band 6 (passes) = 6"},
      {"min_over_max", [](GridSpec& s) { s.at(3, 1) = 0.6f; }, "min <= max"},
      {"max_nan", [](GridSpec& s) { s.at(4, 1) = kNan; }, "must be finite with min <= max"},
      {"variance_zero", [](GridSpec& s) { s.at(1, 1) = 0; }, "the variance > 0"},
      {"elevation_without_variance", [](GridSpec& s) { s.at(1, 1) = kNan; }, "both be nodata or both finite"},
      {"weight_nan", [](GridSpec& s) { s.at(7, 1) = kNan; }, "height band 0 is partly nodata"},
      {"weight_negative", [](GridSpec& s) { s.at(7, 1) = -3e4f; }, "height band 0's weight -30000 must be finite and > 0"},
      {"weight_inf", [&](GridSpec& s) { s.at(11, 1) = inf; }, "height band 1's weight inf must be finite and > 0"},
      {"mean_inf", [&](GridSpec& s) { s.at(8, 1) = -inf; }, "height band 0's mean -inf must be finite"},
      {"band_count_negative", [](GridSpec& s) { s.at(9, 1) = -1; }, "band 10 (height_band_0_count) = -1"},
      {"band_count_over_count", [](GridSpec& s) { s.at(9, 1) = 6; }, "band 10 (height_band_0_count) = 6"},
      {"bands_over_count", [](GridSpec& s) { s.at(13, 1) = 3; }, "the height bands hold 6 points, more than the cell's count 5"},
      {"band_index_fraction", [](GridSpec& s) { s.at(6, 1) = 10.5f; }, "band 7 (height_band_0_index) = 10.5"},
      {"bands_out_of_order", [](GridSpec& s) { s.at(10, 1) = 11; }, "height band 1's index 11 is not below the band above it"},
      {"band_after_gap",
       [](GridSpec& s) {
         for (int q = 0; q < 4; ++q) s.at(6 + q, 1) = kNan;
       },
       "height band 1 follows an empty one"},
      {"unobserved_with_values", [](GridSpec& s) { s.at(0, 0) = 1.0f; }, "an unobserved cell holds nothing"},
  };
  for (const Case& c : cases) {
    GridSpec s = valid_spec();
    c.damage(s);
    const std::string path = dir + "/" + c.name + ".tif";
    write_grid(path, s);
    const std::string e = error_of([&] { io::read_elevation_geotiff(path); });
    EXPECT_NE(e.find(path + ": cell (row 0, col "), std::string::npos) << c.name << ": " << e;
    EXPECT_NE(e.find(c.rule), std::string::npos) << c.name << ": wanted '" << c.rule << "' in: " << e;
    // merge reads the same way, and leaves the error to the caller.
    ElevationGrid g(0.1, 0.05, 2);
    const std::string m = error_of([&] { io::merge_elevation_geotiff(g, path); });
    EXPECT_EQ(m, e) << c.name;
  }
}

// Item 6: counts summed past 32 bits are refused, not wrapped.
TEST(GridsHardening, MergeRefusesCountsThatWouldWrap) {
  const std::string dir = test::fresh_dir();
  GridSpec s = valid_spec();
  s.at(2, 1) = 4294967040.0f;  // 2^32 - 256, exactly a float
  write_grid(dir + "/a.tif", s);
  ElevationGrid g = io::read_elevation_geotiff(dir + "/a.tif");
  s.at(0, 1) = 0.53f;  // other bytes: not "the same grid"
  write_grid(dir + "/b.tif", s);
  const std::string e = error_of([&] { io::merge_elevation_geotiff(g, dir + "/b.tif"); });
  EXPECT_NE(e.find(dir + "/b.tif"), std::string::npos) << e;
  EXPECT_NE(e.find("more than a count can"), std::string::npos) << e;
}

// Item 6: the same grid given twice (by the same path, another path to the same file, or a copy)
// is refused; distinct grids are not.
TEST(GridsHardening, TheSameGridTwiceIsRefused) {
  const std::string dir = test::fresh_dir();
  write_grid(dir + "/a.tif", valid_spec());
  GridSpec other = valid_spec();
  other.at(0, 1) = 0.51f;
  write_grid(dir + "/b.tif", other);
  std::filesystem::copy_file(dir + "/a.tif", dir + "/copy.tif");
  std::filesystem::create_symlink(dir + "/a.tif", dir + "/link.tif");
  const auto check = [&](const std::vector<std::string>& p) { return error_of([&] { io::check_distinct_grids(p); }); };
  EXPECT_EQ(check({dir + "/a.tif", dir + "/b.tif"}), "");
  std::string e = check({dir + "/a.tif", dir + "/b.tif", dir + "/a.tif"});
  EXPECT_NE(e.find("are the same file"), std::string::npos) << e;
  e = check({dir + "/link.tif", dir + "/a.tif"});
  EXPECT_NE(e.find("are the same file"), std::string::npos) << e;
  e = check({dir + "/a.tif", dir + "/b.tif", dir + "/copy.tif"});
  EXPECT_NE(e.find("'" + dir + "/a.tif' and '" + dir + "/copy.tif' hold the same bytes"), std::string::npos) << e;
}

// Item 13: the merge metadata is parsed strictly, and the pixel scale must agree with it.
TEST(GridsHardening, JunkMetadataAndADisagreeingPixelScaleAreRefusedNamingTheField) {
  const std::string dir = test::fresh_dir();
  struct Case {
    const char* name;
    std::function<void(GridSpec&)> damage;
    const char* want;
  };
  const Case cases[] = {
      {"res_junk", [](GridSpec& s) { s.metadata[2].second = "0.1junk"; },
       "GDAL metadata item PCDP_RESOLUTION = '0.1junk' is not a number"},
      {"res_blank", [](GridSpec& s) { s.metadata[2].second = " 0.1"; }, "PCDP_RESOLUTION = ' 0.1' is not a number"},
      {"res_empty", [](GridSpec& s) { s.metadata[2].second = ""; }, "PCDP_RESOLUTION = '' is not a number"},
      {"res_negative", [](GridSpec& s) { s.metadata[2].second = "-0.1"; }, "PCDP_RESOLUTION = -0.1: must be > 0"},
      {"res_nan", [](GridSpec& s) { s.metadata[2].second = "nan"; }, "PCDP_RESOLUTION = 'nan' is not a number"},
      {"band_junk", [](GridSpec& s) { s.metadata[0].second = "0.05m"; }, "PCDP_BAND = '0.05m' is not a number"},
      {"support_fraction", [](GridSpec& s) { s.metadata[1].second = "2.5"; },
       "PCDP_MIN_SUPPORT = 2.5: must be a whole number"},
      {"support_junk", [](GridSpec& s) { s.metadata[1].second = "2x"; }, "PCDP_MIN_SUPPORT = '2x' is not a number"},
      {"res_twice", [](GridSpec& s) { s.metadata.push_back({"PCDP_RESOLUTION", "0.2"}); },
       "PCDP_RESOLUTION is given twice"},
      {"res_missing", [](GridSpec& s) { s.metadata.pop_back(); }, "PCDP_RESOLUTION is missing"},
      {"scale", [](GridSpec& s) { s.pixel_scale = 0.2; },
       "the GeoTIFF pixel scale (ModelPixelScaleTag) 0.2 x 0.2 m disagrees with GDAL metadata item PCDP_RESOLUTION = 0.1 m"},
  };
  for (const Case& c : cases) {
    GridSpec s = valid_spec();
    c.damage(s);
    const std::string path = dir + "/" + c.name + ".tif";
    write_grid(path, s);
    const std::string e = error_of([&] { io::read_elevation_geotiff(path); });
    EXPECT_EQ(e.rfind(path + ": ", 0), 0u) << c.name << ": " << e;
    EXPECT_NE(e.find(c.want), std::string::npos) << c.name << ": wanted '" << c.want << "' in: " << e;
  }
}

// The reader reads sparse files as GDAL writes them (SPARSE_OK: blocks never written have
// offset and byte count 0): nodata there, the written block's values elsewhere.
TEST(GridsHardening, SparseFilesFromGdalReadAsNodata) {
  const std::string dir = test::fresh_dir();
  const std::string path = dir + "/sparse.tif";
  GDALAllRegister();
  {
    char** opts = nullptr;
    opts = CSLSetNameValue(opts, "TILED", "YES");
    opts = CSLSetNameValue(opts, "BLOCKXSIZE", "16");
    opts = CSLSetNameValue(opts, "BLOCKYSIZE", "16");
    opts = CSLSetNameValue(opts, "SPARSE_OK", "TRUE");
    opts = CSLSetNameValue(opts, "COMPRESS", "DEFLATE");
    GDALDataset* ds = GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), 40, 40, 2, GDT_Float32, opts);
    CSLDestroy(opts);
    ASSERT_NE(ds, nullptr);
    std::vector<float> block(16 * 16, 7.0f);
    for (int b = 1; b <= 2; ++b) {
      ds->GetRasterBand(b)->SetNoDataValue(std::nan(""));
      ASSERT_EQ(ds->GetRasterBand(b)->RasterIO(GF_Write, 16, 16, 16, 16, block.data(), 16, 16, GDT_Float32, 0, 0), CE_None);
    }
    GDALClose(ds);
  }
  const io::detail::FloatTiffData d = io::detail::read_float_tiff(path);
  ASSERT_EQ(d.planes.size(), 2u);
  ASSERT_EQ(d.planes[1].size(), 1600u);
  EXPECT_EQ(d.planes[1][20 * 40 + 20], 7.0f);
  EXPECT_TRUE(std::isnan(d.planes[1][0]));
  EXPECT_TRUE(std::isnan(d.planes[0][39 * 40 + 39]));
  // Piece by piece, only the stored block's rows come.
  io::detail::FloatTiffRows rows(path);
  int pieces = 0;
  rows.for_each_piece([&](const io::detail::FloatTiffPiece& p) {
    EXPECT_EQ(p.col0, 16);
    EXPECT_EQ(p.row, 16 + pieces);
    ++pieces;
  });
  EXPECT_EQ(pieces, 16);
}
