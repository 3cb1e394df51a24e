// Georeferenced poses end to end (docs/data_contract.md "Coordinates"): a simulated run with its
// pose file moved to UTM (500 km east, 5,300 km north, 100 m up) against the same run near 0 —
// the same labels, products equal up to the map origin within 1 mm, map.bt not empty, the
// GeoTIFF in absolute map metres, evaluate and merge working — and out-of-range coordinates
// refused with a clear error naming the stage (never wrapped, never dropped).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "pcdp/fusion/elevation.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace pcdp;
using test::run_cli;

namespace {

constexpr double kShift[3] = {500000.0, 5300000.0, 100.0};

// The pose file moved by `shift`, plus (when `extra_x` is not 0) one more pose 10 s after the
// last, `extra_x` metres east of it: the returns keep their poses, the poses' extent grows.
void write_moved_poses(const std::string& from, const std::string& to, const double shift[3], double extra_x = 0.0) {
  std::istringstream in(test::read_text(from));
  std::ostringstream out;
  std::string line;
  std::getline(in, line);
  out << line << "\n";
  double last[7] = {0, 0, 0, 0, 0, 0, 0};
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    double v[7];
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]), 7) << line;
    for (int a = 0; a < 3; ++a) v[1 + a] += shift[a];
    char b[400];
    std::snprintf(b, sizeof b, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", v[0], v[1], v[2], v[3], v[4], v[5], v[6]);
    out << b;
    std::copy(v, v + 7, last);
  }
  if (extra_x != 0.0) {
    char b[400];
    std::snprintf(b, sizeof b, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", last[0] + 10.0, last[1] + extra_x, last[2],
                  last[3], last[4], last[5], last[6]);
    out << b;
  }
  test::write_text(to, out.str());
}

struct Sim {
  sim::SimConfig cfg;
  std::string dir;
};

Sim simulate_into(const std::string& dir) {
  Sim s;
  s.cfg = test::small_sim_config();
  s.dir = dir;
  const sim::SimResult r = sim::simulate(s.cfg);
  sim::write_run(r, s.cfg, dir);
  sim::write_truth(r, s.cfg, dir);
  return s;
}

nlohmann::json report(const std::string& out) { return nlohmann::json::parse(test::read_text(out + "/report.json")); }

const char* const kAllStages =
    "  - type: reject_occlusion\n  - type: reject_mixed_pixels\n  - type: check_consistency\n"
    "  - type: fuse_elevation\n  - type: fuse_octomap\n";

}  // namespace

