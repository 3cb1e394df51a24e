#include <gtest/gtest.h>

#include <cmath>

#include "pcdp/models/nod_plan.hpp"

using namespace pcdp;

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}

TEST(NodPlan, UniformStepKeepsTheGroundDistance) {
  for (double theta : {10 * kDeg, 30 * kDeg, 60 * kDeg}) {
    const double step = uniform_step(theta, 1.5, 0.1);
    EXPECT_NEAR(1.5 / std::tan(theta) - 1.5 / std::tan(theta + step), 0.1, 1e-12);
  }
  // Once the ground point would pass under the laser the step goes straight down.
  EXPECT_NEAR(uniform_step(89.5 * kDeg, 1.0, 0.02), 0.5 * kDeg, 1e-12);
}

TEST(NodPlan, ReproducesBrotenCollierSection42LowerLimit) {
  // h = 1 m, d = 0.02 m, tau = 13.3 ms, 0.072 deg encoder, 90 deg/s (Broten & Collier 4.2): below
  // about 15 degrees the step needed per line is smaller than one encoder count.
  NodPlanParams p;
  p.angle_step = 0.1 * kDeg;
  const NodPlan plan = plan_nod(p);
  EXPECT_NEAR(plan.achievable_from / kDeg, 15.0, 0.5);
  // The report's upper limit (75 deg) does not follow from 90 deg/s: the ideal profile needs at
  // most 86 deg/s at 13.3 ms per line, so it stays achievable almost to the vertical...
  EXPECT_GT(plan.achievable_to / kDeg, 85.0);
  for (const auto& r : plan.rows) EXPECT_FALSE(r.rate_limited);
  // ...and a usable rate of 80 deg/s puts the limit where the report does.
  p.max_rate = 80 * kDeg;
  const NodPlan slower = plan_nod(p);
  EXPECT_NEAR(slower.achievable_to / kDeg, 74.0, 2.0);
  EXPECT_NEAR(slower.achievable_from / kDeg, 15.0, 0.5);
}

TEST(NodPlan, VehicleMotionAndDeadZone) {
  NodPlanParams p;
  p.height = 2.0;
  p.sample_distance = 0.2;
  p.speed = 2.0;
  p.dead_zone_time = 1.5;  // stopping distance 3 m
  const NodPlan plan = plan_nod(p);
  EXPECT_NEAR(plan.dead_zone_angle, std::atan2(2.0, 3.0), 1e-12);
  for (const auto& r : plan.rows) {
    if (r.ground_distance > 0.2 + 2.0 * 0.0133) {
      EXPECT_GT(r.step_down, r.step_up);  // motion works against the downward nod (5.1)
    }
    EXPECT_EQ(r.in_dead_zone, r.angle > plan.dead_zone_angle);
    if (r.in_dead_zone) {
      EXPECT_FALSE(r.achievable);
    }
  }
  // A vehicle faster than d / tau outruns an upward nod: nothing is achievable.
  p.speed = 20.0;
  EXPECT_EQ(plan_nod(p).achievable_to, 0.0);
}

TEST(NodPlan, ConstantRateSampleDistanceGrowsTowardsTheHorizon) {
  NodPlanParams p;
  p.rate = 60 * kDeg;
  const NodPlan plan = plan_nod(p);
  for (std::size_t i = 1; i < plan.rows.size(); ++i)
    EXPECT_LT(plan.rows[i].constant_rate_distance, plan.rows[i - 1].constant_rate_distance);  // Broten & Collier 4.1.1
}
