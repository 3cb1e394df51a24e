#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <stdexcept>

#include "pcdp/pipeline/work_share.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/stages/check_consistency.hpp"

using namespace pcdp;

namespace {
/// Appends a kept, registered return at q seen from `origin` (range_cal is left to the caller).
void push_return(Pass& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& q) {
  p.x.push_back(q.x());
  p.y.push_back(q.y());
  p.z.push_back(q.z());
  p.ox.push_back(origin.x());
  p.oy.push_back(origin.y());
  p.oz.push_back(origin.z());
  p.label.push_back(Label::kKept);
  p.range.push_back(static_cast<float>((q - origin).norm()));
}

/// A registered pass of single rays from `origin` to the given points.
Pass rays(std::size_t index, const Eigen::Vector3d& origin, const std::vector<Eigen::Vector3d>& pts) {
  Pass p;
  p.index = index;
  for (const auto& q : pts) push_return(p, origin, q);
  p.range_cal = p.range;
  return p;
}
}  // namespace

TEST(CheckConsistency, AVeilThatAnotherPassSawThroughIsLabelledAndTheWallIsNot) {
  // Pass 0 sees a wall at x = 10 and a veil point floating at x = 6.05; pass 1, from another
  // viewpoint, sees the wall behind the veil through the veil's voxel.
  std::vector<Eigen::Vector3d> wall;
  for (int i = -20; i <= 20; ++i) wall.emplace_back(10.05, 0.1 * i + 0.05, 1.05);
  std::vector<Eigen::Vector3d> p0 = wall;
  p0.emplace_back(6.05, 0.05, 1.05);  // the veil
  Pass a = rays(0, {0.05, 0.05, 1.05}, p0);
  // Pass 1's ray goes exactly through the veil's voxel: aimed at the wall through (6.05, 0.05).
  const Eigen::Vector3d o1(0.05, -3.0, 1.05), through(6.05, 0.05, 1.05);
  const Eigen::Vector3d dir = (through - o1).normalized();
  const Eigen::Vector3d end = o1 + dir * ((10.05 - o1.x()) / dir.x());
  Pass b = rays(1, o1, {end});
  ConsistencyParams prm;
  ConsistencyEvidence ev(prm);
  ev.add_pass(a);
  ev.add_pass(b);
  ev.finalize();
  EXPECT_EQ(ev.label(a), 1u);
  EXPECT_EQ(a.label.back(), Label::kInconsistent);
  for (std::size_t i = 0; i + 1 < a.size(); ++i) EXPECT_EQ(a.label[i], Label::kKept);
  EXPECT_EQ(ev.label(b), 0u);
  // Its own rays never contradict a pass: with only pass 0, nothing is labelled.
  ConsistencyEvidence alone(prm);
  Pass a2 = rays(0, {0.05, 0.05, 1.05}, p0);
  alone.add_pass(a2);
  alone.finalize();
  EXPECT_EQ(alone.label(a2), 0u);
}