TEST(Georef, UtmPosesGiveTheSameRunUpToTheMapOrigin) {
  const std::string dir = test::fresh_dir("utm");
  const Sim s = simulate_into(dir);
  write_moved_poses(dir + "/poses.csv", dir + "/poses_utm.csv", kShift);
  const std::string yaml = dir + "/pipeline.yaml";
  test::write_text(yaml, test::pipeline_yaml(s.cfg, dir, dir + "/near") + kAllStages);
  const auto near = run_cli({"run", yaml, "--quiet"});
  ASSERT_EQ(near.exit_code, 0) << near.err;
  const auto utm = run_cli({"run", yaml, "--quiet", "--set", "input.poses=" + dir + "/poses_utm.csv", "--output-dir", dir + "/utm"});
  ASSERT_EQ(utm.exit_code, 0) << utm.err;

  // report.json states the origin (a round number near the poses) only when there is one.
  const auto rn = report(dir + "/near"), ru = report(dir + "/utm");
  EXPECT_FALSE(rn.contains("map_origin"));
  ASSERT_TRUE(ru.contains("map_origin"));
  const double origin[3] = {ru["map_origin"][0], ru["map_origin"][1], ru["map_origin"][2]};
  EXPECT_EQ(origin[0], 500000.0);
  EXPECT_EQ(origin[1], 5300000.0);
  EXPECT_EQ(origin[2], 0.0);
  EXPECT_EQ(ru["labels"], rn["labels"]);
  EXPECT_EQ(ru["warnings"], rn["warnings"]);

  // returns.pcd and cloud.pcd: every label the same, every point the same up to the origin
  // (the header's "# map_origin"), within 1 mm (float32 of a UTM northing would keep 0.5 m).
  for (const char* file : {"/returns.pcd", "/cloud.pcd"}) {
    SCOPED_TRACE(file);
    const io::PcdTable a = io::read_pcd(dir + "/near" + file), b = io::read_pcd(dir + "/utm" + file);
    ASSERT_EQ(a.header.points, b.header.points);
    EXPECT_EQ(a.header.map_origin[0], 0.0);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(b.header.map_origin[k], origin[k]);
    EXPECT_EQ(b.header.viewpoint[0], 0.0);
    const char* axes[3] = {"x", "y", "z"};
    double worst = 0.0;
    std::size_t points = 0;
    for (int k = 0; k < 3; ++k) {
      const auto ca = test::column(a, axes[k]), cb = test::column(b, axes[k]);
      for (std::size_t i = 0; i < ca.size(); ++i) {
        ASSERT_EQ(std::isfinite(ca[i]), std::isfinite(cb[i])) << i;
        if (!std::isfinite(ca[i])) continue;
        worst = std::max(worst, std::fabs((cb[i] + b.header.map_origin[k]) - (ca[i] + kShift[k])));
        points += k == 0;
      }
    }
    EXPECT_GT(points, 1000u);
    EXPECT_LT(worst, 1e-3);
    if (std::string(file) == "/returns.pcd") {
      EXPECT_EQ(test::column(a, "label"), test::column(b, "label"));
    }
  }

  // elevation.tif: georeferenced in absolute map metres (the tie point moved by the shift, cell
  // for cell), heights in map metres, equal within 1 mm.
  const ElevationGrid ga = io::read_elevation_geotiff(dir + "/near/elevation.tif");
  const ElevationGrid gb = io::read_elevation_geotiff(dir + "/utm/elevation.tif");
  ASSERT_GT(ga.size(), 100u);
  EXPECT_EQ(ga.size(), gb.size());
  const std::int64_t dx = std::llround(kShift[0] / ga.resolution()), dy = std::llround(kShift[1] / ga.resolution());
  std::size_t surfaces = 0;
  ga.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    const ElevationCell* d = gb.find(ix + dx, iy + dy);
    ASSERT_NE(d, nullptr) << ix << " " << iy;
    EXPECT_EQ(d->count, c.count);
    double ea = 0, va = 0, eb = 0, vb = 0;
    const bool sa = ga.surface(c, ea, va), sb = gb.surface(*d, eb, vb);
    ASSERT_EQ(sa, sb);
    if (!sa) return;
    EXPECT_NEAR(eb, ea + kShift[2], 1e-3);
    EXPECT_NEAR(vb, va, 1e-9);
    ++surfaces;
  });
  EXPECT_GT(surfaces, 100u);

  // map.bt: local to the origin, and not empty (OctoMap's keys reach +-3.3 km at 0.1 m: UTM
  // coordinates used to fall outside and the map came out empty).
  const auto leaves = [](const nlohmann::json& r) {
    for (const auto& st : r["stages"])
      if (st["type"] == "fuse_octomap") return st["metrics"]["occupied_leaves"].get<double>();
    return -1.0;
  };
  EXPECT_GT(leaves(rn), 1000.0);
  EXPECT_NEAR(leaves(ru), leaves(rn), 0.02 * leaves(rn));
  EXPECT_GT(fs::file_size(dir + "/utm/map.bt"), fs::file_size(dir + "/near/map.bt") / 2);

  // evaluate reads the origin from returns.pcd: the same label scores (the truth is near 0, so
  // the registration error is the shift itself, not compared here).
  const auto en = run_cli({"evaluate", "--truth", dir, "--run", dir + "/near", "--quiet"});
  const auto eu = run_cli({"evaluate", "--truth", dir, "--run", dir + "/utm", "--quiet"});
  ASSERT_EQ(en.exit_code, 0) << en.err;
  ASSERT_EQ(eu.exit_code, 0) << eu.err;
  const auto jn = nlohmann::json::parse(test::read_text(dir + "/near/evaluation.json"));
  const auto ju = nlohmann::json::parse(test::read_text(dir + "/utm/evaluation.json"));
  EXPECT_EQ(ju["labels"], jn["labels"]);
  EXPECT_EQ(ju["run_labels"], jn["run_labels"]);
  EXPECT_NEAR(ju["registration_error"]["median"].get<double>(),
              std::sqrt(kShift[0] * kShift[0] + kShift[1] * kShift[1] + kShift[2] * kShift[2]), 1.0);

  // clean-cloud keeps the points relative to the origin and says so in its output's header. The
  // run's cloud was measured from a moving scanner, which its `range` field shows, so clean-cloud
  // refuses it (tests/e2e/test_las_cli.cpp); its x y z alone, with the map origin, are accepted.
  EXPECT_EQ(run_cli({"clean-cloud", dir + "/utm/cloud.pcd", "-o", dir + "/clean.pcd", "--viewpoint", "0,0,101", "-q"}).exit_code, 2);
  {
    const io::PcdTable t = io::read_pcd(dir + "/utm/cloud.pcd");
    io::PcdWriter w(dir + "/xyz.pcd", {t.header.fields[0], t.header.fields[1], t.header.fields[2]});
    w.set_map_origin(t.header.map_origin[0], t.header.map_origin[1], t.header.map_origin[2]);
    for (std::size_t i = 0; i < t.header.points; ++i) {
      float row[3];
      for (int k = 0; k < 3; ++k) std::memcpy(&row[k], t.columns[static_cast<std::size_t>(k)].data() + 4 * i, 4);
      w.append(reinterpret_cast<const std::uint8_t*>(row), 1);
    }
    w.close();
  }
  const auto cc = run_cli({"clean-cloud", dir + "/xyz.pcd", "-o", dir + "/clean.pcd", "--viewpoint", "0,0,101", "-q"});
  ASSERT_EQ(cc.exit_code, 0) << cc.err;
  const io::PcdTable clean = io::read_pcd(dir + "/clean.pcd");
  for (int k = 0; k < 3; ++k) EXPECT_EQ(clean.header.map_origin[k], origin[k]);
}

