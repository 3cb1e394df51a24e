// Georeferenced poses (docs/data_contract.md "Coordinates"): the map origin rule, the elevation
// grid's keys far from 0 (no wrap: a clear error beyond what they hold), the GeoTIFF's absolute
// georeferencing of a UTM grid, the PCD products' "# map_origin" header line, and the streaming
// API at UTM scale.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/fusion/elevation.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/io/outputs.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/stages/fuse_elevation.hpp"
#include "pcdp/pipeline/stream.hpp"
#include "pcdp/core/transforms.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
PoseTrack track(const std::vector<Eigen::Vector3d>& positions) {
  std::vector<PoseSample> s;
  for (std::size_t k = 0; k < positions.size(); ++k) {
    PoseSample p;
    p.stamp = static_cast<double>(k);
    p.position = positions[k];
    s.push_back(p);
  }
  return PoseTrack(std::move(s));
}

// One kept point at (x, y, z) in a pass of one return.
Pass point_pass(double x, double y, double z) {
  Pass p = test::line_pass({5.0f}, {100.0f});
  p.source = "far.pcd";
  p.x = {x};
  p.y = {y};
  p.z = {z};
  p.ox = {x - 5.0};
  p.oy = {y};
  p.oz = {z};
  p.cov.clear();
  return p;
}
}  // namespace

TEST(Georef, OriginIsZeroNearZeroAndARoundNumberFarAway) {
  EXPECT_TRUE(choose_map_origin(PoseTrack{}).isZero());
  // Local frames, the simulator, the sample: the origin stays 0 (outputs as without an origin).
  EXPECT_TRUE(choose_map_origin(track({{-999.0, 12.0, 0.4}, {999.0, -999.0, 999.0}})).isZero());
  // UTM: the bounding box's centre, each axis rounded to a whole kilometre (z 100 m rounds to 0).
  const Eigen::Vector3d o = choose_map_origin(track({{500123.4, 5300490.0, 100.0}, {500300.0, 5300700.0, 104.0}}));
  EXPECT_EQ(o, Eigen::Vector3d(500000.0, 5301000.0, 0.0));
  // A local track driving 3.5 km from 0 gets a centred origin: the OctoMap's keys reach +-3.3 km.
  EXPECT_EQ(choose_map_origin(track({{0.0, 0.0, 0.0}, {3500.0, 10.0, 2.0}})), Eigen::Vector3d(2000.0, 0.0, 0.0));
  // Exactly representable in float32.
  for (int a = 0; a < 3; ++a) EXPECT_EQ(static_cast<double>(static_cast<float>(o[a])), o[a]);
  // One axis far is enough; the others round too.
  EXPECT_EQ(choose_map_origin(track({{10.0, 20.0, 5000.0}})), Eigen::Vector3d(0.0, 0.0, 5000.0));
  // The centre, not the first pose: a long drive keeps its ends equally far from the origin.
  EXPECT_EQ(choose_map_origin(track({{500000.0, 0.0, 0.0}, {530000.0, 0.0, 0.0}})).x(), 515000.0);

  const PoseTrack t = track({{500123.4, 5300490.0, 100.0}, {500300.0, 5300700.0, 104.0}});
  const PoseTrack s = shift_poses(t, o);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.samples()[0].position, Eigen::Vector3d(500123.4 - 500000.0, 5300490.0 - 5301000.0, 100.0));
  EXPECT_DOUBLE_EQ(farthest_pose_offset(t, o), 510.0);
}

TEST(Georef, ElevationGridHoldsUtmAtAMillimetreWithoutWrapping) {
  // At 1 mm, UTM northings are 5.3e9 cells from 0: beyond 31-bit keys around 0 (they used to
  // wrap: the cell, and the GeoTIFF's tie point, landed elsewhere). Keys around the grid's key
  // origin hold them, with their absolute indices.
  FuseElevationParams prm;
  prm.resolution = 0.001;
  prm.origin_x = 500000.0;
  prm.origin_y = 5300000.0;
  ElevationGrid g = make_elevation_grid(prm);
  EXPECT_EQ(g.key_origin_x(), g.cell_index(500000.0));
  fuse_pass(g, point_pass(12.3456, -7.891, 100.0), prm, 1e-4);  // pass coordinates are relative to the origin
  ASSERT_EQ(g.size(), 1u);
  std::int64_t ix = 0, iy = 0;
  g.for_each([&](std::int64_t x, std::int64_t y, const ElevationCell&) {
    ix = x;
    iy = y;
  });
  EXPECT_EQ(ix, g.cell_index(500012.3456));
  EXPECT_EQ(iy, g.cell_index(5299992.109));
  EXPECT_NE(g.find(ix, iy), nullptr);
  EXPECT_EQ(g.find(ix + (std::int64_t{1} << 31), iy), nullptr);  // the cell a wrapped key would alias

  // Beyond the keys' reach: refused, never wrapped.
  EXPECT_FALSE(g.holds(g.key_origin_x() + ElevationGrid::kKeyReach, iy));
  EXPECT_TRUE(g.holds(g.key_origin_x() + ElevationGrid::kKeyReach - 1, iy));
  EXPECT_THROW(g.set_cell(g.key_origin_x() - ElevationGrid::kKeyReach - 1, iy, ElevationCell{}), std::out_of_range);
  EXPECT_THROW(g.sample(500000.0 + 1.2e6, 5300000.0, 0.0, 1e-4, 0), std::out_of_range);
  EXPECT_THROW(g.set_key_origin(0, 0), std::logic_error);  // only before the first cell
}

