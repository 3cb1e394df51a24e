// The Cartesian importers (octomap scan.dat / .graph, PCD / PLY clouds) on the real files of
// ../shared/datasets: counts, frames, and that registering the imported passes gives the
// original points back (within the documented max_residual).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <unordered_map>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/import/3dtk.hpp"
#include "pcdp/import/scans.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/pipeline/pipeline.hpp"
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
  const pcdp::LineRecovery& rec = r.recovery[0];
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

// ---- 3DTK: the beams per line come from the scan's geometry --------------------------------

namespace {
/// The InputError message of `f`, or "(no error)".
template <class F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

/// A synthetic 3DTK uos scan of `lines` x `beams` (bearings over 180 degrees, both ends, from the
/// right), the nod rising by 1 degree a line from -20 degrees; ranges r(b, l) in metres; point
/// `sentinel` is the 32.767 m no-return and points in `zeros` are missing (0 0 0).
struct Synthetic3d {
  std::size_t beams, lines;
  std::vector<double> range, bearing, nod;  // truth, per point / per line
};

Synthetic3d write_synthetic_3d(const std::string& path, std::size_t beams, std::size_t lines, const std::string& header,
                               const std::vector<std::size_t>& zeros, std::size_t sentinel) {
  Synthetic3d s{beams, lines, {}, {}, {}};
  std::string text = header;
  char buf[128];
  for (std::size_t l = 0; l < lines; ++l) {
    const double n = (-20.0 + static_cast<double>(l)) * M_PI / 180.0;
    s.nod.push_back(n);
    for (std::size_t b = 0; b < beams; ++b) {
      const std::size_t i = l * beams + b;
      const double be = -M_PI / 2 + M_PI * static_cast<double>(b) / static_cast<double>(beams - 1);
      double r = 3.0 + 0.5 * std::sin(3.0 * be) + 0.01 * static_cast<double>(l);
      if (i == sentinel) r = 32.767;
      const bool zero = std::find(zeros.begin(), zeros.end(), i) != zeros.end();
      s.range.push_back(zero || i == sentinel ? 0.0 : r);
      s.bearing.push_back(be);
      const Eigen::Vector3d ours = r * Eigen::Vector3d(std::cos(be) * std::cos(n), std::sin(be), std::cos(be) * std::sin(n));
      const Eigen::Vector3d uos = zero ? Eigen::Vector3d(Eigen::Vector3d::Zero()) : Eigen::Vector3d(Eigen::Vector3d(-ours.y(), ours.z(), ours.x()) * 100.0);
      std::snprintf(buf, sizeof buf, "%.6f %.6f %.6f\n", uos.x(), uos.y(), uos.z());
      text += buf;
    }
  }
  test::write_text(path, text);
  const std::string pose = path.substr(0, path.rfind('.')) + ".pose";
  test::write_text(pose, "0 0 0\n0 0 0\n");
  return s;
}
}  // namespace

TEST(Import3dtk, KurtScansShow360BeamsPerLineInTheirGeometry) {
  const std::string path = std::string(PCDP_SHARED_DIR) + "/datasets/kurt3d_3dtk_nodding/scan000.3d";
  std::ifstream in(path);
  std::string header;
  std::getline(in, header);  // "360 x 225"
  std::vector<Eigen::Vector3d> pts;
  for (double x, y, z; in >> x >> y >> z;) pts.push_back({x, y, z});
  ASSERT_EQ(pts.size(), 81360u);
  EXPECT_EQ(io::beams_per_line_from_geometry(pts, path), 360u);
  // The whole importer: 226 lines of 360 (the line numbers of scan 0 run 0..225).
  const io::Imported3dtk r = io::import_3dtk({path}, false);
  ASSERT_EQ(r.passes.size(), 1u);
  EXPECT_EQ(r.passes[0].line_count(), 226u);
  EXPECT_EQ(*std::max_element(r.passes[0].beam.begin(), r.passes[0].beam.end()), 359u);
}

