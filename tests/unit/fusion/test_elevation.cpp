#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <vector>

#include "io/elevation_png.hpp"
#include "pcdp/fusion/elevation.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/sim/nodding_sim.hpp"
#include "pcdp/stages/fuse_elevation.hpp"
#include "pcdp/stages/register.hpp"
#include "test_support.hpp"

using namespace pcdp;
namespace fs = std::filesystem;

namespace {
void expect_same(const ElevationGrid& a, const ElevationGrid& b, double tol) {
  std::size_t n = 0;
  a.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    const ElevationCell* d = b.find(ix, iy);
    ASSERT_NE(d, nullptr) << ix << "," << iy;
    EXPECT_EQ(c.count, d->count);
    EXPECT_EQ(c.passes, d->passes);
    EXPECT_EQ(c.bands[0].index, d->bands[0].index);
    double e1, v1, e2, v2;
    const bool s1 = a.surface(c, e1, v1), s2 = b.surface(*d, e2, v2);
    EXPECT_EQ(s1, s2);
    if (s1 && s2) {
      EXPECT_NEAR(e1, e2, tol);
      EXPECT_NEAR(v1, v2, tol * v1);
    }
    EXPECT_EQ(c.zmax, d->zmax);
    ++n;
  });
  EXPECT_EQ(n, b.size());
}

// What Debian's gdalinfo prints for a file (the test fails if it cannot read it).
std::string gdalinfo(const std::string& tif) {
  const std::string txt = tif + ".info.txt";
  const std::string cmd = "gdalinfo " + tif + " > " + txt + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << test::read_text(txt);
  return test::read_text(txt);
}

std::vector<Pass> registered_sample_like_passes() {
  sim::SimConfig c = test::small_sim_config();
  c.passes = 4;
  c.scanner.range_sigma = 0.005;
  const auto r = sim::simulate(c);
  const PoseTrack poses(r.poses);
  std::vector<Pass> out;
  for (const auto& sp : r.passes) {
    Pass p = sp.pass;
    register_pass(p, RegisterParams{}, SensorParams{}, make_transform(c.mount_translation, c.mount_rpy, c.rpy_order), &poses);
    out.push_back(std::move(p));
  }
  return out;
}
}  // namespace

TEST(Elevation, TopSurfaceGateKeepsTheTopOfAFaceAndIgnoresLowerPoints) {
  ElevationGrid g(0.1, 0.05);
  for (int i = 0; i < 20; ++i) g.add(0.05, 0.05, 0.02 * i, 1e-4, 0);  // a vertical face 0 .. 0.38 m
  for (int i = 0; i < 5; ++i) g.add(0.05, 0.05, 0.40, 1e-4, 0);       // its top surface
  const ElevationCell* c = g.find(0, 0);
  ASSERT_NE(c, nullptr);
  double e, v;
  ASSERT_TRUE(g.surface(*c, e, v));
  EXPECT_NEAR(e, 0.39, 0.02);
  EXPECT_EQ(c->count, 25u);
  EXPECT_NEAR(c->zmin, 0.0, 1e-6);
  g.add(0.05, 0.05, -0.5, 1e-4, 1);  // a point under an overhang: counted, not fused
  ASSERT_TRUE(g.surface(*g.find(0, 0), e, v));
  EXPECT_NEAR(e, 0.39, 0.02);
  EXPECT_EQ(g.find(0, 0)->passes, 2u);
  g.add(0.05, 0.05, 1.3, 1e-4, 1);  // a lone stray point far above: not the surface (min_support 2)
  ASSERT_TRUE(g.surface(*g.find(0, 0), e, v));
  EXPECT_NEAR(e, 0.39, 0.02);
  g.add(0.05, 0.05, 1.31, 1e-4, 1);  // a second one: now it is a surface
  ASSERT_TRUE(g.surface(*g.find(0, 0), e, v));
  EXPECT_NEAR(e, 1.305, 0.01);
}

TEST(Elevation, InverseVarianceWeighting) {
  ElevationGrid g(1.0, 1.0);
  g.add(0.5, 0.5, 0.10, 1e-4, 0);
  g.add(0.5, 0.5, 0.20, 4e-4, 0);  // four times the variance: a quarter of the weight
  double e, v;
  ASSERT_TRUE(g.surface(*g.find(0, 0), e, v));
  EXPECT_NEAR(e, (0.10 * 4 + 0.20) / 5, 1e-12);
  EXPECT_NEAR(v, 1.0 / (1e4 + 2.5e3), 1e-15);
}

