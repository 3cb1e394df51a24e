#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/pass.hpp"
#include "pcdp/stages/check_consistency.hpp"

using namespace pcdp;

namespace {
/// A registered pass of single rays from `origin` to the given points.
Pass rays(std::size_t index, const Eigen::Vector3d& origin, const std::vector<Eigen::Vector3d>& pts) {
  Pass p;
  p.index = index;
  for (const auto& q : pts) {
    p.x.push_back(q.x());
    p.y.push_back(q.y());
    p.z.push_back(q.z());
    p.ox.push_back(origin.x());
    p.oy.push_back(origin.y());
    p.oz.push_back(origin.z());
    p.label.push_back(Label::kKept);
    p.range.push_back(static_cast<float>((q - origin).norm()));
  }
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
  EXPECT_EQ(ev.label(a), 1u);
  EXPECT_EQ(a.label.back(), Label::kInconsistent);
  for (std::size_t i = 0; i + 1 < a.size(); ++i) EXPECT_EQ(a.label[i], Label::kKept);
  EXPECT_EQ(ev.label(b), 0u);
  // Its own rays never contradict a pass: with only pass 0, nothing is labelled.
  ConsistencyEvidence alone(prm);
  Pass a2 = rays(0, {0.05, 0.05, 1.05}, p0);
  alone.add_pass(a2);
  EXPECT_EQ(alone.label(a2), 0u);
}
