// The received-amplitude profile of a non-coaxial LADAR scanning past a range edge
// (Liu, Adams & Wijesoma 2005, section 4, eqs. 1-19).
//
// Target 1 (near, range d1, amplitude P1 when fully lit) ends at an edge; target 2 (far, d2, P2)
// lies behind it. x is the displacement of the footprint past the point where its leading edge
// reaches the edge of target 1 (metres at target 1). The receiver sits s - q from the
// transmitter; theta is the transceiver separation angle (0: separated across the edge,
// 90 deg: "coaxial" for this edge), so the separation that matters is (s - q) cos(theta).
//
// Received amplitude = P1 * (part of the footprint still on target 1)
//                    + P2 * (part on target 2 that the receiver can see),
// eqs. 3, 7, 11, 15 and 16, with
//   X1 = (s - q)(d2 - d1) / d2                 (eq. 4)  target 2 starts to be seen,
//   X2 = X1 + d1 alpha                         (eq. 12) target 2 fully seen,
//   theta1 = acos(1 - 2 x / (d1 alpha))        (eq. 7),
//   theta2 = acos(1 - 2 (x - X1) / (d1 alpha)) (eqs. 10, 14 as corrected here).
//
// Which scale for theta2? Eqs. 10 and 14 print d2 alpha; eq. 12 implies d1 alpha. The rays that
// pass the edge of target 1 form, at range d2, a segment of the r2 = d2 alpha / 2 disk whose
// height is (d2 / d1) x (similar triangles from the transmitter); the receiver's view of target 2
// is cut by the same edge, from a point s - q to the side, so the part it sees has height
// (d2 / d1)(x - X1). Relative to r2 that is 2 (x - X1) / (d1 alpha): the d1 alpha scale. It is
// the only reading under which (a) the profile is continuous at X2, where eq. 16 says P2 is
// reached, and (b) a coaxial sensor (s - q = 0) loses no energy (P1 share + P2 share = 1, so no
// dip below min(P1, P2)). With d2 alpha the profile jumps at X2 and a coaxial sensor would dip.
// amplitude_as_printed() keeps the printed version for the tests that show this.
#pragma once

#include <utility>
#include <vector>

namespace pcdp {

struct EdgeParams {
  double d1 = 5.8;          ///< m, near target range
  double d2 = 12.6;         ///< m, far target range (> d1)
  double p1 = 115.0;        ///< amplitude of target 1 fully lit
  double p2 = 50.0;         ///< amplitude of target 2 fully lit
  double alpha = 0.003;     ///< rad, full beam divergence
  double separation = 0.029;///< m, s - q
  double theta = 0.0;       ///< rad, transceiver separation angle
};

/// Fraction of a disk of diameter 1 beyond a chord at depth u from its edge (u in [0, 1]):
/// (theta - sin(2 theta) / 2) / pi with theta = acos(1 - 2u).
double disk_fraction(double u);

/// Signed effective separation (s - q) cos(theta); <= 0: the receiver is on the far side of the
/// edge and sees everything lit (no occlusion).
double effective_separation(const EdgeParams& e);
double x1(const EdgeParams& e);  ///< eq. 4 with the effective separation (0 when it is <= 0)
double x2(const EdgeParams& e);  ///< eq. 12

/// The received amplitude at displacement x (eqs. 3, 7, 11, 15, 16, d1 alpha reading).
double amplitude_at(const EdgeParams& e, double x);
/// The same with theta2 scaled by d2 alpha as printed in eqs. 10 and 14 (for comparison only).
double amplitude_as_printed(const EdgeParams& e, double x);

struct ProfileMinimum {
  double x = 0.0;
  double amplitude = 0.0;
};
/// The minimum over x. By eqs. 17-18 it lies in [X1, 2 r1] (eq. 19 has no closed form): found by
/// a grid and golden-section refinement.
ProfileMinimum profile_minimum(const EdgeParams& e);
/// A lower bound of the profile, from the separation alone: min(p1, p2) (2 - 2 F(1/2 + c/2)), F
/// the disk fraction and c = X1 / (d1 alpha) clamped to [0, 1] (0 when the far target can be hidden).
double profile_lower_bound(const EdgeParams& e);
/// Whether the profile's minimum (as profile_minimum finds it) is below `level`: false at once
/// where the lower bound is above it, and the search stops at the first amplitude below it.
bool profile_dips_below(const EdgeParams& e, double level);

/// The profile sampled at n points over [-0.2 X2, 1.2 X2] (for plots and CSV).
std::vector<std::pair<double, double>> amplitude_profile(const EdgeParams& e, int n);

/// Minimum amplitude against theta (Liu et al. Fig. 18): the worst case over both edge
/// orientations, i.e. with (s - q)|cos(theta)|.
std::vector<std::pair<double, double>> minimum_vs_theta(EdgeParams e, int n);

}  // namespace pcdp