namespace {
using Voxel = std::array<std::int64_t, 3>;
Voxel voxel_at(const Eigen::Vector3d& p, double res) {
  return {static_cast<std::int64_t>(std::floor(p.x() / res)), static_cast<std::int64_t>(std::floor(p.y() / res)),
          static_cast<std::int64_t>(std::floor(p.z() / res))};
}
// The definition, the slow way: every ray walked voxel by voxel (a reference
// implementation), then each return judged against every other pass's voxel sets. `crossings`, if
// given, receives the number of (ray, lonely voxel) pairs the walks visit (the stage's
// ray_crossings): a lonely voxel holds a return with no other pass's hit within hit_radius.
std::vector<std::vector<Label>> reference_labels(const std::vector<Pass>& passes, const ConsistencyParams& p,
                                                 std::uint64_t* crossings = nullptr) {
  const double res = p.resolution;
  std::vector<std::set<Voxel>> hit(passes.size()), free(passes.size());
  std::vector<std::map<Voxel, std::uint64_t>> visits(passes.size());  // rays of the pass through each voxel
  for (std::size_t k = 0; k < passes.size(); ++k) {
    const Pass& pass = passes[k];
    for (std::size_t i = 0; i < pass.size(); ++i) {
      if (!pass.is_kept(i)) continue;
      const Eigen::Vector3d o(pass.ox[i], pass.oy[i], pass.oz[i]), e(pass.x[i], pass.y[i], pass.z[i]);
      hit[k].insert(voxel_at(e, res));
      const double len = (e - o).norm();
      if (len <= p.margin || len > p.max_range) continue;
      const Eigen::Vector3d d = (e - o) / len;
      Voxel v = voxel_at(o, res);
      double tmax[3], tdelta[3];
      for (int a = 0; a < 3; ++a) {
        const double boundary = (static_cast<double>(v[a]) + (d[a] > 0 ? 1.0 : 0.0)) * res;
        tmax[a] = std::fabs(d[a]) > 1e-12 ? (boundary - o[a]) / d[a] : INFINITY;
        tdelta[a] = std::fabs(d[a]) > 1e-12 ? res / std::fabs(d[a]) : INFINITY;
      }
      for (double t = 0.0; t < len - p.margin;) {
        free[k].insert(v);
        ++visits[k][v];
        const int a = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
        t = tmax[a];
        tmax[a] += tdelta[a];
        v[a] += d[a] > 0 ? 1 : -1;
      }
    }
  }
  std::vector<std::vector<Label>> out;
  std::set<Voxel> lonely;
  for (std::size_t k = 0; k < passes.size(); ++k) {
    std::vector<Label> labels = passes[k].label;
    for (std::size_t i = 0; i < passes[k].size(); ++i) {
      if (!passes[k].is_kept(i)) continue;
      const Voxel v = voxel_at({passes[k].x[i], passes[k].y[i], passes[k].z[i]}, res);
      int seen_free = 0;
      bool near_hit = false;
      for (std::size_t j = 0; j < passes.size(); ++j) {
        if (j == k) continue;
        seen_free += free[j].count(v) ? 1 : 0;
        const int h = p.hit_radius;
        for (int dx = -h; dx <= h; ++dx)
          for (int dy = -h; dy <= h; ++dy)
            for (int dz = -h; dz <= h; ++dz) near_hit = near_hit || hit[j].count({v[0] + dx, v[1] + dy, v[2] + dz});
      }
      if (!near_hit) lonely.insert(v);
      if (seen_free >= p.min_passes && !near_hit) labels[i] = Label::kInconsistent;
    }
    out.push_back(labels);
  }
  if (crossings) {
    *crossings = 0;
    for (const auto& pass_visits : visits)
      for (const Voxel& v : lonely) {
        const auto it = pass_visits.find(v);
        if (it != pass_visits.end()) *crossings += it->second;
      }
  }
  return out;
}

// Moves every point and origin onto a grid of 2^-14 m (61 um): the stage keeps rays in single
// precision relative to the pass's first origin, which is then exact, so its crossings can be
// compared one for one with the double-precision walk here (otherwise a ray grazing a voxel's
// corner by a micrometre may count on one side only; the labels agree either way).
void snap(std::vector<Pass>& passes) {
  const auto q = [](double& v) { v = std::round(v * 16384.0) / 16384.0; };
  for (Pass& p : passes)
    for (std::size_t i = 0; i < p.size(); ++i)
      for (double* v : {&p.x[i], &p.y[i], &p.z[i], &p.ox[i], &p.oy[i], &p.oz[i]}) q(*v);
}

// Passes that look at the same few walls and floor from different places, with stray returns
// floating in between (veils, false ranges) that other passes see through.
std::vector<Pass> random_scene(std::uint32_t seed, std::size_t npasses, const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Pass> passes;
  for (std::size_t k = 0; k < npasses; ++k) {
    const Eigen::Vector3d origin(2.0 + 4.0 * u(rng), -3.0 + 6.0 * u(rng), 1.0 + u(rng));
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < 1500; ++i) {
      Eigen::Vector3d q;
      const double r = u(rng);
      if (r < 0.4) q = {12.0 + 0.02 * u(rng), -8.0 + 16.0 * u(rng), 3.0 * u(rng)};   // a far wall
      else if (r < 0.8) q = {12.0 * u(rng), -8.0 + 16.0 * u(rng), 0.01 * u(rng)};     // the floor
      else if (r < 0.9) q = {-4.0 + 0.02 * u(rng), -8.0 + 16.0 * u(rng), 3.0 * u(rng)}; // a wall behind
      else q = {1.0 + 10.0 * u(rng), -6.0 + 12.0 * u(rng), 0.2 + 2.5 * u(rng)};       // strays in between
      pts.push_back(q + offset);
    }
    passes.push_back(rays(k, origin + offset, pts));
    // Moving origins, as on a vehicle: every return from its own point.
    Pass& p = passes.back();
    for (std::size_t i = 0; i < p.size(); ++i) p.ox[i] += 0.001 * static_cast<double>(i);
  }
  snap(passes);
  return passes;
}
}  // namespace

