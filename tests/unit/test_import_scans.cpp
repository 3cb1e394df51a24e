// The Cartesian importers (octomap scan.dat / .graph, PCD / PLY clouds) on the real files of
// ../shared/datasets: counts, frames, and that registering the imported passes gives the
// original points back (within the documented max_residual).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <unordered_map>

#include "pcdp/errors.hpp"
#include "pcdp/io/import_scans.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
const std::string kOcto = std::string(PCDP_SHARED_DIR) + "/datasets/octomap_share/";

/// Registers every imported pass (mount identity, no skew correction, as the importers say).
std::vector<Eigen::Vector3d> register_all(io::ImportedScans& r) {
  const PoseTrack poses(r.poses);
  SensorParams s;
  s.range_min = 0.0;
  s.range_max = 1000.0;
  RegisterParams rp;
  rp.skew_correction = false;
  rp.covariance = false;
  std::vector<Eigen::Vector3d> out;
  for (auto& p : r.passes) {
    register_pass(p, rp, s, Eigen::Isometry3d::Identity(), &poses);
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p.is_kept(i)) out.push_back({p.x[i], p.y[i], p.z[i]});
  }
  return out;
}

/// Largest distance from a point of `a` to its nearest point of `b` (grid search, radius `cell`).
double worst_nearest(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b, double cell) {
  const auto key = [&](long x, long y, long z) { return (x * 73856093L) ^ (y * 19349663L) ^ (z * 83492791L); };
  std::unordered_multimap<long, std::size_t> grid;
  for (std::size_t i = 0; i < b.size(); ++i)
    grid.emplace(key(std::lround(std::floor(b[i].x() / cell)), std::lround(std::floor(b[i].y() / cell)),
                     std::lround(std::floor(b[i].z() / cell))),
                 i);
  double worst = 0;
  for (const auto& p : a) {
    double best = INFINITY;
    const long cx = std::lround(std::floor(p.x() / cell)), cy = std::lround(std::floor(p.y() / cell)),
               cz = std::lround(std::floor(p.z() / cell));
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          const auto range = grid.equal_range(key(cx + dx, cy + dy, cz + dz));
          for (auto it = range.first; it != range.second; ++it) best = std::min(best, (b[it->second] - p).norm());
        }
    worst = std::max(worst, best);
  }
  return worst;
}

std::vector<Eigen::Vector3d> read_xyz(const std::string& path) {
  std::ifstream in(path);
  std::vector<Eigen::Vector3d> v;
  for (double x, y, z; in >> x >> y >> z;) v.push_back({x, y, z});
  return v;
}
}  // namespace

TEST(ImportScans, OctomapScanDatFindsItsLinesAndNodAxisAndComesBackWithinTheResidual) {
  const auto original = read_xyz(kOcto + "scan.dat");
  ASSERT_EQ(original.size(), 88206u);  // SOURCE.md
  io::ImportOptions opt;
  opt.auto_nod_origin = true;
  io::ImportedScans r = io::import_octomap({kOcto + "scan.dat"}, opt);
  ASSERT_EQ(r.passes.size(), 1u);
  EXPECT_EQ(r.passes[0].size(), 88206u);
  const io::LineRecovery& rec = r.recovery[0];
  EXPECT_EQ(rec.lines, 491u);  // SOURCE.md: 491 scan lines
  // The points fit a nodding laser about half a metre above the file's origin (derived from the
  // data: the elevation at +-90 degrees is ~6 degrees at 4.8 m on every line, whatever the tilt).
  EXPECT_NEAR(rec.nod_origin.z(), 0.5, 0.02);
  EXPECT_NEAR(rec.nod_origin.x(), 0.0, 0.05);
  EXPECT_LT(rec.median_residual, 0.001);
  EXPECT_LE(rec.max_residual, opt.max_residual);
  EXPECT_LT(rec.loose_points, 88206u / 20);  // most points keep their line
  const auto back = register_all(r);
  ASSERT_EQ(back.size(), 88206u);
  EXPECT_LE(worst_nearest(back, original, 0.05), opt.max_residual + 1e-4);
  // Without the nod origin the same scan does not fit: half its points leave their lines.
  const io::ImportedScans plain = io::import_octomap({kOcto + "scan.dat"});
  EXPECT_GT(plain.recovery[0].loose_points, 88206u / 3);
}