TEST(Georef, FusingAPointBeyondTheGridIsAnInputErrorNamingStagePassAndPoint) {
  FuseElevationParams prm;
  prm.resolution = 0.001;
  prm.stage = "'elev' (fuse_elevation)";
  ElevationGrid g = make_elevation_grid(prm);  // key origin at 0: +-1,073 km
  try {
    fuse_pass(g, point_pass(5.3e6, 10.0, 0.0), prm, 1e-4);
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("far.pcd"), std::string::npos) << m;
    EXPECT_NE(m.find("'elev' (fuse_elevation)"), std::string::npos) << m;
    EXPECT_NE(m.find("5300000.000"), std::string::npos) << m;
    EXPECT_NE(m.find("line 0 beam 0"), std::string::npos) << m;
  }
  EXPECT_EQ(g.size(), 0u);
  // A height band beyond int32 (z / band >= 2^31): refused too, not converted out of range.
  FuseElevationParams tall;
  tall.band = 0.001;
  ElevationGrid t = make_elevation_grid(tall);
  EXPECT_THROW(fuse_pass(t, point_pass(0.0, 0.0, 3.0e6), tall, 1e-4), InputError);
  // Outside the extent (map metres, with the origin added): not fused, so no error.
  FuseElevationParams ext = prm;
  ext.has_extent = true;
  ext.xmin = ext.ymin = -10.0;
  ext.xmax = ext.ymax = 10.0;
  ElevationGrid ge = make_elevation_grid(ext);
  fuse_pass(ge, point_pass(5.3e6, 0.0, 0.0), ext, 1e-4);
  EXPECT_EQ(ge.size(), 0u);
}

TEST(Georef, ExtentAndZMaxAreInMapMetres) {
  FuseElevationParams prm;
  prm.origin_x = 500000.0;
  prm.origin_y = 5300000.0;
  prm.origin_z = 1000.0;
  prm.has_extent = true;
  prm.xmin = 500000.0;
  prm.xmax = 500010.0;
  prm.ymin = 5300000.0;
  prm.ymax = 5300010.0;
  prm.z_max = 1000.5;
  ElevationGrid g = make_elevation_grid(prm);
  fuse_pass(g, point_pass(5.0, 5.0, 0.2), prm, 1e-4);   // inside, below z_max
  fuse_pass(g, point_pass(5.0, 5.0, 0.7), prm, 1e-4);   // above z_max (1000.7)
  fuse_pass(g, point_pass(-5.0, 5.0, 0.2), prm, 1e-4);  // west of the extent
  ASSERT_EQ(g.size(), 1u);
  g.for_each([&](std::int64_t ix, std::int64_t, const ElevationCell& c) {
    EXPECT_EQ(ix, g.cell_index(500005.0));
    EXPECT_FLOAT_EQ(c.zmax, 1000.2f);  // heights in map metres too
  });
}

