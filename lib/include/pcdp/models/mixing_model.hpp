// The mixed-pixel model: what a footprint split between two surfaces returns.
//
// Mixing (Ye & Borenstein 2002, section 4.5; the receiver integrates the echo): a footprint with a
// share f of its power-weighted area on a near surface at range d1 and the rest on a far surface at
// d2 returns the power-weighted range and the summed amplitude
//     r = (f P1 d1 + (1 - f) P2 d2) / (f P1 + (1 - f) P2),      A = f P1 + (1 - f) P2,
// where P1, P2 are the amplitudes each surface would return if it filled the footprint. With the
// power share w = f P1 / A of the near surface, r = w d1 + (1 - w) d2, so w follows from the range
// alone, and then the amplitude is fixed: A = 1 / (w / P1 + (1 - w) / P2), a weighted harmonic mean
// of P1 and P2 (mixture_amplitude_at). A non-coaxial receiver (Liu et al. 2005) can only lose
// part of the far surface's light behind the edge, so a real mixture is never brighter than that.
//
// Plane model: a planar surface meets the fan of a scan in a straight line, so two returns on one
// surface predict where a third beam meets it: the point of that beam's ray closest to the line
// through the two returns (range_on_line). This is exact for planes at any incidence, where
// extrapolating the range itself is not (ground at grazing incidence grows like 1 / sin of the
// depression angle: its range steps grow from line to line) when the three beams lie in one
// plane (one scan line); on curved surfaces its error is second order in the step.

#pragma once

#include <Eigen/Core>

namespace pcdp {

/// Range of a mixture with share f (0..1) of the footprint on the near surface (d1, P1).
double mixture_range(double f, double d1, double p1, double d2, double p2);
/// Amplitude of that mixture: f P1 + (1 - f) P2.
double mixture_amplitude(double f, double p1, double p2);
/// The footprint share f on the near surface that gives range r (d1 <= r <= d2); NaN outside, or
/// when d1 == d2 or an amplitude is not positive.
double mixture_share(double r, double d1, double p1, double d2, double p2);
/// The amplitude a mixture of the two surfaces has at range r: 1 / (w / P1 + (1 - w) / P2) with
/// w = (d2 - r) / (d2 - d1), r clamped to [d1, d2] (outside it the nearest mixture is the pure
/// surface). NaN when d2 <= d1 or an amplitude is not positive.
double mixture_amplitude_at(double r, double d1, double p1, double d2, double p2);

/// Range along the ray from `origin` in unit direction `dir` at its closest approach to the line
/// through a and b (the plane model above). NaN when a and b coincide or the line runs within
/// about 0.6 degrees of the ray (a surface seen exactly edge-on predicts nothing). `miss`, if
/// given, gets the distance between ray and line there: 0 when the three beams lie in one plane
/// (along a scan line); across lines of a nodding scan they are only nearly so, and a large miss
/// means the prediction is not about this beam's surface.
double range_on_line(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, double* miss = nullptr);

/// Range along the ray from `origin` in unit direction `dir` to the plane through `point` with
/// unit normal `normal` (the plane of a 2-D patch of returns: two along one scan direction, two
/// across). Unlike range_on_line it needs no third beam in the fan of the first two, so it
/// predicts across lines as well as along them. NaN when the ray runs within 1e-7 rad of the
/// plane (seen exactly edge-on, a plane predicts nothing). Negative: the plane is behind.
double range_on_plane(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& point,
                      const Eigen::Vector3d& normal);

}  // namespace pcdp