TEST(Georef, MergeOfUtmGridsWithDifferentOriginsIsAbsolute) {
  // Two runs of the same passes, their poses 500.6 km and 500.0 km east: map origins 501 km and
  // 500 km. Their grids merge in absolute map metres: the merged raster spans both, each cell
  // where its run put it.
  const std::string dir = test::fresh_dir("merge_utm");
  const Sim s = simulate_into(dir);
  const double east[3] = {500600.0, 5300000.0, 100.0};
  write_moved_poses(dir + "/poses.csv", dir + "/poses_a.csv", kShift);
  write_moved_poses(dir + "/poses.csv", dir + "/poses_b.csv", east);
  const std::string yaml = dir + "/pipeline.yaml";
  test::write_text(yaml, test::pipeline_yaml(s.cfg, dir, dir + "/a") + "  - type: fuse_elevation\n    resolution: 0.5\n    png: false\n");
  for (const char* k : {"a", "b"}) {
    const auto r = run_cli({"run", yaml, "--quiet", "--set", std::string("input.poses=") + dir + "/poses_" + k + ".csv",
                            "--output-dir", dir + "/" + k});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  EXPECT_EQ(report(dir + "/a")["map_origin"][0], 500000.0);
  EXPECT_EQ(report(dir + "/b")["map_origin"][0], 501000.0);
  const auto m = run_cli({"merge", dir + "/a/elevation.tif", dir + "/b/elevation.tif", "-o", dir + "/m.tif"});
  ASSERT_EQ(m.exit_code, 0) << m.err;
  const ElevationGrid a = io::read_elevation_geotiff(dir + "/a/elevation.tif");
  const ElevationGrid b = io::read_elevation_geotiff(dir + "/b/elevation.tif");
  const ElevationGrid merged = io::read_elevation_geotiff(dir + "/m.tif");
  EXPECT_EQ(merged.size(), a.size() + b.size());  // 600 m apart: no cell in common
  const std::int64_t d = std::llround(600.0 / a.resolution());
  a.for_each([&](std::int64_t ix, std::int64_t iy, const ElevationCell& c) {
    ASSERT_NE(merged.find(ix, iy), nullptr);
    const ElevationCell* cb = b.find(ix + d, iy);
    ASSERT_NE(cb, nullptr);  // the same passes, 600 m east
    EXPECT_EQ(cb->count, c.count);
    EXPECT_NE(merged.find(ix + d, iy), nullptr);
  });
}

TEST(Georef, CoordinatesBeyondAStagesKeysAreAnInputErrorNamingTheStage) {
  // One more pose 34 km east of the rest: the map origin (the poses' centre) moves 17 km from
  // the returns, which then lie beyond what some stages' keys hold. Each says so (exit 3), naming
  // the stage, the pass and the point, instead of wrapping keys or dropping rays.
  const std::string dir = test::fresh_dir("range");
  const Sim s = simulate_into(dir);
  write_moved_poses(dir + "/poses.csv", dir + "/poses_far.csv", kShift, 34000.0);
  const std::string base = test::pipeline_yaml(s.cfg, dir, dir + "/out");
  const auto run = [&](const std::string& stages, const std::string& poses) {
    const std::string yaml = dir + "/p.yaml";
    test::write_text(yaml, base + stages);
    return run_cli({"run", yaml, "--quiet", "--set", "input.poses=" + poses});
  };
  {  // OctoMap: +-3,276.7 m at 0.1 m (the rays used to be dropped: an empty map.bt)
    const auto r = run("  - type: fuse_octomap\n    name: octo\n", dir + "/poses_far.csv");
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("stage 'octo' (fuse_octomap)"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("pass_000.pcd"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("OctoMap's key range"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("(517000.000, 5300000.000, 0.000)"), std::string::npos) << r.err;  // the origin
    EXPECT_FALSE(fs::exists(dir + "/out/map.bt"));
  }
  {  // check_consistency's voxel keys: +-10.5 km at 1 cm
    const auto r = run("  - type: check_consistency\n    resolution: 0.01\n", dir + "/poses_far.csv");
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("(check_consistency)"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("voxel keys"), std::string::npos) << r.err;
  }
  {  // the elevation grid's keys: +-1,073 km at 1 mm (a pose 3,000 km east)
    write_moved_poses(dir + "/poses.csv", dir + "/poses_very_far.csv", kShift, 3.0e6);
    const auto r = run("  - type: fuse_elevation\n    resolution: 0.001\n", dir + "/poses_very_far.csv");
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("(fuse_elevation)"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("beyond what the elevation grid holds"), std::string::npos) << r.err;
  }
  {  // with the same stages at coarser resolutions the run succeeds, and the report warns that
     // float32 products keep 1 mm only within 16 km of the origin
    const auto r = run("  - type: check_consistency\n  - type: fuse_elevation\n", dir + "/poses_far.csv");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto rep = report(dir + "/out");
    EXPECT_EQ(rep["map_origin"][0], 517000.0);
    bool warned = false;
    for (const auto& w : rep["warnings"]) warned |= w.get<std::string>().find("keep 1 mm only within") != std::string::npos;
    EXPECT_TRUE(warned) << rep["warnings"];
  }
}

// The pipeline key `crs` (here through --set, as a user would): elevation.tif and the merge of two
// such grids state EPSG:32632 to GDAL, `gdalinfo -stats` prints no error, a grid in another CRS
// is refused by merge (exit 3, both files and both CRSs named), and an unusable CRS by the
// configuration (exit 2, naming the key).
TEST(Georef, CrsIsWrittenKeptByMergeAndCheckedAtConfigTime) {
  const std::string dir = test::fresh_dir("crs");
  const std::string scans = std::string(PCDP_SOURCE_DIR) + "/sample_scans/";
  const std::string yaml = std::string(PCDP_SOURCE_DIR) + "/pipelines/nodding_terrain.yaml";
  const auto run = [&](const std::string& glob, const std::string& out, const std::string& crs) {
    return run_cli({"run", yaml, "--quiet", "--set", "input.scans=" + scans + glob, "--set",
                    "input.poses=" + scans + "poses.csv", "--set", "crs=" + crs, "--output-dir", out});
  };
  ASSERT_EQ(run("pass_000.pcd", dir + "/a", "EPSG:32632").exit_code, 0);
  ASSERT_EQ(run("pass_001.pcd", dir + "/b", "EPSG:32632").exit_code, 0);
  ASSERT_EQ(run("pass_002.pcd", dir + "/c", "EPSG:32633").exit_code, 0);
  EXPECT_TRUE(std::filesystem::exists(dir + "/a/elevation.state.tif"));
  const auto m = run_cli({"merge", dir + "/a/elevation.tif", dir + "/b/elevation.tif", "-o", dir + "/m.tif"});
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/m.state.tif"));
  const auto gdalinfo = [&](const std::string& args) {
    const std::string txt = dir + "/info.txt";
    EXPECT_EQ(std::system(("gdalinfo " + args + " > " + txt + " 2>&1").c_str()), 0);
    return test::read_text(txt);
  };
  for (const std::string& f : {dir + "/a/elevation.tif", dir + "/m.tif"}) {
    const std::string info = gdalinfo("-stats " + f);
    EXPECT_NE(info.find("ID[\"EPSG\",32632]]"), std::string::npos) << f << "\n" << info;
    EXPECT_EQ(info.find("ERROR"), std::string::npos) << f << "\n" << info;
    EXPECT_EQ(info.find("Band 7"), std::string::npos) << f;  // the six user bands only
    EXPECT_NE(info.find("Description = passes"), std::string::npos) << f;
  }
  const auto other = run_cli({"merge", dir + "/a/elevation.tif", dir + "/c/elevation.tif", "-o", dir + "/x.tif"});
  EXPECT_EQ(other.exit_code, 3) << other.err;
  EXPECT_NE(other.err.find("'" + dir + "/a/elevation.tif' is in EPSG:32632 and '" + dir + "/c/elevation.tif' in EPSG:32633"),
            std::string::npos) << other.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.tif"));
  const auto bad = run("pass_000.pcd", dir + "/d", "EPSG:4326");
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("--set crs=EPSG:4326: crs = EPSG:4326 (WGS 84) is a geographic CRS"), std::string::npos) << bad.err;
}
