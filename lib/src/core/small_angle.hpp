// Sine and cosine of small angles by their Taylor series (internal to the library).
//
// Below kSmallAngle the first omitted term is under 3e-18 of the result (sin: x^11/11! against x;
// cos: x^12/12! against 1), far below double rounding (1.1e-16), so these agree with std::sin and
// std::cos to a few units in the last place (tests/unit/core/test_transforms.cpp checks it) and cost a
// handful of multiplications instead of a library call. Used where a hot loop needs the sine of
// an angle that is small by construction: the slerp of nearby poses, the nod's step within a line.
#pragma once

namespace pcdp::detail {

constexpr double kSmallAngle = 0.1;  ///< rad

/// sin(x) for |x| <= kSmallAngle: x - x^3/3! + x^5/5! - x^7/7! + x^9/9!
inline double sin_small(double x) {
  const double x2 = x * x;
  return x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0) * (1.0 - x2 * (1.0 / 72.0)))));
}

/// cos(x) for |x| <= kSmallAngle: 1 - x^2/2! + x^4/4! - ... + x^10/10!
inline double cos_small(double x) {
  const double x2 = x * x;
  return 1.0 - x2 * 0.5 *
                   (1.0 - x2 * (1.0 / 12.0) *
                              (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0) * (1.0 - x2 * (1.0 / 90.0)))));
}

/// 1 - cos(x) for |x| <= kSmallAngle: x^2/2! - x^4/4! + ... - x^12/12! (no cancellation; the
/// first omitted term is under 4e-18 of the result)
inline double vers_small(double x) {
  const double x2 = x * x;
  return x2 * 0.5 *
         (1.0 - x2 * (1.0 / 12.0) *
                    (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0) * (1.0 - x2 * (1.0 / 90.0) * (1.0 - x2 * (1.0 / 132.0))))));
}

}  // namespace pcdp::detail
