// The simulator's shapes beyond axis-aligned boxes: boxes turned about the vertical (edges oblique
// to the scan lines) and vertical cylinders (posts), their truth height, and their scene keys.
#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/sim/nodding_sim.hpp"

using namespace pcdp;
using namespace pcdp::sim;

namespace {
constexpr double kPi = 3.14159265358979323846;

/// A static, single-ray scanner at the origin (vehicle = map, mount = identity), ground out of reach.
SimConfig static_scanner() {
  SimConfig c;
  c.mount_translation = {0, 0, 0};
  c.mount_rpy = {0, 0, 0};
  c.motion.speed = 0.0;
  c.scene.ground_z = -100.0;
  c.scanner.range_max = 30.0;
  c.scanner.amplitude_scale = 1000.0;
  return c;
}

/// One ray in the scan plane (nod 0) at `bearing`, with the footprint axes.
BeamResult ray(const SimConfig& c, double bearing, const Eigen::Vector3d& origin = Eigen::Vector3d::Zero()) {
  const Eigen::Vector3d d = nod_frame_point(1.0, bearing, 0.0);
  const Eigen::Vector3d u(-std::sin(bearing), std::cos(bearing), 0.0), v(0, 0, 1);
  return cast_beam(c, origin, d, u, v, bearing);
}
}  // namespace

TEST(SimShapes, ATurnedBoxIsHitOnItsTurnedFaceAndItsCornerIsWhereGeometrySays) {
  SimConfig c = static_scanner();
  const double yaw = 0.5;  // rad
  // 1 m deep, 4 m wide, centred at (6, 0); turned by yaw about z through the centre.
  c.scene.boxes.push_back({{5.5, -2.0, -2.0}, {6.5, 2.0, 2.0}, 0.5, yaw});
  const Eigen::Vector2d centre(6.0, 0.0), n(std::cos(yaw), std::sin(yaw));  // front face normal is -n
  for (double b : {-0.2, -0.1, 0.0, 0.1, 0.2}) {
    const BeamResult r = ray(c, b);
    ASSERT_TRUE(r.any_hit) << b;
    // The front face: (p - centre) . n = -0.5, p = t (cos b, sin b).
    const Eigen::Vector2d d(std::cos(b), std::sin(b));
    const double t = (-0.5 + centre.dot(n)) / d.dot(n);
    EXPECT_NEAR(r.range, t, 1e-9) << b;
    // Amplitude = scale * reflectivity * cos(incidence) / range: the normal is turned too.
    EXPECT_NEAR(r.amplitude, 1000.0 * 0.5 * std::fabs(d.dot(n)) / t, 1e-6) << b;
  }
  // The front face's left corner, local (5.5, 2) turned about the centre: the edge between the
  // front face and the left side face. Rays just right of it hit the front face, rays just left
  // of it the side face ((p - centre) . m = 2, m = the turned +y axis).
  const Eigen::Vector2d m(-std::sin(yaw), std::cos(yaw));
  const Eigen::Vector2d corner = centre - 0.5 * n + 2.0 * m;
  const double bc = std::atan2(corner.y(), corner.x());
  const auto plane_t = [&](double b, const Eigen::Vector2d& normal, double offset) {
    const Eigen::Vector2d d(std::cos(b), std::sin(b));
    return (offset + centre.dot(normal)) / d.dot(normal);
  };
  EXPECT_NEAR(ray(c, bc - 1e-4).range, plane_t(bc - 1e-4, n, -0.5), 1e-9);
  EXPECT_NEAR(ray(c, bc + 1e-4).range, plane_t(bc + 1e-4, m, 2.0), 1e-9);
  // The box's silhouette ends at its left rear corner: beyond it nothing is hit.
  const Eigen::Vector2d rear = centre + 0.5 * n + 2.0 * m;
  const double br = std::atan2(rear.y(), rear.x());
  EXPECT_TRUE(ray(c, br - 1e-4).any_hit);
  EXPECT_FALSE(ray(c, br + 1e-4).any_hit);
  // Unturned, the same bearing just left of the front corner would still be on the front face.
  SimConfig flat = c;
  flat.scene.boxes[0].yaw = 0.0;
  EXPECT_NEAR(ray(flat, bc + 1e-4).range, 5.5 / std::cos(bc + 1e-4), 1e-9);
}

TEST(SimShapes, ATurnedBoxsTopHeightFollowsItsTurnedFootprint) {
  Scene s;
  s.ground_z = 0.0;
  s.boxes.push_back({{-1.0, -0.2, -0.3}, {1.0, 0.2, 0.7}, 0.5, kPi / 4});  // a 2 m x 0.4 m box at 45 deg
  EXPECT_DOUBLE_EQ(s.top_height(0.0, 0.0), 0.7);
  EXPECT_DOUBLE_EQ(s.top_height(0.6, 0.6), 0.7);   // on the turned diagonal: inside
  EXPECT_DOUBLE_EQ(s.top_height(0.9, 0.0), 0.0);   // inside the unturned box, outside the turned one
  EXPECT_DOUBLE_EQ(s.top_height(-0.6, -0.6), 0.7);
  EXPECT_DOUBLE_EQ(s.top_height(0.6, -0.6), 0.0);
}