TEST(Elevation, MergingGridsOfDisjointPassesEqualsFusingAllPasses) {
  const auto passes = registered_sample_like_passes();
  FuseElevationParams prm;
  ElevationGrid all(prm.resolution, prm.band);
  for (const auto& p : passes) fuse_pass(all, p, prm, 1e-4);
  // Every grouping and order: {0,1} + {2,3}, {3} + {0,2} + {1}, and the reverse.
  ElevationGrid a(prm.resolution, prm.band), b(prm.resolution, prm.band);
  fuse_pass(a, passes[0], prm, 1e-4);
  fuse_pass(a, passes[1], prm, 1e-4);
  fuse_pass(b, passes[2], prm, 1e-4);
  fuse_pass(b, passes[3], prm, 1e-4);
  ElevationGrid ab = a;
  ab.merge(b);
  expect_same(all, ab, 1e-9);
  ElevationGrid ba = b;
  ba.merge(a);
  expect_same(all, ba, 1e-9);
  ElevationGrid g3(prm.resolution, prm.band), g02(prm.resolution, prm.band), g1(prm.resolution, prm.band);
  fuse_pass(g3, passes[3], prm, 1e-4);
  fuse_pass(g02, passes[0], prm, 1e-4);
  fuse_pass(g02, passes[2], prm, 1e-4);
  fuse_pass(g1, passes[1], prm, 1e-4);
  g3.merge(g02);
  g3.merge(g1);
  expect_same(all, g3, 1e-9);
  // And through GeoTIFF files (float32 bands: elevations agree to float32 precision).
  const std::string dir = test::fresh_dir();
  io::write_elevation_geotiff(a, dir + "/a.tif");
  io::write_elevation_geotiff(b, dir + "/b.tif");
  io::write_elevation_geotiff(all, dir + "/all.tif");
  ElevationGrid fa = io::read_elevation_geotiff(dir + "/a.tif");
  fa.merge(io::read_elevation_geotiff(dir + "/b.tif"));
  expect_same(io::read_elevation_geotiff(dir + "/all.tif"), fa, 1e-6);
  // merge_elevation_geotiff (what `merge` does) reads b into the grid a strip of rows at a time
  // (these files hold several strips): the same cells, the same floats, in the same order.
  ElevationGrid fs = io::read_elevation_geotiff(dir + "/a.tif");
  io::merge_elevation_geotiff(fs, dir + "/b.tif");
  ASSERT_EQ(fs.size(), fa.size());
  expect_same(fa, fs, 0.0);
  std::vector<std::int64_t> order_a, order_s;
  fa.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell&) { order_a.insert(order_a.end(), {ix, iy}); });
  fs.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell&) { order_s.insert(order_s.end(), {ix, iy}); });
  EXPECT_EQ(order_a, order_s);
  // b's merge state re-tiled by GDAL, as a user making a cloud-optimized GeoTIFF of b would (16 x
  // 16 tiles, several across and down): merged, the same cells and floats.
  {
    GDALAllRegister();
    GDALDataset* src = static_cast<GDALDataset*>(GDALOpen((dir + "/b.state.tif").c_str(), GA_ReadOnly));
    ASSERT_NE(src, nullptr);
    ASSERT_GT(src->GetRasterXSize(), 32);
    ASSERT_GT(src->GetRasterYSize(), 32);
    char** o = nullptr;
    for (const char* kv : {"TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16", "COMPRESS=DEFLATE"}) o = CSLAddString(o, kv);
    GDALDataset* tiled = GetGDALDriverManager()->GetDriverByName("GTiff")->CreateCopy(
        (dir + "/b_tiled.state.tif").c_str(), src, FALSE, o, nullptr, nullptr);
    CSLDestroy(o);
    ASSERT_NE(tiled, nullptr);
    int bx = 0, by = 0;
    tiled->GetRasterBand(1)->GetBlockSize(&bx, &by);
    EXPECT_EQ(bx, 16);
    GDALClose(tiled);
    GDALClose(src);
    ElevationGrid ft = io::read_elevation_geotiff(dir + "/a.tif");
    io::merge_elevation_geotiff(ft, dir + "/b_tiled.tif");
    ASSERT_EQ(ft.size(), fa.size());
    expect_same(fa, ft, 0.0);
  }
  // A grid of another resolution is refused before any cell is read: the grid is as it was.
  ElevationGrid coarse(2 * prm.resolution, prm.band);
  fuse_pass(coarse, passes[2], prm, 1e-4);
  io::write_elevation_geotiff(coarse, dir + "/coarse.tif");
  try {
    io::merge_elevation_geotiff(fs, dir + "/coarse.tif");
    ADD_FAILURE() << "merged a grid of another resolution";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("coarse.state.tif: resolution " + format_value(2 * prm.resolution) + " m"),
              std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("grids merge only on the same grid"), std::string::npos) << e.what();
  }
  ASSERT_EQ(fs.size(), fa.size());
  expect_same(fa, fs, 0.0);
}