TEST(Import3dtk, A181BeamScanImportsWithItsOwnBeamCount) {
  const std::string dir = test::fresh_dir();
  // The first point of line 3 and a mid-line point are missing: the line break is still found.
  const std::vector<std::size_t> zeros = {3 * 181, 10 * 181 + 90};
  const Synthetic3d s = write_synthetic_3d(dir + "/scan000.3d", 181, 40, "", zeros, 5 * 181 + 17);
  const io::Imported3dtk r = io::import_3dtk({dir + "/scan000.3d"}, false);
  ASSERT_EQ(r.passes.size(), 1u);
  const Pass& p = r.passes[0];
  ASSERT_EQ(p.size(), 181u * 40u);
  EXPECT_EQ(p.line_count(), 40u);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    EXPECT_EQ(p.beam[i], i % 181) << i;
    EXPECT_EQ(p.line[i], i / 181) << i;
    EXPECT_NEAR(p.range[i], s.range[i], 1e-5) << i;
    EXPECT_NEAR(p.bearing[i], s.bearing[i], 1e-5) << i;  // the no-returns too (the fitted beam grid)
    EXPECT_NEAR(p.nod[i], s.nod[i / 181], 1e-5) << i;
    checked += s.range[i] > 0 ? 1 : 0;
  }
  EXPECT_EQ(checked, 181u * 40u - 3u);
  // The same file with a "W x H" header that agrees, then one that does not.
  write_synthetic_3d(dir + "/scan001.3d", 181, 40, "181 x 39\n", zeros, 5);
  EXPECT_EQ(io::import_3dtk({dir + "/scan001.3d"}, false).passes[0].size(), 181u * 40u);
  // An override that the header and the geometry both contradict is refused (it divides the count).
  try {
    io::import_3dtk({dir + "/scan001.3d"}, false, 362);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--beams-per-line 362 contradicts the header (181 beams per line) and the points' geometry (181)"),
              std::string::npos)
        << e.what();
  }
  write_synthetic_3d(dir + "/scan002.3d", 181, 40, "360 x 20\n", zeros, 5);
  EXPECT_NE(input_error_of([&] { io::import_3dtk({dir + "/scan002.3d"}, false); })
                .find("scan002.3d:1: the header says 360 beams per line, the points' geometry 181; give the count with --beams-per-line N"),
            std::string::npos);
  // An explicit count wins over the header, and must divide the point count.
  EXPECT_EQ(io::import_3dtk({dir + "/scan002.3d"}, false, 181).passes[0].line_count(), 40u);
  EXPECT_NE(input_error_of([&] { io::import_3dtk({dir + "/scan002.3d"}, false, 180); })
                .find("scan002.3d: 7240 points is not a whole number of 180-beam lines"),
            std::string::npos);
}

TEST(Import3dtk, LinesOfDifferentLengthsAskForTheCount) {
  const std::string dir = test::fresh_dir();
  write_synthetic_3d(dir + "/scan000.3d", 181, 10, "", {}, 99999);
  // Drop one point in the middle of line 4: that line has 180 beams.
  std::string text = test::read_text(dir + "/scan000.3d");
  std::size_t at = 0;
  for (std::size_t k = 0; k < 4 * 181 + 50; ++k) at = text.find('\n', at) + 1;
  text.erase(at, text.find('\n', at) + 1 - at);
  test::write_text(dir + "/scan000.3d", text);
  const std::string err = input_error_of([&] { io::import_3dtk({dir + "/scan000.3d"}, false); });
  EXPECT_NE(err.find("scan000.3d: cannot read the beams per scan line from the geometry: most lines have 181 beams, "
                     "but the bearing"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("give the count with --beams-per-line N"), std::string::npos) << err;
  // A scan with one direction only cannot tell either.
  test::write_text(dir + "/flat.3d", "0 0 100\n0 0 200\n");
  test::write_text(dir + "/flat.pose", "0 0 0\n0 0 0\n");
  EXPECT_NE(input_error_of([&] { io::import_3dtk({dir + "/flat.3d"}, false); }).find("no two points with different bearings"),
            std::string::npos);
}

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