TEST(SimShapes, APostIsHitOnItsRoundSideAndOnItsTop) {
  SimConfig c = static_scanner();
  c.scene.posts.push_back({5.0, 0.0, 0.1, -1.0, 1.0, 0.8});
  for (double b : {0.0, 0.01, -0.015}) {
    const BeamResult r = ray(c, b);
    ASSERT_TRUE(r.any_hit) << b;
    // |t (cos b, sin b) - (5, 0)| = 0.1, nearer root.
    const double t = 5.0 * std::cos(b) - std::sqrt(0.01 - 25.0 * std::sin(b) * std::sin(b));
    EXPECT_NEAR(r.range, t, 1e-9) << b;
    const Eigen::Vector2d p(t * std::cos(b), t * std::sin(b));
    const Eigen::Vector2d normal = (p - Eigen::Vector2d(5.0, 0.0)) / 0.1;
    EXPECT_NEAR(r.amplitude, 1000.0 * 0.8 * std::fabs(normal.dot(Eigen::Vector2d(std::cos(b), std::sin(b)))) / t, 1e-6);
  }
  EXPECT_FALSE(ray(c, 0.021).any_hit);  // sin(b) * 5 > 0.1: beside the post
  // From above, straight down onto the top cap.
  const BeamResult top = cast_beam(c, {5.03, 0.02, 3.0}, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}, 0.0);
  ASSERT_TRUE(top.any_hit);
  EXPECT_NEAR(top.range, 2.0, 1e-12);
  // Truth height: the post's top over its disc, the terrain beside it.
  c.scene.ground_z = 0.0;
  EXPECT_DOUBLE_EQ(c.scene.top_height(5.05, 0.05), 1.0);
  EXPECT_DOUBLE_EQ(c.scene.top_height(5.0, 0.11), 0.0);
}

TEST(SimShapes, AScanAcrossAPostInFrontOfAWallGivesReturnsOnThePostAndMixedPixelsAtItsSides) {
  SimConfig c = static_scanner();
  c.scanner.beams = 401;
  c.scanner.bearing_min = -0.05;
  c.scanner.bearing_max = 0.05;
  c.scanner.beam_divergence = 0.01;
  c.scanner.subrays = 37;
  c.scanner.min_amplitude = 1.0;
  c.scanner.mixed_pixel_tolerance = 0.04;
  c.scanner.nod_rate = 0.0;
  c.scanner.nod_min = c.scanner.nod_max = 0.0;
  c.lines_per_pass = 1;
  c.scene.posts.push_back({5.0, 0.0, 0.075, -2.0, 2.0, 0.5});
  c.scene.boxes.push_back({{9.0, -5.0, -5.0}, {9.5, 5.0, 5.0}, 0.5});  // a wall behind
  const SimResult r = simulate(c);
  const SimPass& sp = r.passes.at(0);
  int on_post = 0, on_wall = 0, mixed = 0;
  for (std::size_t i = 0; i < sp.pass.size(); ++i) {
    const float range = sp.pass.range[i];
    ASSERT_GT(range, 0.0f) << i;
    if (sp.truth[i] == Label::kMixedPixel) {
      ++mixed;
      EXPECT_GT(range, 4.925 + 0.04);
      EXPECT_LT(range, 9.0 - 0.04);
      EXPECT_EQ(sp.footprint[i].near_object, 1);  // the post: object boxes.size() + 0
      EXPECT_EQ(sp.footprint[i].far_object, 0);   // the wall
    } else if (range < 5.1) {
      ++on_post;
    } else {
      ++on_wall;
    }
  }
  EXPECT_GT(on_post, 10);  // the 15 cm post spans 0.03 rad of the 0.1 rad scan
  EXPECT_GT(on_wall, 100);
  EXPECT_GT(mixed, 4);  // at both sides
}

TEST(SimShapes, SceneKeysForTurnedBoxesAndPosts) {
  const std::string base =
      "passes: 1\nlines_per_pass: 2\nscanner: {beams: 11}\n"
      "boxes:\n  - {min: [1, 1, 0], max: [2, 3, 1], yaw: 0.3, reflectivity: 0.2}\n";
  const SimConfig c = load_scene_from_string(base + "posts:\n  - {name: p, x: 4, y: -1, radius: 0.05, z_min: -0.2, z_max: 1.5}\n",
                                             "scene.yaml");
  ASSERT_EQ(c.scene.boxes.size(), 1u);
  EXPECT_DOUBLE_EQ(c.scene.boxes[0].yaw, 0.3);
  ASSERT_EQ(c.scene.posts.size(), 1u);
  EXPECT_DOUBLE_EQ(c.scene.posts[0].x, 4.0);
  EXPECT_DOUBLE_EQ(c.scene.posts[0].radius, 0.05);
  EXPECT_DOUBLE_EQ(c.scene.posts[0].z_max, 1.5);
  EXPECT_DOUBLE_EQ(c.scene.posts[0].reflectivity, 0.5);  // default
  EXPECT_THROW(load_scene_from_string(base + "posts:\n  - {x: 4, y: -1, radius: 0.05, z_min: 1, z_max: 0.5}\n", "s"),
               ConfigError);
  EXPECT_THROW(load_scene_from_string(base + "posts:\n  - {x: 4, y: -1, z_min: 0, z_max: 1}\n", "s"), ConfigError);
  EXPECT_THROW(load_scene_from_string(base + "posts:\n  - {x: 4, y: -1, radius: 0.05, z_min: 0, z_max: 1, hieght: 2}\n", "s"),
               ConfigError);
  EXPECT_THROW(load_scene_from_string(base + "posts:\n  - {x: 4, y: -1, radius: -1, z_min: 0, z_max: 1}\n", "s"),
               ConfigError);
}