TEST(Elevation, GeoTiffRoundTripAndGdalinfo) {
  ElevationGrid g(0.25, 0.05);
  g.add(1.1, -2.3, 0.5, 1e-4, 0);
  g.add(1.1, -2.3, 0.51, 1e-4, 0);
  g.add(3.9, 4.4, 1.5, 1e-4, 0);
  const std::string dir = test::fresh_dir();
  // It returns the cells with a surface: the first has two points, the second one, below the
  // default min_support of 2.
  EXPECT_EQ(io::write_elevation_geotiff(g, dir + "/e.tif"), 1u);
  expect_same(g, io::read_elevation_geotiff(dir + "/e.tif"), 1e-6);
  // gdalinfo (Debian's gdal-bin) sees the bands, nodata and north-up geotransform of docs/data_contract.md.
  const std::string info = gdalinfo(dir + "/e.tif");
  EXPECT_NE(info.find("Origin = (1.000000000000000,4.500000000000000)"), std::string::npos) << info;
  EXPECT_NE(info.find("Pixel Size = (0.250000000000000,-0.250000000000000)"), std::string::npos) << info;
  for (const char* band : {"Band 1 Block", "Description = elevation", "Description = variance", "Description = count",
                           "Description = min", "Description = max"})
    EXPECT_NE(info.find(band), std::string::npos) << band;
  EXPECT_NE(info.find("NoData Value=nan"), std::string::npos);
  EXPECT_NE(info.find("Type=Float32"), std::string::npos);
  // Copies GDAL makes of it (as GDAL wrote elevation.tif for earlier versions, and in the layouts
  // it writes by default) are the same grid to `merge`, which reads without GDAL.
  GDALAllRegister();
  GDALDataset* src = static_cast<GDALDataset*>(GDALOpen((dir + "/e.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(src, nullptr);
  const std::vector<std::vector<const char*>> layouts = {
      {"COMPRESS=DEFLATE", "INTERLEAVE=BAND", nullptr}, {"INTERLEAVE=PIXEL", nullptr}, {"BIGTIFF=YES", nullptr}};
  GDALDataset* state = static_cast<GDALDataset*>(GDALOpen((dir + "/e.state.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(state, nullptr);
  for (std::size_t k = 0; k < layouts.size(); ++k) {
    // Both files copied: the grid and its merge state (which `merge` reads).
    const std::string copy = dir + "/copy" + std::to_string(k) + ".tif";
    for (const auto& [from, to] : {std::make_pair(src, copy), std::make_pair(state, io::elevation_state_path(copy))}) {
      GDALDataset* dst = GetGDALDriverManager()->GetDriverByName("GTiff")->CreateCopy(
          to.c_str(), from, FALSE, const_cast<char**>(layouts[k].data()), nullptr, nullptr);
      ASSERT_NE(dst, nullptr);
      GDALClose(dst);
    }
    expect_same(g, io::read_elevation_geotiff(copy), 1e-6);
  }
  GDALClose(state);
  // The grid without its merge state is refused, naming the missing file.
  try {
    std::filesystem::remove(dir + "/copy0.state.tif");
    io::read_elevation_geotiff(dir + "/copy0.tif");
    ADD_FAILURE() << "read without its merge state";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("its merge state " + dir + "/copy0.state.tif is missing"), std::string::npos)
        << e.what();
  }
  GDALClose(src);
  // Without the PCDP_* metadata it is not one of our grids.
  GDALDataset* bare = GetGDALDriverManager()->GetDriverByName("GTiff")->Create((dir + "/bare.tif").c_str(), 4, 4, 22,
                                                                              GDT_Float32, nullptr);
  ASSERT_NE(bare, nullptr);
  GDALClose(bare);
  try {
    io::read_elevation_geotiff(dir + "/bare.tif");
    ADD_FAILURE() << "read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not an elevation grid of pcd_pipeline"), std::string::npos) << e.what();
  }
}

TEST(Elevation, GeoTiffStripsHoldAtLeast64KiBOfABand) {
  // Strips of >= 64 KiB (16,384 float cells): a narrow tall grid gets ceil(65536 / 40) = 1,639
  // rows a strip, a grid wider than 16,384 cells one row, a small grid a single strip. Each
  // round-trips whatever its strips.
  const auto block_of = [](const ElevationGrid& g, const std::string& dir) {
    io::write_elevation_geotiff(g, dir + "/s.tif");
    expect_same(g, io::read_elevation_geotiff(dir + "/s.tif"), 1e-6);
    const std::string info = gdalinfo(dir + "/s.tif");
    const auto at = info.find("Band 1 Block=");
    return at == std::string::npos ? info : info.substr(at + 13, info.find(' ', at + 13) - at - 13);
  };
  const std::string dir = test::fresh_dir();
  ElevationGrid tall(0.5, 0.05), wide(0.5, 0.05), small(0.5, 0.05);
  tall.add(0.1, 0.1, 1.0, 1e-4, 0);
  tall.add(4.9, 2499.9, 2.0, 1e-4, 0);  // 10 x 5000 cells
  wide.add(0.1, 0.1, 1.0, 1e-4, 0);
  wide.add(10000.1, 0.6, 2.0, 1e-4, 0);  // 20001 x 2 cells
  small.add(0.1, 0.1, 1.0, 1e-4, 0);
  small.add(9.9, 4.9, 2.0, 1e-4, 0);  // 20 x 10 cells
  EXPECT_EQ(block_of(tall, dir), "10x1639");
  EXPECT_EQ(block_of(wide, dir), "20001x1");
  EXPECT_EQ(block_of(small, dir), "20x10");
}

TEST(Elevation, PngShowsTheGridNorthUpAndFailsWithoutLeavingAFile) {
  // A plane rising eastwards, 40 x 20 cells of 0.5 m, with one empty cell. The map is drawn at 8
  // pixels a cell (900 / 40 capped at 8), where the picture's layout says.
  ElevationGrid g(0.5, 0.05);
  for (int ix = 0; ix < 40; ++ix)
    for (int iy = 0; iy < 20; ++iy)
      if (!(ix == 10 && iy == 15))
        for (int k = 0; k < 2; ++k) g.add(0.5 * ix + 0.25, 0.5 * iy + 0.25, 0.05 * ix, 1e-4, 0);  // min_support 2
  const std::string dir = test::fresh_dir();
  io::write_elevation_png(g, dir + "/e.png");
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&img, (dir + "/e.png").c_str())) << img.message;
  img.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> px(PNG_IMAGE_SIZE(img));
  ASSERT_TRUE(png_image_finish_read(&img, nullptr, px.data(), 0, nullptr)) << img.message;
  const io::detail::ElevationPicture pic = io::detail::render_elevation(g);
  ASSERT_EQ(img.width, static_cast<unsigned>(pic.width));
  ASSERT_EQ(img.height, static_cast<unsigned>(pic.height));
  ASSERT_EQ(pic.scale, 8);
  ASSERT_EQ(pic.map_width, 40 * 8);
  ASSERT_EQ(pic.map_height, 20 * 8);
  const auto at = [&](int col, int row, int ch) {  // centre pixel of a cell, north row first
    return px[3 * (static_cast<std::size_t>(pic.cell_y(19 - row)) * img.width + static_cast<std::size_t>(pic.cell_x(col))) +
              static_cast<std::size_t>(ch)];
  };
  // The empty cell (ix 10, iy 15: row 19 - 15 = 4 from the top) is the no-data grey.
  for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(at(10, 4, ch), 225);
  // Away from the edges (where the slope is one-sided) the hillshade is the same everywhere, so
  // green rises with the height along a row (of the ramp's channels, green alone is monotonic:
  // 1, 82, 145, 201, 231), from purple to yellow.
  for (int col = 2; col < 38; ++col) EXPECT_LE(at(col, 10, 1), at(col + 1, 10, 1)) << col;
  EXPECT_GT(at(1, 10, 2), at(1, 10, 1));   // west: more blue than green (the ramp's low end)
  EXPECT_GT(at(38, 10, 1), at(38, 10, 2));  // east: more green than blue (yellow)
  EXPECT_GT(at(38, 10, 1), at(1, 10, 1) + 100);
  // A path that cannot be replaced (a folder) fails with its name and leaves no temporary file.
  fs::create_directories(dir + "/taken.png");
  try {
    io::write_elevation_png(g, dir + "/taken.png");
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("taken.png"), std::string::npos) << e.what();
  }
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename().string().find("tmp"), std::string::npos) << e.path();
}