TEST(Georef, GeoTiffOfAUtmGridIsAbsoluteAndMerges) {
  const std::string dir = test::fresh_dir();
  FuseElevationParams prm;
  prm.resolution = 0.001;
  prm.min_support = 1;
  prm.origin_x = 500000.0;
  prm.origin_y = 5300000.0;
  ElevationGrid a = make_elevation_grid(prm), b = make_elevation_grid(prm);
  // Points at cell centres (1.0005 + 0.001 k, 2.0005), one per cell.
  const auto at = [](int k) { return point_pass(1.0005 + 0.001 * k, 2.0005, 100.0 + 0.01 * k); };
  for (int k = 0; k < 5; ++k) fuse_pass(a, at(k), prm, 1e-4);
  for (int k = 3; k < 9; ++k) fuse_pass(b, at(k), prm, 1e-4);
  io::write_elevation_geotiff(a, dir + "/a.tif");
  io::write_elevation_geotiff(b, dir + "/b.tif");
  // GDAL sees the true map metres: the north-west corner of cell (500001.000, 5300002.000).
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen((dir + "/a.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  GDALClose(ds);
  EXPECT_NEAR(gt[0], 500001.0, 1e-6);
  EXPECT_NEAR(gt[3], 5300002.001, 1e-6);
  EXPECT_NEAR(gt[1], 0.001, 1e-12);
  // Read back: the same absolute cells; merged: the union, as fused in one grid.
  const ElevationGrid ra = io::read_elevation_geotiff(dir + "/a.tif");
  ASSERT_EQ(ra.size(), a.size());
  a.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    const ElevationCell* r = ra.find(ix, iy);
    ASSERT_NE(r, nullptr) << ix << " " << iy;
    EXPECT_EQ(r->count, c.count);
    EXPECT_FLOAT_EQ(r->zmax, c.zmax);
  });
  ElevationGrid m = io::read_elevation_geotiff(dir + "/a.tif");
  io::merge_elevation_geotiff(m, dir + "/b.tif");
  ElevationGrid all = make_elevation_grid(prm);
  for (int k = 0; k < 9; ++k) fuse_pass(all, at(k), prm, 1e-4);
  EXPECT_EQ(m.size(), 9u);
  std::uint32_t total = 0;
  all.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell&) {
    const ElevationCell* r = m.find(ix, iy);
    ASSERT_NE(r, nullptr);
    total += r->count;
  });
  EXPECT_EQ(total, 11u);  // 5 + 6: the two cells both saw counted twice
  // A grid beyond the first's key reach: a clear error, not a wrapped cell.
  FuseElevationParams far = prm;
  far.origin_x = 500000.0 + 1.2e6;  // 1.2e9 cells east at 1 mm
  ElevationGrid f = make_elevation_grid(far);
  fuse_pass(f, point_pass(0.0, 0.0, 0.0), far, 1e-4);
  io::write_elevation_geotiff(f, dir + "/far.tif");
  ElevationGrid m2 = io::read_elevation_geotiff(dir + "/a.tif");
  try {
    io::merge_elevation_geotiff(m2, dir + "/far.tif", "a.tif");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("more than 2^30 cells from a.tif"), std::string::npos) << e.what();
  }
}

TEST(Georef, PcdProductsStateTheOriginInTheirHeader) {
  const std::string dir = test::fresh_dir();
  Pass p = point_pass(12.345678, -3.5, 100.25);
  const Eigen::Vector3d origin(500000.0, 5300000.0, 0.0);
  {
    io::ReturnsWriter r(dir + "/returns.pcd", origin);
    io::CloudWriter c(dir + "/cloud.pcd", origin);
    r.append(p);
    c.append(p);
    r.close();
    c.close();
  }
  for (const char* f : {"/returns.pcd", "/cloud.pcd"}) {
    const io::PcdTable t = io::read_pcd(dir + f);
    EXPECT_EQ(t.header.map_origin[0], 500000.0);
    EXPECT_EQ(t.header.map_origin[1], 5300000.0);
    EXPECT_EQ(t.header.map_origin[2], 0.0);
    for (int k = 0; k < 7; ++k) EXPECT_EQ(t.header.viewpoint[k], k == 3 ? 1.0 : 0.0);  // not the sensor position
    const auto x = test::column(t, "x"), y = test::column(t, "y");
    EXPECT_NEAR(x[0] + t.header.map_origin[0], 500012.345678, 1e-6);
    EXPECT_NEAR(y[0] + t.header.map_origin[1], 5299996.5, 1e-6);
    EXPECT_EQ(test::read_text(dir + f).find("# .PCD v0.7 - Point Cloud Data file format (written by pcd_pipeline)\n"
                                            "# map_origin 500000 5300000 0\nVERSION 0.7\n"),
              0u);
  }
  // Without an origin, the header is as it always was.
  {
    io::ReturnsWriter r(dir + "/plain.pcd");
    r.append(p);
    r.close();
  }
  const std::string plain = test::read_text(dir + "/plain.pcd");
  EXPECT_EQ(plain.find("map_origin"), std::string::npos);
  EXPECT_EQ(io::read_pcd(dir + "/plain.pcd").header.map_origin[0], 0.0);
  // Our reader is strict about its own line: three finite numbers.
  for (const char* bad : {"# map_origin 1 2", "# map_origin 1 2 nan", "# map_origin 1 2 3x"}) {
    std::string text = plain;
    text.insert(text.find("VERSION"), std::string(bad) + "\n");
    test::write_text(dir + "/bad.pcd", text);
    EXPECT_THROW(io::read_pcd(dir + "/bad.pcd"), InputError) << bad;
  }
  // Other comments are still skipped.
  std::string other = plain;
  other.insert(other.find("VERSION"), "# map origin is a phrase here\n");
  test::write_text(dir + "/other.pcd", other);
  EXPECT_EQ(io::read_pcd(dir + "/other.pcd").header.map_origin[0], 0.0);
}

