// The float32 GeoTIFF reader (lib/src/io/tiff_reader.hpp): our own files (classic and BigTIFF)
// read back bit for bit; files as GDAL wrote them for pcd_pipeline before (DEFLATE, band or pixel
// interleaved, uncompressed) read the same as GDAL reads them; tiled files as GDAL writes them;
// GDAL's metadata unescaped as GDAL does; and damaged or unsupported files rejected with an error
// naming the file and the rule.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "io/tiff_reader.hpp"
#include "io/tiff_writer.hpp"
#include "pcdp/core/errors.hpp"
#include "test_support.hpp"

using namespace pcdp;
using io::detail::FloatTiff;
using io::detail::FloatTiffData;

namespace {
float value(int b, int col, int row) {
  if ((3 * col + row) % 7 == 0) return std::numeric_limits<float>::quiet_NaN();
  return static_cast<float>(b * 1000 + row * 10 + col) - 0.125f;
}

const int kWidth = 11;
const io::detail::PlaneFill fill = [](int first, std::vector<std::vector<float>>& planes) {
  for (std::size_t j = 0; j < planes.size(); ++j)
    for (std::size_t i = 0; i < planes[j].size(); ++i)
      planes[j][i] = value(first + static_cast<int>(j), static_cast<int>(i % kWidth), static_cast<int>(i / kWidth));
};

// Every sample equal to value() (NaN where it is NaN), bit for bit otherwise.
void expect_values(const FloatTiffData& d, int bands, int height) {
  ASSERT_EQ(d.width, kWidth);
  ASSERT_EQ(d.height, height);
  ASSERT_EQ(d.bands, bands);
  ASSERT_EQ(d.planes.size(), static_cast<std::size_t>(bands));
  for (int b = 0; b < bands; ++b)
    for (int row = 0; row < height; ++row)
      for (int col = 0; col < kWidth; ++col) {
        const float v = d.planes[static_cast<std::size_t>(b)][static_cast<std::size_t>(row * kWidth + col)];
        const float want = value(b, col, row);
        if (std::isnan(want)) ASSERT_TRUE(std::isnan(v)) << b << " " << col << " " << row;
        else ASSERT_EQ(v, want) << b << " " << col << " " << row;
      }
}

// A file as pcd_pipeline had GDAL write elevation.tif, with creation options `opts` added:
// kWidth columns of value() unless told otherwise.
void gdal_write(const std::string& path, int bands, int height, std::vector<std::string> opts, int width = kWidth,
                float (*values)(int, int, int) = value) {
  GDALAllRegister();
  char** o = nullptr;
  for (const auto& kv : opts) o = CSLAddString(o, kv.c_str());
  GDALDataset* ds = GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), width, height, bands,
                                                                            GDT_Float32, o);
  CSLDestroy(o);
  ASSERT_NE(ds, nullptr);
  double gt[6] = {-4.5, 0.25, 0, 7.75, 0, -0.25};
  ds->SetGeoTransform(gt);
  ds->SetMetadataItem("PCDP_NOTE", "a<b & \"c\"");
  std::vector<float> plane(static_cast<std::size_t>(width * height));
  for (int b = 0; b < bands; ++b) {
    for (int i = 0; i < width * height; ++i) plane[static_cast<std::size_t>(i)] = values(b, i % width, i / width);
    ASSERT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, width, height, plane.data(), width, height,
                                                 GDT_Float32, 0, 0),
              CE_None);
  }
  GDALClose(ds);
}

std::string bytes_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}
void write_bytes(const std::string& path, const std::string& b) { std::ofstream(path, std::ios::binary) << b; }

// The InputError's message, or "" if the file was read. Nothing may reach stderr meanwhile:
// libtiff's and libgeotiff's messages go to the error, not to the terminal.
std::string error_of(const std::string& path) {
  std::fflush(stderr);
  std::FILE* sink = std::tmpfile();
  const int saved = ::dup(2);
  ::dup2(::fileno(sink), 2);
  std::string message;
  try {
    io::detail::read_float_tiff(path);
  } catch (const InputError& e) {
    message = e.what();
  }
  std::fflush(stderr);
  ::dup2(saved, 2);
  ::close(saved);
  std::rewind(sink);
  std::string printed;
  for (int c; (c = std::fgetc(sink)) != EOF;) printed += static_cast<char>(c);
  std::fclose(sink);
  EXPECT_EQ(printed, "") << path;
  return message;
}
}  // namespace

