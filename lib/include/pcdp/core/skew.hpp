// Skew correction (Broten & Collier 3.2; docs/data_contract.md "Skew").
//
// The encoder is read once per line, at the stamp of the line's last return. Every return gets
// the nod angle at its own stamp, interpolated linearly between the readings that bracket it and
// extrapolated with the local rate at the ends. Reversals of the nod are handled because the
// interpolation is local.
//
// Reading of the report: it prints  theta_c = theta_r +/- omega * i / N  ("positive for an
// increasing encoder"). Taken literally this is inconsistent twice: omega * i / N has units of
// rad/s (the sweep period tau is missing), and since the encoder is read *after* the last return,
// a return scanned earlier in the line was at an *earlier* angle, i.e. for an increasing encoder
// its angle is *below* the reading, by omega * tau * (N - i) / N. The physically right correction
// is therefore  theta(t) = theta_r - omega * (t_read - t), which is what interpolation in time
// gives (the report's "+" holds if i counts back from the reading). tests/unit/core/test_skew.cpp
// checks it against a constant-rate nod.
#pragma once

#include <cstddef>
#include <vector>

namespace pcdp {

struct Pass;

/// Per-line encoder readings of one pass as a function of time.
class EncoderTrack {
 public:
  EncoderTrack() = default;
  /// `stamps` strictly increasing. `latency`: a reading describes the angle at stamp - latency.
  EncoderTrack(std::vector<double> stamps, std::vector<double> angles, double latency);

  /// The nod angle at `stamp`. `hint` carries the last bracket between calls (O(1) for sorted
  /// queries). With a single reading, that reading (no rate can be estimated).
  double angle_at(double stamp, std::size_t& hint) const {
    // Inline for the usual case, a stamp in the hint's own bracket (every return of a line).
    if (hint + 1 < t_.size() && stamp >= t_[hint] && stamp <= t_[hint + 1]) return a_[hint] + (stamp - t_[hint]) * slope_[hint];
    return angle_search(stamp, hint);
  }
  /// The local nod rate (rad/s) at `stamp`: the slope of the bracketing readings (0 with one).
  double rate_at(double stamp, std::size_t& hint) const;
  std::size_t size() const { return t_.size(); }
  /// Reading k (after angle_at, `hint` holds the k whose bracket [k, k + 1] gave the angle).
  double reading(std::size_t k) const { return a_[k]; }

 private:
  std::size_t bracket(double stamp, std::size_t hint) const;
  double angle_search(double stamp, std::size_t& hint) const;
  std::vector<double> t_, a_, slope_;  // slope_[k]: rad/s over bracket [k, k + 1]
};

/// The track of a pass: reading of line k = its `nod`, at the stamp of its last return.
EncoderTrack encoder_track(const Pass& pass, double latency);

}  // namespace pcdp