TEST(CheckConsistency, LabelsEqualTheVoxelByVoxelDefinition) {
  // The stage looks for free space only where it can decide a label (returns with no other pass's
  // hit nearby) and tests rays against those voxels exactly: it must label exactly what walking
  // every ray voxel by voxel labels, whatever the options.
  struct Case {
    ConsistencyParams p;
    std::uint32_t seed;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  };
  std::vector<Case> cases;
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    ConsistencyParams p;
    cases.push_back({p, seed});
    p.hit_radius = seed - 1;  // 0, 1, 2
    p.min_passes = 2;
    p.resolution = 0.05 * seed;
    p.margin = 0.2 * seed;
    p.max_range = 8.0 + 3.0 * seed;
    cases.push_back({p, seed + 10});
  }
  // In a UTM frame (500 km east, 4500 km north): voxel indices far beyond the 21-bit keys, which
  // wrap; the geometry must not.
  for (std::uint32_t seed : {21u, 22u}) cases.push_back({ConsistencyParams{}, seed, {500000.0, 4500000.0, 100.0}});
  std::size_t total_inconsistent = 0, total_lonely_kept = 0;
  for (const Case& c : cases) {
    std::vector<Pass> passes = random_scene(c.seed, 4, c.offset);
    std::uint64_t crossings = 0;
    const auto want = reference_labels(passes, c.p, &crossings);
    ConsistencyEvidence ev(c.p);
    for (const Pass& p : passes) ev.add_pass(p);
    ev.finalize();
    // Points in every direction make no scan-line fans: this checks the grid walk.
    EXPECT_EQ(ev.stats().rays_in_fans, 0u);
    EXPECT_EQ(ev.stats().crossings, crossings) << "seed " << c.seed;
    std::size_t labelled = 0;
    for (std::size_t k = 0; k < passes.size(); ++k) {
      labelled += ev.label(passes[k]);
      for (std::size_t i = 0; i < passes[k].size(); ++i)
        ASSERT_EQ(passes[k].label[i], want[k][i]) << "seed " << c.seed << " pass " << k << " return " << i;
    }
    const auto& s = ev.stats();
    EXPECT_EQ(s.returns, 4u * 1500u);
    EXPECT_LE(labelled, s.lonely_returns);  // only lonely returns can be contradicted
    total_inconsistent += labelled;
    total_lonely_kept += s.lonely_returns - labelled;
  }
  // Not vacuous: both outcomes occur among the returns that needed free-space evidence.
  EXPECT_GT(total_inconsistent, 100u);
  EXPECT_GT(total_lonely_kept, 100u);
}

namespace {
// Passes of a nodding scanner in a room (floor, four walls): scan lines of rays from a moving
// origin (every return from its own point, up to `spread` m apart along a line), in a plane that
// tilts as the line is scanned (skew, `twist` rad over a line), with some returns cut short
// (veils, false ranges: lonely) and some strays right beyond the margin, at the fan's apex.
std::vector<Pass> fan_scene(std::uint32_t seed, std::size_t npasses, double spread, double twist,
                            const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr int kLines = 36, kBeams = 61;
  std::vector<Pass> passes;
  for (std::size_t k = 0; k < npasses; ++k) {
    Pass p;
    p.index = k;
    const Eigen::Vector3d start(1.0 + 4.0 * u(rng), -3.0 + 6.0 * u(rng), 0.8 + u(rng));
    const Eigen::Vector3d drive = Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, 0.0).normalized();
    const double heading = 2.0 * M_PI * u(rng);
    for (int l = 0; l < kLines; ++l) {
      p.line_begin.push_back(p.size());
      // The nod: the scan plane turns about the bearing-zero axis, down and back up.
      const double nod0 = -0.6 + 1.2 * std::fabs(static_cast<double>(l) / (kLines / 2) - 1.0);
      for (int b = 0; b < kBeams; ++b) {
        const double f = static_cast<double>(b) / (kBeams - 1);
        const double bearing = -1.7 + 3.4 * f, nod = nod0 + twist * f;
        const Eigen::Vector3d o = start + drive * spread * (l + f);
        const Eigen::Vector3d d_s(std::cos(bearing) * std::cos(nod), std::sin(bearing), std::cos(bearing) * std::sin(nod));
        const Eigen::Vector3d d = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()) * d_s;
        double t = INFINITY;  // the room: floor z = 0, walls x = -4, 12, y = -8, 8, ceiling z = 4
        const auto plane = [&](double oc, double dc, double at) {
          if (std::fabs(dc) > 1e-9 && (at - oc) / dc > 0) t = std::min(t, (at - oc) / dc);
        };
        plane(o.z(), d.z(), 0.0);
        plane(o.z(), d.z(), 4.0);
        plane(o.x(), d.x(), -4.0);
        plane(o.x(), d.x(), 12.0);
        plane(o.y(), d.y(), -8.0);
        plane(o.y(), d.y(), 8.0);
        const double r = u(rng);
        if (r < 0.04) t *= 0.2 + 0.7 * u(rng);        // a veil or false range
        else if (r < 0.05) t = 0.55 + 0.5 * u(rng);   // a stray just beyond the margin
        push_return(p, o + offset, o + t * d + offset);
      }
    }
    p.line_begin.push_back(p.size());
    p.range_cal = p.range;
    passes.push_back(std::move(p));
  }
  snap(passes);
  return passes;
}
}  // namespace

