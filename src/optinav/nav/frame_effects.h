// What a real flight adds to a frame synthesised from an orthophoto: altitude changes (scale),
// attitude (roll and pitch from gusts, and banking in turns: a true perspective view), motion
// blur, exposure changes and weather. Every effect is seeded.
#pragma once

#include <cstdint>
#include <functional>
#include <random>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "optinav/sim/weather.h"

namespace optinav::nav {

struct FrameEffectOptions {
  double altitude_variation = 0.05;  // smooth altitude change, +- fraction of the altitude
  // Gusts: the vehicle's roll and pitch per frame, a tilt uniform in [0, max] in a random
  // direction (pitch = tilt cos a, roll = tilt sin a); turns add their bank angle.
  double max_tilt_deg = 3.0;
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

// What the camera saw when a frame was taken (for effects that need the geometry, e.g. weather).
struct FrameView {
  int64_t t_ns = 0;
  Eigen::Vector3d position_enu = Eigen::Vector3d::Zero();  // camera, about the start; z = AGL
  // The attitude (maploc/aerial_camera.h convention): yaw = frame up, clockwise from north.
  double heading_deg = 0;
  double roll_deg = 0, pitch_deg = 0;
  double focal_px = 0;
  int width = 0, height = 0;
};
using FrameHook = std::function<void(cv::Mat& gray, const FrameView& view)>;

// A hook putting the simulator's weather (sim/weather.h: fog and dust haze by depth, rain, snow,
// leaves and dust particles as 3D objects around the camera) on a grey nadir frame. The depth
// of each pixel is its distance to flat ground along the optical axis, from the view's altitude
// and attitude. `spec.distance_scale` <= 0 picks altitude / 50: harsher than the simulator's advice
// for nadir cameras (altitude / 20); at 640 m, 50 % fog keeps about 38 % of the ground's
// contrast and 100 % under 1 %. Returns an empty hook for clear weather.
FrameHook MakeWeatherHook(sim::WeatherSpec spec, uint64_t seed);

}  // namespace optinav::nav