TEST(TiffReader, ReadsOurOwnClassicAndBigTiffBitForBit) {
  const std::string dir = test::fresh_dir();
  for (bool big : {false, true}) {
    FloatTiff t;
    t.width = kWidth;
    t.height = 9;
    t.bands = 5;
    t.rows_per_strip = 4;  // the last strip holds one row
    t.pixel_scale[0] = t.pixel_scale[1] = 0.5;
    t.tiepoint[3] = -3.0;
    t.tiepoint[4] = 12.5;
    t.gdal_metadata = io::detail::gdal_metadata({{"PCDP_A", "1.5"}, {"PCDP_B", "x < y & \"z\""}}, {"elevation", ""});
    t.bigtiff = big;
    t.groups = {2, 3};
    const std::string path = dir + (big ? "/big.tif" : "/classic.tif");
    io::detail::write_float_tiff(path, t, 6, fill, run_in_order);
    const FloatTiffData d = io::detail::read_float_tiff(path);
    expect_values(d, 5, 9);
    EXPECT_TRUE(d.georeferenced);
    EXPECT_EQ(d.pixel_scale[0], 0.5);
    EXPECT_EQ(d.tiepoint[3], -3.0);
    EXPECT_EQ(d.tiepoint[4], 12.5);
    EXPECT_EQ(d.gdal_metadata, t.gdal_metadata);
    // Row by row (what `merge` reads): the strips in order, 4 + 4 + 1 rows, every band's rows.
    io::detail::FloatTiffRows rows(path);
    EXPECT_EQ(rows.info().height, 9);
    std::vector<std::vector<float>> got;
    int first = -1, count = 0, next_row = 0;
    std::vector<int> counts;
    while (rows.next(first, count, got)) {
      EXPECT_EQ(first, next_row);
      ASSERT_EQ(got.size(), 5u);
      for (int b = 0; b < 5; ++b)
        for (int i = 0; i < count * kWidth; ++i)
          EXPECT_EQ(std::memcmp(&got[static_cast<std::size_t>(b)][static_cast<std::size_t>(i)],
                                &d.planes[static_cast<std::size_t>(b)][static_cast<std::size_t>(first * kWidth + i)],
                                sizeof(float)),
                    0);
      counts.push_back(count);
      next_row += count;
    }
    EXPECT_EQ(counts, (std::vector<int>{4, 4, 1}));
    EXPECT_FALSE(rows.next(first, count, got));  // and stays at the end
    // Dataset items only (not the band description), unescaped twice as GDAL does.
    const auto items = io::detail::gdal_metadata_items(d.gdal_metadata);
    ASSERT_EQ(items.size(), 2u);
    EXPECT_EQ(items[0], (std::pair<std::string, std::string>{"PCDP_A", "1.5"}));
    EXPECT_EQ(items[1], (std::pair<std::string, std::string>{"PCDP_B", "x < y & \"z\""}));
  }
}

TEST(TiffReader, ReadsFilesAsGdalWroteThemForPcdPipeline) {
  const std::string dir = test::fresh_dir();
  // What fuse_elevation asked of GDAL before our writer (DEFLATE, band interleaved, strips of
  // BLOCKYSIZE rows), and the variants GDAL writes by default: pixel interleaved, uncompressed.
  const std::vector<std::vector<std::string>> variants = {
      {"COMPRESS=DEFLATE", "ZLEVEL=1", "INTERLEAVE=BAND", "BLOCKYSIZE=4"},
      {"COMPRESS=DEFLATE", "INTERLEAVE=PIXEL", "BLOCKYSIZE=3"},
      {"INTERLEAVE=BAND"},
      {"COMPRESS=DEFLATE", "INTERLEAVE=BAND", "BLOCKYSIZE=5", "BIGTIFF=YES"}};
  for (std::size_t k = 0; k < variants.size(); ++k) {
    const std::string path = dir + "/gdal" + std::to_string(k) + ".tif";
    gdal_write(path, 4, 10, variants[k]);
    const FloatTiffData d = io::detail::read_float_tiff(path);
    SCOPED_TRACE(path);
    expect_values(d, 4, 10);
    ASSERT_TRUE(d.georeferenced);
    // GDAL's geotransform from the tags: the north-west corner and the pixel size.
    EXPECT_EQ(d.tiepoint[3] - d.tiepoint[0] * d.pixel_scale[0], -4.5);
    EXPECT_EQ(d.tiepoint[4] + d.tiepoint[1] * d.pixel_scale[1], 7.75);
    EXPECT_EQ(d.pixel_scale[0], 0.25);
    bool found = false;
    for (const auto& [name, v] : io::detail::gdal_metadata_items(d.gdal_metadata))
      if (name == "PCDP_NOTE") found = v == "a<b & \"c\"";
    EXPECT_TRUE(found) << d.gdal_metadata;
  }
}