TEST(CheckConsistency, ScanLineFansFindExactlyTheCrossingsOfTheVoxelWalk) {
  // Rays of scan lines are tested through their line's fan (plane and bearing bounds measured on
  // the rays, then the exact ray-box test): every crossing of the voxel-by-voxel walk must be
  // found, and no other, with origins that move along a line and planes that twist.
  struct Case {
    ConsistencyParams p;
    std::uint32_t seed;
    double spread, twist;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  };
  std::vector<Case> cases;
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    ConsistencyParams p;
    cases.push_back({p, seed, 0.0, 0.0});
    cases.push_back({p, seed + 10, 0.01 * seed, 0.004 * seed});
    p.hit_radius = seed - 1;
    p.min_passes = 2;
    p.resolution = 0.05 * seed;
    p.margin = 0.2 * seed;
    p.max_range = 8.0 + 3.0 * seed;
    cases.push_back({p, seed + 20, 0.02, 0.01});
  }
  cases.push_back({ConsistencyParams{}, 31u, 0.01, 0.005, {500000.0, 4500000.0, 100.0}});
  std::size_t total_inconsistent = 0, total_lonely_kept = 0;
  std::uint64_t total_crossings = 0;
  for (const Case& c : cases) {
    std::vector<Pass> passes = fan_scene(c.seed, 4, c.spread, c.twist, c.offset);
    std::uint64_t crossings = 0;
    const auto want = reference_labels(passes, c.p, &crossings);
    ConsistencyEvidence ev(c.p);
    for (const Pass& p : passes) ev.add_pass(p);
    ev.finalize();
    const auto& s = ev.stats();
    EXPECT_EQ(s.rays_in_fans, s.rays_walked) << "seed " << c.seed;  // every line made a fan
    EXPECT_EQ(s.crossings, crossings) << "seed " << c.seed;
    std::size_t labelled = 0;
    for (std::size_t k = 0; k < passes.size(); ++k) {
      labelled += ev.label(passes[k]);
      for (std::size_t i = 0; i < passes[k].size(); ++i)
        ASSERT_EQ(passes[k].label[i], want[k][i]) << "seed " << c.seed << " pass " << k << " return " << i;
    }
    total_inconsistent += labelled;
    total_lonely_kept += s.lonely_returns - labelled;
    total_crossings += crossings;
  }
  EXPECT_GT(total_inconsistent, 100u);
  EXPECT_GT(total_lonely_kept, 100u);
  EXPECT_GT(total_crossings, 1000u);
}

TEST(CheckConsistency, TheThreadCountDoesNotChangeTheLabels) {
  const std::vector<Pass> passes = random_scene(7, 5);
  std::vector<std::vector<Label>> got[2];
  for (unsigned threads : {1u, 2u}) {
    ConsistencyEvidence ev{ConsistencyParams{}};
    for (const Pass& p : passes) ev.add_pass(p);
    ev.finalize(*WorkShare::threads(threads));
    for (Pass p : passes) {
      ev.label(p);
      got[threads - 1].push_back(p.label);
    }
  }
  EXPECT_EQ(got[0], got[1]);
}

TEST(CheckConsistency, LabelsAPassThatChangedSinceItWasCollected) {
  // label() goes straight to the lonely returns finalize() found, by their position among the
  // pass's kept returns; given a pass that no longer matches (a return rejected since), it must
  // judge each return by its voxel, as for any pass.
  std::vector<Pass> passes = fan_scene(5, 3, 0.01, 0.004);
  ConsistencyEvidence ev{ConsistencyParams{}};
  for (const Pass& p : passes) ev.add_pass(p);
  ev.finalize();
  Pass changed = passes[1];
  std::vector<Label> want = passes[1].label;
  const std::size_t n = ev.label(passes[1]);
  ASSERT_GT(n, 5u);
  std::size_t first = 0;  // the first contradicted return: everything after it shifts by one
  while (passes[1].label[first] != Label::kInconsistent) ++first;
  changed.label[first / 2] = Label::kMixedPixel;
  want = passes[1].label;
  want[first / 2] = Label::kMixedPixel;
  EXPECT_EQ(ev.label(changed), first / 2 == first ? n - 1 : n);
  EXPECT_EQ(changed.label, want);
}

TEST(CheckConsistency, EvidenceIsCompleteBeforeLabelling) {
  std::vector<Pass> passes = random_scene(3, 2);
  ConsistencyEvidence ev{ConsistencyParams{}};
  ev.add_pass(passes[0]);
  EXPECT_THROW(ev.label(passes[0]), std::logic_error);  // not finalized: the labels would be wrong
  ev.finalize();
  EXPECT_THROW(ev.add_pass(passes[1]), std::logic_error);  // too late: the rays are gone
}