TEST(ImportScans, OctomapGraphNodeKeepsItsPoseAndPoints) {
  io::ImportedScans r = io::import_octomap({kOcto + "spherical_scan.graph"});
  ASSERT_EQ(r.passes.size(), 1u);  // SOURCE.md: 1 node, 10,201 points, pose (1, 0, -0.5)
  EXPECT_EQ(r.passes[0].size(), 10201u);
  EXPECT_NEAR(r.poses.front().position.x(), 1.0, 1e-12);
  EXPECT_NEAR(r.poses.front().position.z(), -0.5, 1e-12);
  const auto back = register_all(r);
  ASSERT_EQ(back.size(), 10201u);
  const Eigen::Vector3d centre(1.0, 0.0, -0.5);
  double worst = 0;
  for (const auto& p : back) worst = std::max(worst, std::fabs((p - centre).norm() - 4.01));
  EXPECT_LT(worst, 1e-3);  // every point at 4.01 m from the node origin, as the data set says
  EXPECT_LE(r.recovery[0].max_residual, 0.02);  // and within max_residual of where it was
}

TEST(ImportScans, CartesianPcdCloudComesBack) {
  const std::string path = std::string(PCDP_SHARED_DIR) + "/datasets/pcl_table_scene_lms400/table_scene_lms400_downsampled.pcd";
  const io::PcdTable t = io::read_pcd(path);
  const auto x = test::column(t, "x"), y = test::column(t, "y"), z = test::column(t, "z"), in = test::column(t, "intensity");
  std::vector<Eigen::Vector3d> original;
  for (std::size_t i = 0; i < x.size(); ++i) original.push_back({x[i], y[i], z[i]});
  io::ImportedScans r = io::import_cloud({path}, nullptr);
  ASSERT_EQ(r.passes.size(), 1u);
  EXPECT_EQ(r.passes[0].size(), 41049u);
  // The intensity field becomes the amplitude.
  double sum_in = 0, sum_amp = 0;
  for (const double v : in) sum_in += v;
  for (const float a : r.passes[0].amplitude) sum_amp += a;
  EXPECT_NEAR(sum_amp, sum_in, 1e-6 * sum_in);
  const auto back = register_all(r);
  ASSERT_EQ(back.size(), original.size());
  EXPECT_LE(worst_nearest(back, original, 0.05), 0.02 + 1e-4);
}