TEST(TiffReader, ReadsTiledFilesAsGdalWritesThem) {
  // Tiled GeoTIFFs (GDAL's TILED=YES, what cloud-optimized GeoTIFFs use): 16 x 16 tiles over a
  // 37 x 35 raster, three tiles across and down, the right and bottom ones padded; band and pixel
  // interleaved, DEFLATE and none. Every sample as written, bit for bit.
  const std::string dir = test::fresh_dir();
  const int width = 37, height = 35, bands = 3;
  float (*v)(int, int, int) = [](int b, int col, int row) {
    return (5 * col + 3 * row) % 11 == 0 ? std::numeric_limits<float>::quiet_NaN()
                                         : static_cast<float>(b * 10000 + row * 100 + col) + 0.375f;
  };
  const std::vector<std::vector<std::string>> variants = {
      {"TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16", "COMPRESS=DEFLATE", "INTERLEAVE=BAND"},
      {"TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16", "COMPRESS=DEFLATE", "INTERLEAVE=PIXEL"},
      {"TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=16", "INTERLEAVE=PIXEL"},
      {"TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=48", "INTERLEAVE=BAND", "BIGTIFF=YES"}};
  for (std::size_t k = 0; k < variants.size(); ++k) {
    const std::string path = dir + "/tiled" + std::to_string(k) + ".tif";
    SCOPED_TRACE(path);
    gdal_write(path, bands, height, variants[k], width, v);
    GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
    ASSERT_NE(ds, nullptr);
    int bx = 0, by = 0;
    ds->GetRasterBand(1)->GetBlockSize(&bx, &by);
    GDALClose(ds);
    ASSERT_EQ(bx, k == 2 ? 32 : 16);  // GDAL made tiles, not strips
    ASSERT_EQ(by, k == 3 ? 48 : 16);
    const FloatTiffData d = io::detail::read_float_tiff(path);
    ASSERT_EQ(d.width, width);
    ASSERT_EQ(d.height, height);
    ASSERT_EQ(d.bands, bands);
    std::size_t nan = 0;
    for (int b = 0; b < bands; ++b)
      for (int i = 0; i < width * height; ++i) {
        const float got = d.planes[static_cast<std::size_t>(b)][static_cast<std::size_t>(i)], want = v(b, i % width, i / width);
        if (std::isnan(want)) {
          ++nan;
          ASSERT_TRUE(std::isnan(got)) << b << " " << i;
        } else {
          ASSERT_EQ(got, want) << b << " " << i;
        }
      }
    EXPECT_GT(nan, 0u);
    // Row by row: one row of tiles at a time, top first, the last one cut to the raster.
    io::detail::FloatTiffRows rows(path);
    std::vector<std::vector<float>> got;
    int first = 0, count = 0, expect_first = 0;
    const int tile_rows = k == 3 ? 48 : 16;
    while (rows.next(first, count, got)) {
      EXPECT_EQ(first, expect_first);
      EXPECT_EQ(count, std::min(tile_rows, height - first));
      expect_first += count;
    }
    EXPECT_EQ(expect_first, height);
  }
}

