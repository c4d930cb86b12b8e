// What a real flight adds to a frame synthesised from an orthophoto: altitude changes (scale),
// camera tilt (perspective), motion blur, exposure changes and weather. Every effect is seeded.
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include <opencv2/core.hpp>

namespace optinav::nav {

struct FrameEffectOptions {
  double altitude_variation = 0.05;  // smooth altitude change, +- fraction of the altitude
  double max_tilt_deg = 3.0;         // camera tilt away from nadir, uniform in [0, max]
  double yaw_jitter_deg = 2.0;       // camera yaw about the flight direction (sigma)
  double motion_blur_px = 1.5;       // blur length along the flight direction, uniform [0, max]
  double exposure_variation = 0.15;  // gain uniform in 1 +- this; gamma in 1 +- this / 2
  double noise_sigma = 2.0;          // sensor noise, grey levels
  std::string Check() const;         // "" when valid, else names the field
};

// Smooth, seeded altitude factor over time: 1 + variation * (sum of slow sinusoids), in
// [1 - variation, 1 + variation].
class AltitudeProfile {
 public:
  AltitudeProfile(double variation, uint64_t seed);
  double Factor(double t_s) const;

 private:
  double variation_;
  double amp_[3], freq_[3], phase_[3];
};

// Motion blur (a line kernel along `direction_rad`, clockwise from frame up), exposure (gain and
// gamma) and sensor noise, in place on an 8-bit grey frame. Draws from `rng`.
void ApplyPhotometricEffects(cv::Mat& gray, const FrameEffectOptions& options, double direction_rad,
                             std::mt19937_64& rng);

}  // namespace optinav::nav
