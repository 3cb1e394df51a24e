// The float32 GeoTIFF writer (lib/src/io/tiff_writer.hpp), read back through GDAL: values,
// strips, georeferencing, metadata, nodata, classic and BigTIFF, the same bytes whatever the
// order or threads its tasks run on, and errors that leave no file.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "io/tiff_writer.hpp"
#include "pipeline/ordered_parallel.hpp"
#include "test_support.hpp"

using namespace pcdp;
using io::detail::FloatTiff;

namespace {
// Band b's value at (col, row); NaN in a diagonal stripe (nodata).
float value(int b, int col, int row) {
  if ((col + row) % 5 == 0) return std::numeric_limits<float>::quiet_NaN();
  return static_cast<float>(b * 1000 + row * 10 + col) + 0.25f;
}

FloatTiff image(int w, int h, int bands, int rps) {
  FloatTiff t;
  t.width = w;
  t.height = h;
  t.bands = bands;
  t.rows_per_strip = rps;
  t.pixel_scale[0] = t.pixel_scale[1] = 0.5;
  t.tiepoint[3] = -3.0;
  t.tiepoint[4] = 12.5;
  t.gdal_metadata = io::detail::gdal_metadata({{"KEY", "a<b & \"c\""}}, {"", "second"});
  t.gdal_nodata = "nan";
  return t;
}

const io::detail::PlaneFill fill = [](int first, std::vector<std::vector<float>>& planes) {
  const int w = 7;
  for (std::size_t j = 0; j < planes.size(); ++j)
    for (std::size_t i = 0; i < planes[j].size(); ++i)
      planes[j][i] = value(first + static_cast<int>(j), static_cast<int>(i % w), static_cast<int>(i / w));
};

std::string bytes_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}

// Reads every band through GDAL and checks the values, georeferencing and tags.
void expect_reads_back(const std::string& path, const FloatTiff& t) {
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr) << path;
  EXPECT_EQ(ds->GetRasterXSize(), t.width);
  EXPECT_EQ(ds->GetRasterYSize(), t.height);
  ASSERT_EQ(ds->GetRasterCount(), t.bands);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  EXPECT_DOUBLE_EQ(gt[0], -3.0);
  EXPECT_DOUBLE_EQ(gt[1], 0.5);
  EXPECT_DOUBLE_EQ(gt[3], 12.5);
  EXPECT_DOUBLE_EQ(gt[5], -0.5);
  ASSERT_NE(ds->GetMetadataItem("KEY"), nullptr);
  EXPECT_STREQ(ds->GetMetadataItem("KEY"), "a<b & \"c\"");
  EXPECT_STREQ(ds->GetRasterBand(2)->GetDescription(), "second");
  int has_nodata = 0;
  EXPECT_TRUE(std::isnan(ds->GetRasterBand(1)->GetNoDataValue(&has_nodata)));
  EXPECT_TRUE(has_nodata);
  int bx = 0, by = 0;
  ds->GetRasterBand(1)->GetBlockSize(&bx, &by);
  EXPECT_EQ(by, t.rows_per_strip);
  std::vector<float> plane(static_cast<std::size_t>(t.width) * static_cast<std::size_t>(t.height));
  std::size_t checked = 0;
  for (int b = 0; b < t.bands; ++b) {
    ASSERT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Read, 0, 0, t.width, t.height, plane.data(), t.width, t.height,
                                                 GDT_Float32, 0, 0),
              CE_None);
    for (int row = 0; row < t.height; ++row)
      for (int col = 0; col < t.width; ++col) {
        const float v = plane[static_cast<std::size_t>(row) * static_cast<std::size_t>(t.width) + static_cast<std::size_t>(col)];
        const float want = value(b, col, row);
        if (std::isnan(want)) EXPECT_TRUE(std::isnan(v));
        else EXPECT_EQ(v, want) << "band " << b << " col " << col << " row " << row;
        ++checked;
      }
  }
  EXPECT_EQ(checked, static_cast<std::size_t>(t.bands * t.width * t.height));
  GDALClose(ds);
}

// Runs the tasks last to first: a thread order the serial share never uses.
class ReverseShare final : public WorkShare {
 public:
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    for (std::size_t i = n; i-- > 0;) task(i);
  }
};
// Runs the tasks on two threads.
class TwoThreads final : public WorkShare {
 public:
  void run(std::size_t n, const std::function<void(std::size_t)>& task) override {
    detail::parallel_for(n, 2, [&](std::size_t i) { task(i); });
  }
};
}  // namespace