TEST(TiffReader, RejectsWhatItCannotReadNamingTheFileAndTheRule) {
  const std::string dir = test::fresh_dir();
  const auto expect_error = [&](const std::string& path, const std::string& rule) {
    const std::string e = error_of(path);
    EXPECT_NE(e.find(path), std::string::npos) << e;
    EXPECT_NE(e.find(rule), std::string::npos) << "wanted '" << rule << "' in: " << e;
  };
  expect_error(dir + "/missing.tif", "cannot open");
  write_bytes(dir + "/text.tif", "hello, this is not a TIFF");
  expect_error(dir + "/text.tif", "not a TIFF file");
  // libtiff reads big-endian files too; this one is a header and nothing else.
  write_bytes(dir + "/mm.tif", std::string("MM\0*\0\0\0\x08", 8));
  expect_error(dir + "/mm.tif", "not a TIFF file libtiff can read");
  // GDAL files of kinds we do not read.
  gdal_write(dir + "/lzw.tif", 2, 6, {"COMPRESS=LZW"});
  expect_error(dir + "/lzw.tif", "tag 259 (Compression) = 5");
  gdal_write(dir + "/pred.tif", 2, 6, {"COMPRESS=DEFLATE", "PREDICTOR=3"});
  expect_error(dir + "/pred.tif", "tag 317 (Predictor) = 3");
  {
    GDALAllRegister();
    GDALDataset* ds = GetGDALDriverManager()->GetDriverByName("GTiff")->Create((dir + "/int.tif").c_str(), 4, 4, 1,
                                                                              GDT_Int16, nullptr);
    ASSERT_NE(ds, nullptr);
    GDALClose(ds);
    expect_error(dir + "/int.tif", "tag 258 (BitsPerSample) = 16");
  }
  // A tiled file whose TileWidth (tag 322) claims tiles far larger than the file could hold:
  // refused before a tile's buffer is allocated.
  gdal_write(dir + "/tiled.tif", 2, 6, {"TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16"});
  ASSERT_EQ(error_of(dir + "/tiled.tif"), "");
  std::string tiled = bytes_of(dir + "/tiled.tif");
  const auto u32 = [&](std::size_t at) {
    std::uint32_t x = 0;
    std::memcpy(&x, tiled.data() + at, 4);
    return x;
  };
  const std::size_t dir0 = u32(4);
  std::uint16_t entries = 0;
  std::memcpy(&entries, tiled.data() + dir0, 2);
  bool patched = false;
  for (std::size_t e = 0; e < entries; ++e) {
    const std::size_t at = dir0 + 2 + 12 * e;
    std::uint16_t tag = 0, type = 0;
    std::memcpy(&tag, tiled.data() + at, 2);
    std::memcpy(&type, tiled.data() + at + 2, 2);
    if (tag != 322) continue;
    const std::uint32_t huge = type == 3 ? 0xFFF0u : 0x7FFFFFF0u;  // SHORT or LONG; a multiple of 16, as TIFF asks
    std::memcpy(&tiled[at + 8], &huge, type == 3 ? 2 : 4);
    patched = true;
  }
  ASSERT_TRUE(patched);
  write_bytes(dir + "/huge_tiles.tif", tiled);
  expect_error(dir + "/huge_tiles.tif", "larger than the file's");
  // Our own file, damaged: cut short, a strip's bytes flipped, a raster claimed far larger than
  // the file can hold (nothing that size is allocated).
  FloatTiff t;
  t.width = kWidth;
  t.height = 9;
  t.bands = 2;
  t.rows_per_strip = 9;
  io::detail::write_float_tiff(dir + "/ok.tif", t, 1, fill, run_in_order);
  const std::string ok = bytes_of(dir + "/ok.tif");
  ASSERT_EQ(error_of(dir + "/ok.tif"), "");
  write_bytes(dir + "/short.tif", ok.substr(0, ok.size() - 40));
  expect_error(dir + "/short.tif", "its directory is damaged (libtiff: ");
  std::string flipped = ok;
  for (std::size_t i = 10; i < 30; ++i) flipped[i] = static_cast<char>(~flipped[i]);
  write_bytes(dir + "/flipped.tif", flipped);
  expect_error(dir + "/flipped.tif", "strip 0 cannot be decoded (row 0) (libtiff: ");
  // ImageLength is the second entry of the directory: its value field set to 2^31 - 1 rows.
  std::uint32_t ifd = 0;
  std::memcpy(&ifd, ok.data() + 4, 4);
  std::string huge = ok;
  const std::size_t length_value = ifd + 2 + 12 + 8;
  std::uint16_t tag = 0;
  std::memcpy(&tag, huge.data() + ifd + 2 + 12, 2);
  ASSERT_EQ(tag, 257u);
  const std::uint32_t rows = 0x7fffffff;
  std::memcpy(&huge[length_value], &rows, 4);
  write_bytes(dir + "/huge.tif", huge);
  expect_error(dir + "/huge.tif", "its directory is damaged (libtiff: Incorrect count for \"StripOffsets\"");
}