TEST(Elevation, SamplesAddedInOneBatchEqualPointsAddedOneByOne) {
  // Cells on both sides of zero and far out (negative indices, the 31-bit key's offset) and runs
  // of points in one cell (the batch's last-cell shortcut), in two passes.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> xy(-3000.0, 3000.0), z(-1.0, 1.0), near(-0.04, 0.04);
  ElevationGrid one(0.1, 0.05), batch(0.1, 0.05);
  std::vector<ElevationSample> s;
  for (int pass = 0; pass < 2; ++pass) {
    s.clear();
    for (int i = 0; i < 5000; ++i) {
      const double x = xy(rng), y = i % 3 == 0 ? -0.05 : xy(rng);
      for (int k = 0; k < 1 + i % 4; ++k) {  // 1-4 points in a row in the same cell or next door
        const double px = x + near(rng), py = y + near(rng), pz = z(rng), var = 1e-4 * (1 + k);
        one.add(px, py, pz, var, pass);
        s.push_back(batch.sample(px, py, pz, var, pass));
      }
    }
    batch.add(s.data(), s.size());
  }
  ASSERT_EQ(one.size(), batch.size());
  ASSERT_GT(one.size(), 9000u);
  std::size_t negative = 0;
  one.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    negative += ix < 0 && iy < 0;
    const ElevationCell* d = batch.find(ix, iy);
    ASSERT_NE(d, nullptr) << ix << "," << iy;
    EXPECT_EQ(c.count, d->count);
    EXPECT_EQ(c.passes, d->passes);
    for (int k = 0; k < ElevationCell::kBands; ++k) {
      EXPECT_EQ(c.bands[k].index, d->bands[k].index);
      EXPECT_EQ(c.bands[k].w, d->bands[k].w);  // same sums in the same order: to the bit
      EXPECT_EQ(c.bands[k].wz, d->bands[k].wz);
    }
    EXPECT_EQ(c.zmin, d->zmin);
    EXPECT_EQ(c.zmax, d->zmax);
  });
  EXPECT_GT(negative, 1000u);
  // A cell's indices come back from for_each as they went in, far from the origin too.
  ElevationGrid far(0.001, 0.05);
  far.add(-1.0e6, 1.0e6 - 0.0005, 0.0, 1e-4, 0);
  std::int64_t fx = 0, fy = 0;
  far.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell&) {
    fx = ix;
    fy = iy;
  });
  EXPECT_EQ(fx, far.cell_index(-1.0e6));
  EXPECT_EQ(fy, far.cell_index(1.0e6 - 0.0005));
  EXPECT_NE(far.find(fx, fy), nullptr);
  EXPECT_EQ(far.find(fx + 1, fy), nullptr);
}

