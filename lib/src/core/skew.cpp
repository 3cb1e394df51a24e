#include "pcdp/core/skew.hpp"

#include <algorithm>
#include <cassert>

#include "pcdp/core/pass.hpp"

namespace pcdp {

EncoderTrack::EncoderTrack(std::vector<double> stamps, std::vector<double> angles, double latency)
    : t_(std::move(stamps)), a_(std::move(angles)) {
  assert(t_.size() == a_.size());
  for (double& t : t_) t -= latency;
  // Each bracket's slope once, not a division per query.
  for (std::size_t k = 0; k + 1 < t_.size(); ++k) slope_.push_back((a_[k + 1] - a_[k]) / (t_[k + 1] - t_[k]));
}

std::size_t EncoderTrack::bracket(double stamp, std::size_t hint) const {
  const std::size_t n = t_.size();
  std::size_t k;
  if (hint + 1 < n && stamp >= t_[hint] && stamp <= t_[hint + 1]) {
    k = hint;
  } else if (hint + 2 < n && stamp >= t_[hint + 1] && stamp <= t_[hint + 2]) {
    k = hint + 1;
  } else {
    const auto it = std::upper_bound(t_.begin(), t_.end(), stamp);
    const std::size_t u = static_cast<std::size_t>(it - t_.begin());
    k = u == 0 ? 0 : std::min(u - 1, n - 2);  // before the first / after the last: extrapolate
  }
  return k;
}

double EncoderTrack::angle_search(double stamp, std::size_t& hint) const {
  const std::size_t n = t_.size();
  if (n == 0) return 0.0;
  if (n == 1) return a_[0];
  const std::size_t k = hint = bracket(stamp, hint);
  return a_[k] + (stamp - t_[k]) * slope_[k];
}

double EncoderTrack::rate_at(double stamp, std::size_t& hint) const {
  if (t_.size() < 2) return 0.0;
  const std::size_t k = hint = bracket(stamp, hint);
  return slope_[k];
}

EncoderTrack encoder_track(const Pass& pass, double latency) {
  std::vector<double> t, a;
  t.reserve(pass.line_count());
  a.reserve(pass.line_count());
  for (std::size_t k = 0; k < pass.line_count(); ++k) {
    const std::size_t last = pass.line_begin[k + 1] - 1;
    t.push_back(pass.stamp[last]);
    a.push_back(pass.nod[last]);
  }
  return EncoderTrack(std::move(t), std::move(a), latency);
}

}  // namespace pcdp