TEST(TiffWriter, ClassicAndBigTiffReadBackThroughGdal) {
  const std::string dir = test::fresh_dir();
  // 7 x 9 cells in strips of 4 rows: the last strip holds one row.
  FloatTiff t = image(7, 9, 3, 4);
  io::detail::write_float_tiff(dir + "/c.tif", t, 1, fill, WorkShare::serial());
  expect_reads_back(dir + "/c.tif", t);
  EXPECT_EQ(bytes_of(dir + "/c.tif").substr(0, 4), std::string("II*\0", 4));
  t.bigtiff = true;
  io::detail::write_float_tiff(dir + "/b.tif", t, 12, fill, WorkShare::serial());
  expect_reads_back(dir + "/b.tif", t);
  EXPECT_EQ(bytes_of(dir + "/b.tif").substr(0, 4), std::string("II+\0", 4));
  // libtiff's own codec (the comparison of bench/bench_tiff.cpp): the same values, and with
  // Debian's libtiff on libdeflate at the same level, the same bytes.
  FloatTiff codec = t;
  codec.libtiff_codec = true;
  io::detail::write_float_tiff(dir + "/codec.tif", codec, 12, fill, WorkShare::serial());
  expect_reads_back(dir + "/codec.tif", codec);
  EXPECT_EQ(bytes_of(dir + "/codec.tif").size(), bytes_of(dir + "/b.tif").size());
  // One band, one strip: no ExtraSamples tag, still read.
  FloatTiff one = image(7, 2, 1, 2);
  one.gdal_metadata = io::detail::gdal_metadata({{"KEY", "x & y"}}, {});
  io::detail::write_float_tiff(dir + "/one.tif", one, 1, fill, WorkShare::serial());
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir + "/one.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(ds->GetRasterCount(), 1);
  EXPECT_STREQ(ds->GetMetadataItem("KEY"), "x & y");
  EXPECT_STREQ(ds->GetRasterBand(1)->GetDescription(), "");
  GDALClose(ds);
}

TEST(TiffWriter, SameBytesWhateverTheOrderAndThreadsOfItsTasks) {
  const std::string dir = test::fresh_dir();
  const FloatTiff t = image(7, 40, 22, 3);
  ReverseShare reverse;
  TwoThreads two;
  io::detail::write_float_tiff(dir + "/serial.tif", t, 1, fill, WorkShare::serial());
  io::detail::write_float_tiff(dir + "/reverse.tif", t, 1, fill, reverse);
  io::detail::write_float_tiff(dir + "/two.tif", t, 1, fill, two);
  const std::string serial = bytes_of(dir + "/serial.tif");
  EXPECT_GT(serial.size(), 100u);
  EXPECT_EQ(serial, bytes_of(dir + "/reverse.tif"));
  EXPECT_EQ(serial, bytes_of(dir + "/two.tif"));
  expect_reads_back(dir + "/two.tif", t);
  // Bands filled in groups: the same file.
  FloatTiff grouped = t;
  grouped.groups = {6, 4, 4, 4, 4};
  io::detail::write_float_tiff(dir + "/grouped.tif", grouped, 1, fill, two);
  EXPECT_EQ(serial, bytes_of(dir + "/grouped.tif"));
  grouped.groups = {6, 4, 4, 4};  // 18 of 22 bands
  EXPECT_THROW(io::detail::write_float_tiff(dir + "/short.tif", grouped, 1, fill, two), std::invalid_argument);
  grouped.groups = {6, 0, 4, 4, 4, 4};
  EXPECT_THROW(io::detail::write_float_tiff(dir + "/zero.tif", grouped, 1, fill, two), std::invalid_argument);
}

TEST(TiffWriter, ErrorsNameThePathAndLeaveNoFile) {
  const std::string dir = test::fresh_dir();
  const FloatTiff t = image(7, 9, 3, 4);
  try {
    io::detail::write_float_tiff(dir + "/no/such/dir/x.tif", t, 1, fill, WorkShare::serial());
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no/such/dir/x.tif"), std::string::npos) << e.what();
  }
  // A band that cannot be filled: the error comes through, and nothing is written.
  const io::detail::PlaneFill bad = [](int first, std::vector<std::vector<float>>&) {
    if (first == 2) throw std::runtime_error("band 2 failed");
  };
  EXPECT_THROW(io::detail::write_float_tiff(dir + "/bad.tif", t, 1, bad, WorkShare::serial()), std::runtime_error);
  EXPECT_FALSE(std::ifstream(dir + "/bad.tif").good());
  FloatTiff empty = t;
  empty.width = 0;
  EXPECT_THROW(io::detail::write_float_tiff(dir + "/e.tif", empty, 1, fill, WorkShare::serial()), std::invalid_argument);
  EXPECT_THROW(io::detail::write_float_tiff(dir + "/l.tif", t, 13, fill, WorkShare::serial()), std::runtime_error);
  EXPECT_FALSE(std::ifstream(dir + "/l.tif").good());
}