TEST(ImportScans, PlyNoddingScanIsRecoveredOrganized) {
  // A nodding scan written as binary PLY, seen from (2, 1, 0.5): 30 lines of 61 beams on a room.
  const std::string dir = test::fresh_dir();
  const Eigen::Vector3d vp(2.0, 1.0, 0.5);
  std::vector<Eigen::Vector3d> pts;
  for (int l = 0; l < 30; ++l)
    for (int b = 0; b < 61; ++b) {
      const double n = -0.5 + 0.02 * l, be = -1.5 + 0.05 * b;
      const Eigen::Vector3d d(std::cos(n) * std::cos(be), std::sin(be), std::sin(n) * std::cos(be));
      const double r = 3.0 + 0.5 * std::sin(3 * be) + 0.2 * l / 30.0;
      if ((l * 61 + b) % 17 == 3) continue;  // some no-returns, dropped as scan.dat does
      pts.push_back(vp + r * d);
    }
  const std::string ply = dir + "/scan.ply";
  {
    std::ofstream o(ply, std::ios::binary);
    o << "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex " << pts.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar intensity\nend_header\n";
    for (const auto& p : pts) {
      const float f[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
      o.write(reinterpret_cast<const char*>(f), sizeof f);
      const unsigned char a = 77;
      o.write(reinterpret_cast<const char*>(&a), 1);
    }
  }
  io::ImportedScans r = io::import_cloud({ply}, &vp);
  ASSERT_EQ(r.passes.size(), 1u);
  EXPECT_EQ(r.recovery[0].lines, 30u);
  EXPECT_TRUE(r.recovery[0].organized);
  EXPECT_EQ(r.passes[0].size(), 30u * 61u);  // the dropped beams are back, as no-returns
  EXPECT_EQ(r.recovery[0].loose_points, 0u);
  EXPECT_LT(r.recovery[0].max_residual, 1e-5);  // float storage only
  EXPECT_EQ(r.passes[0].amplitude[0], 77.0f);
  const auto back = register_all(r);
  EXPECT_EQ(back.size(), pts.size());
  EXPECT_LT(worst_nearest(back, pts, 0.05), 1e-5);

  // Bad files name the file and the rule.
  test::write_text(dir + "/bad.ply", "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n");
  try {
    io::import_cloud({dir + "/bad.ply"}, nullptr);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.ply:2: PLY format 'binary_big_endian' is not supported"), std::string::npos) << e.what();
  }
}

TEST(ImportScans, TruncatedGraphNamesTheByte) {
  const std::string dir = test::fresh_dir();
  std::ifstream in(kOcto + "spherical_scan.graph", std::ios::binary);
  std::string data((std::istreambuf_iterator<char>(in)), {});
  data.resize(1000);
  test::write_text(dir + "/cut.graph", data);
  try {
    io::import_octomap({dir + "/cut.graph"});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.graph: byte 8: the file ends inside the points"), std::string::npos) << e.what();
  }
}

#include "pcdp/config.hpp"
#include "pcdp/pipeline.hpp"

TEST(ImportScans, OurCloudPcdGivesItsAmplitudesUnderEitherName) {
  // cloud.pcd has the amplitude as `amplitude` and `intensity`; versions up to 0.1.0 wrote
  // `amplitude` only. import cloud takes either. The old file: `intensity` renamed to a field of
  // the same length that means nothing (only the header changes).
  const std::string dir = test::fresh_dir();
  const sim::SimConfig cfg = test::small_sim_config();
  sim::write_run(sim::simulate(cfg), cfg, dir);
  test::write_text(dir + "/p.yaml", test::pipeline_yaml(cfg, dir, dir + "/out"));
  (void)Pipeline::prepare(load_pipeline(dir + "/p.yaml")).run();
  const std::string now = test::read_text(dir + "/out/cloud.pcd");
  const auto fields = now.find("FIELDS x y z range amplitude intensity ");
  ASSERT_NE(fields, std::string::npos) << now.substr(0, 300);
  std::string old = now;
  old.replace(fields + 29, 9, "unrelated");
  test::write_text(dir + "/old.pcd", old);
  const Eigen::Vector3d vp(0, 0, 2);
  const io::ImportedScans a = io::import_cloud({dir + "/out/cloud.pcd"}, &vp);
  const io::ImportedScans b = io::import_cloud({dir + "/old.pcd"}, &vp);
  ASSERT_EQ(a.passes.size(), 1u);
  ASSERT_EQ(b.passes.size(), 1u);
  const auto& amp = a.passes[0].amplitude;
  ASSERT_GT(amp.size(), 100u);
  std::size_t measured = 0;
  for (const float v : amp) measured += std::isfinite(v) && v != 0.0f;
  EXPECT_GT(measured, amp.size() / 2) << "the amplitudes were not read";
  ASSERT_EQ(b.passes[0].amplitude.size(), amp.size());
  for (std::size_t i = 0; i < amp.size(); ++i) {
    if (std::isfinite(amp[i]) || std::isfinite(b.passes[0].amplitude[i])) {
      ASSERT_EQ(b.passes[0].amplitude[i], amp[i]) << i;
    }
  }
}