TEST(Georef, StreamingAtUtmScaleGivesTheSamePointsInDouble) {
  // LineStream's passes hold doubles in absolute map coordinates: the same registration as near
  // 0, moved by the shift, to well under a millimetre.
  const std::string yaml = "input: {scans: " + std::string(PCDP_SOURCE_DIR) +
                           "/sample_scans/pass_000.pcd}\noutput_dir: " + test::fresh_dir() +
                           "\nstages:\n  - type: register\n";
  const Eigen::Vector3d shift(500000.0, 5300000.0, 100.0);
  std::vector<Pass> out[2];
  for (int k = 0; k < 2; ++k) {
    LineStream s(load_pipeline_from_string(yaml, "stream.yaml", "."));
    for (int i = 0; i < 3; ++i) {
      PoseSample ps;
      ps.stamp = i;
      ps.position = Eigen::Vector3d(1.5 * i, 0.2 * i, 0.4) + (k ? shift : Eigen::Vector3d::Zero());
      ps.orientation = Eigen::Quaterniond(rpy_to_matrix({0.01 * i, 0.02, 0.3 * i}, RpyOrder::kXyz));
      s.add_pose(ps);
    }
    for (std::uint32_t l = 0; l < 20; ++l) {
      ScanLine line;
      line.line = l;
      line.nod = -0.3f + 0.01f * static_cast<float>(l);
      for (int b = 0; b < 30; ++b) {
        line.range.push_back(4.0f + 0.1f * static_cast<float>(b));
        line.bearing.push_back(-0.7f + 0.05f * static_cast<float>(b));
        line.stamp.push_back(0.1 + 0.05 * l + 0.001 * b);
      }
      for (Pass& p : s.push(line)) out[k].push_back(std::move(p));
    }
    for (Pass& p : s.end_pass()) out[k].push_back(std::move(p));
  }
  ASSERT_EQ(out[0].size(), out[1].size());
  std::size_t n = 0;
  for (std::size_t k = 0; k < out[0].size(); ++k)
    for (std::size_t i = 0; i < out[0][k].size(); ++i) {
      ASSERT_TRUE(std::isfinite(out[0][k].x[i]));
      EXPECT_NEAR(out[1][k].x[i] - shift.x(), out[0][k].x[i], 1e-6);
      EXPECT_NEAR(out[1][k].y[i] - shift.y(), out[0][k].y[i], 1e-6);
      EXPECT_NEAR(out[1][k].z[i] - shift.z(), out[0][k].z[i], 1e-6);
      EXPECT_EQ(out[1][k].label[i], out[0][k].label[i]);
      ++n;
    }
  EXPECT_EQ(n, 600u);
}

TEST(Georef, PosePositionsBeyondAnyMapFrameAreRefusedWithTheirLine) {
  // Positions whose differences would overflow (1e308 and -1e308: NaN points, silently): refused
  // by the reader, naming the line and column. UTM and geocentric coordinates read as before.
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/utm.csv", "stamp,x,y,z,roll,pitch,yaw\n0,500000.5,5300000.25,-6400000,0,0,0\n");
  EXPECT_EQ(io::read_pose_csv(dir + "/utm.csv", RpyOrder::kXyz).samples()[0].position.y(), 5300000.25);
  test::write_text(dir + "/far.csv", "stamp,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0,0\n1,1e308,0,0,0,0,0\n");
  try {
    io::read_pose_csv(dir + "/far.csv", RpyOrder::kXyz);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("far.csv:3: column 'x'"), std::string::npos) << e.what();
  }
  test::write_text(dir + "/far_z.csv", "stamp,x,y,z,roll,pitch,yaw\n0,0,0,-2e8,0,0,0\n");
  EXPECT_THROW(io::read_pose_csv(dir + "/far_z.csv", RpyOrder::kXyz), InputError);
  // The origin of the widest track allowed is finite: its centre is computed without overflow.
  EXPECT_TRUE(choose_map_origin(track({{-1e8, 1e8, 0.0}, {1e8, 1e8, 0.0}})).allFinite());
}
