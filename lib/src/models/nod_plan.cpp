#include "pcdp/models/nod_plan.hpp"

#include <cmath>
#include <sstream>

namespace pcdp {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;
}  // namespace

double uniform_step(double theta, double height, double d_r) {
  const double x = height / std::tan(theta);
  const double x_next = x - d_r;
  if (x_next <= 0.0) return kPi / 2 - theta;
  return std::atan2(height, x_next) - theta;
}

NodPlan plan_nod(const NodPlanParams& p) {
  NodPlan plan;
  const double stop = p.speed * p.dead_zone_time;
  plan.dead_zone_angle = stop > 0.0 ? std::atan2(p.height, stop) : kPi / 2;
  const double max_step = p.max_rate * p.sweep_period;
  const double motion = p.speed * p.sweep_period;
  double run_from = 0, best_from = 0, best_to = 0, best_len = -1;
  bool in_run = false;
  for (double a = p.angle_min; a <= p.angle_max + 1e-12; a += p.angle_step) {
    NodPlanRow r;
    r.angle = a;
    r.ground_distance = p.height / std::tan(a);
    // Down: the nod brings the ground point towards the vehicle while the vehicle moves
    // forward, so the nod must cover d + v tau; up: d - v tau (Broten & Collier 5.1).
    r.step_down = uniform_step(a, p.height, p.sample_distance + motion);
    const double d_up = p.sample_distance - motion;
    r.step_up = d_up > 0 ? -uniform_step(a, p.height, -d_up) : 0.0;  // moving the ground point away
    r.resolution_limited = r.step_down < p.encoder_resolution || (d_up > 0 && r.step_up < p.encoder_resolution);
    r.rate_limited = r.step_down > max_step || r.step_up > max_step;
    r.in_dead_zone = a > plan.dead_zone_angle;
    r.achievable = !r.resolution_limited && !r.rate_limited && !r.in_dead_zone && d_up > 0;
    const double next = a + p.rate * p.sweep_period;
    r.constant_rate_distance = next < kPi / 2 ? r.ground_distance - p.height / std::tan(next) : r.ground_distance;
    plan.rows.push_back(r);
    if (r.achievable && !in_run) {
      in_run = true;
      run_from = a;
    }
    if (in_run && (!r.achievable || a + p.angle_step > p.angle_max + 1e-12)) {
      const double to = r.achievable ? a : a - p.angle_step;
      if (to - run_from > best_len) {
        best_len = to - run_from;
        best_from = run_from;
        best_to = to;
      }
      in_run = false;
    }
  }
  if (best_len >= 0) {
    plan.achievable_from = best_from;
    plan.achievable_to = best_to;
  }
  return plan;
}

std::string nod_plan_csv(const NodPlan& plan, const NodPlanParams& p) {
  std::ostringstream os;
  os << "depression_deg,ground_distance_m,uniform_rate_down_deg_s,uniform_rate_up_deg_s,resolution_limited,"
        "rate_limited,dead_zone,uniform_achievable,constant_rate_sample_distance_m\n";
  for (const auto& r : plan.rows) {
    os << r.angle * kDeg << ',' << r.ground_distance << ',' << r.step_down / p.sweep_period * kDeg << ','
       << r.step_up / p.sweep_period * kDeg << ',' << r.resolution_limited << ',' << r.rate_limited << ','
       << r.in_dead_zone << ',' << r.achievable << ',' << r.constant_rate_distance << '\n';
  }
  return os.str();
}

}  // namespace pcdp
