// Planning a nodding profile (Broten & Collier 2005, sections 4-5).
//
// Angles here follow the report: theta is the depression of the beam below the horizon (0 at
// the horizon, 90 deg straight down); a beam at theta meets flat ground at x = h / tan(theta).
#pragma once

#include <string>
#include <vector>

namespace pcdp {

struct NodPlanParams {
  double height = 1.0;               ///< m, laser above the ground (h)
  double sample_distance = 0.02;     ///< m, desired ground distance between lines (d)
  double speed = 0.0;                ///< m/s, vehicle speed (v_m)
  double sweep_period = 0.0133;      ///< s, one line (tau)
  double dead_zone_time = 0.0;       ///< s, stopping distance = speed * this (5.2); 0: none
  double encoder_resolution = 0.0012566;  ///< rad (0.072 deg)
  double max_rate = 1.5708;          ///< rad/s (90 deg/s)
  bool constant_rate = false;        ///< profile: false uniform sample distance, true constant rate
  double rate = 0.5;                 ///< rad/s, constant-rate profile
  double angle_min = 0.0174533;      ///< rad, first depression angle tabulated (1 deg)
  double angle_max = 1.5533430;      ///< rad, last (89 deg)
  double angle_step = 0.0174533;     ///< rad (1 deg)
};

struct NodPlanRow {
  double angle = 0;           ///< depression, rad
  double ground_distance = 0; ///< h / tan(angle), m
  // Uniform profile: the step per line the ideal profile needs, nodding down (vehicle motion
  // against the nod: d + v tau) and up (with it: d - v tau); rates in rad/s.
  double step_down = 0, step_up = 0;
  bool resolution_limited = false;  ///< a needed step is smaller than one encoder count
  bool rate_limited = false;        ///< a needed step exceeds max_rate * tau
  bool in_dead_zone = false;        ///< nearer than the stopping distance
  bool achievable = false;
  // Constant-rate profile: the ground distance between this line and the next.
  double constant_rate_distance = 0;
};

struct NodPlan {
  std::vector<NodPlanRow> rows;
  double dead_zone_angle = 0;  ///< rad: theta_end = atan(h / s) (5.2), pi/2 without a dead zone
  /// The longest run of consecutive achievable angles (uniform profile), rad; 0, 0 when none.
  double achievable_from = 0, achievable_to = 0;
};

/// The ideal step (rad) from depression theta to the next line: theta' = atan(h / (h / tan(theta) - d_r))
/// (section 4.2 with d_r = d +/- v tau of section 5.1); pi/2 - theta when the ground point passes
/// under the laser.
double uniform_step(double theta, double height, double d_r);

NodPlan plan_nod(const NodPlanParams& p);

/// CSV of the plan (degrees for angles, deg/s for rates).
std::string nod_plan_csv(const NodPlan& plan, const NodPlanParams& p);

}  // namespace pcdp
