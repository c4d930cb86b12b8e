// Angle wrapping: the one definition for headings, bearings, yaw offsets and attitude residuals.
#pragma once

#include <cmath>

namespace optinav {

// In [0, 360).
inline double WrapDeg360(double a) {
  a = std::fmod(a, 360.0);
  if (a < 0) a += 360.0;
  return a >= 360.0 ? 0.0 : a;  // -1e-17 + 360 rounds to 360
}

// In [-180, 180).
inline double WrapDeg180(double a) { return WrapDeg360(a + 180.0) - 180.0; }

// Radians, in [-pi, pi] (the nearest multiple of 2 pi removed).
inline double WrapRadPi(double a) { return std::remainder(a, 2 * M_PI); }

}  // namespace optinav