TEST(Elevation, DeflateLevelChangesTheFileNotTheGrid) {
  const std::vector<Pass> passes = registered_sample_like_passes();
  FuseElevationParams prm;
  ElevationGrid g(prm.resolution, prm.band);
  for (const auto& p : passes) fuse_pass(g, p, prm, 1e-4);
  const std::string dir = test::fresh_dir();
  io::write_elevation_geotiff(g, dir + "/fast.tif", 1);
  io::write_elevation_geotiff(g, dir + "/small.tif", 12);
  const auto size = [](const std::string& f) {
    std::FILE* fp = std::fopen(f.c_str(), "rb");
    std::fseek(fp, 0, SEEK_END);
    const long n = std::ftell(fp);
    std::fclose(fp);
    return n;
  };
  EXPECT_LT(size(dir + "/small.tif"), size(dir + "/fast.tif"));
  expect_same(io::read_elevation_geotiff(dir + "/fast.tif"), io::read_elevation_geotiff(dir + "/small.tif"), 0.0);
  EXPECT_THROW(io::write_elevation_geotiff(g, dir + "/bad.tif", 13), std::invalid_argument);
  EXPECT_THROW(io::write_elevation_geotiff(g, dir + "/bad.tif", 0), std::invalid_argument);
  EXPECT_FALSE(std::ifstream(dir + "/bad.tif").good());
}
