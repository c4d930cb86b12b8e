// Weather for synthetic or real camera images: the conditions of the AirSim weather dataset,
// SEEDS.md part 1 (rain, snow, falling leaves, fog, dust storm, and road wetness/snow/leaves), at
// an intensity of 0..100 % (the dataset's presets are 25, 50, 75, 100).
//
// Two parts:
//  1. Image effects, ApplyWeather(): work on ANY rendered camera image given its per-pixel depth,
//     the camera model and its pose in a z-up world, so they are usable on frames synthesised
//     by other means (e.g. an orthophoto warped into a nadir drone camera):
//       - fog: depth-dependent attenuation towards a grey airlight (Koschmieder:
//         I = J e^(-beta d) + A (1 - e^(-beta d)), beta = 3.912 / visibility);
//       - dust: the same with an ochre airlight, a shorter visibility, a global contrast loss and
//         fine wind-blown particles;
//       - rain: falling drops drawn as motion-blurred streaks, slight haze;
//       - snow: falling, swaying flakes;
//       - leaves: falling, tumbling leaves in autumn colours.
//     Particles are 3D objects in the world: an infinite lattice of cells (2 m) moving with the
//     particles' fall velocity, each cell's particles drawn from a hash of (cell, seed, kind).
//     Any camera at any pose and time sees the same particles: the two images of a stereo pair
//     agree, successive frames show the same flake falling; no state is kept between calls.
//     Particles hide behind scene geometry closer than them (depth test per pixel).
//  2. Surface effects, ApplySurfaceWeather(): wet darkening, snow cover, leaves on the ground,
//     applied to the world's ground textures when a world is built (sim/world.h), so they are
//     part of the scene geometry and seen consistently from everywhere.
// Intensity 0 changes nothing (bit-exact). A weather never changes anything but the weather: the
// same seed gives the same particles whatever the route, and the scene itself is unchanged.
#pragma once

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"

namespace optinav::sim {

enum class WeatherKind {
  kNone,
  kRain,         // streaks + wet (darker) ground
  kSnow,         // flakes + ground whitening
  kLeaves,       // falling leaves + leaves on the ground
  kFog,          // depth-dependent haze
  kDust,         // tinted haze, contrast loss, particles
  kRoadWetness,  // surface only: wet road (urban)
  kRoadSnow,     // surface only: snow on the road (urban)
  kRoadLeaves,   // surface only: leaves on the road (urban)
};

struct WeatherSpec {
  WeatherKind kind = WeatherKind::kNone;
  double intensity = 0.0;  // 0..1 (100 %)
  // Multiplies the fog/dust/rain/snow visibility distances. 1 suits ground vehicles and low
  // flights (fog visibility 1000 m at 0+ %, 200 m at 50 %, 40 m at 100 %). A nadir camera at
  // altitude h wants about h / 20: then 100 % fog leaves the ground e^-2 (14 %) of its contrast
  // and 50 % about 70 %.
  double distance_scale = 1.0;
  // Diagnostics: the particles frozen as they are at t = 0 (position, sway and tumble), the
  // same 3D objects in every frame. They hide the scene as before but do not move: a run on
  // such a sequence tells what the particles' motion does to an estimator from what their
  // occlusion does (`optinav sim --particles-still`; docs/VIO.md, 2026-12-06 later).
  bool particles_still = false;

  bool IsClear() const { return kind == WeatherKind::kNone || intensity <= 0; }
  bool HasParticles() const;
  bool HasHaze() const;
  // "none", "fog:50", ... (intensity in percent, rounded).
  std::string ToString() const;
};

// Parses "none" | "KIND:PERCENT" | "KIND" (= 50 %), KIND one of rain, snow, leaves, fog, dust,
// road-wetness, road-snow, road-leaves; PERCENT a number in [0, 100]. Throws optinav::Error
// (field "weather") naming the problem: unknown kind (listing the valid ones), a malformed or
// out-of-range intensity.
WeatherSpec ParseWeather(const std::string& text);
std::string WeatherKindName(WeatherKind kind);

// Visibility (m) of the haze of `spec` (fog, dust, rain), +inf when it has none.
double WeatherVisibilityM(const WeatherSpec& spec);

// Applies the image effects of `spec` to `bgr` (modified in place): CV_8UC3, or CV_32FC3 holding
// unrounded grey levels that a camera model rounds afterwards (sim/camera_noise.h).
//  depth_m: CV_32F, same size, the distance along the optical axis (camera z) of each pixel's
//           surface in metres; non-positive, NaN or +inf means sky (nothing within reach).
//  camera: the model that produced `bgr` (intrinsics and distortion are honoured when
//          projecting particles).
//  world_from_cam: the camera pose; camera frame x right, y down, z forward; world z up
//           (gravity along -z: particles fall along -z).
//  t_ns: the image time; particles move with it.
//  seed: selects the particle field (use the same seed for all cameras and frames of a
//        sequence).
// Surface-only kinds (road-*) and intensity 0 leave the image untouched. Throws Error when the
// sizes or types do not match.
void ApplyWeather(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                  const Rigid3d& world_from_cam, int64_t t_ns, const WeatherSpec& spec,
                  uint64_t seed);

// The two halves of ApplyWeather (same arguments and checks), for callers that want one only:
// the haze (fog, dust, rain and snow attenuation, dust contrast loss, rain dimming) and the
// particles.
void ApplyWeatherHaze(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                      const WeatherSpec& spec);
void DrawWeatherParticles(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                          const Rigid3d& world_from_cam, int64_t t_ns, const WeatherSpec& spec,
                          uint64_t seed);

// The part of a scene surface that weather acts on.
enum class SurfaceRole { kRoad, kGround, kRoof, kOther };
// Changes a surface texture image (CV_8UC3) for the weather: rain wets roads and ground,
// road-wetness only roads; snow covers roads, ground and roofs, road-snow only roads; leaves
// fall on roads and ground, road-leaves only on roads. Coverage grows with the intensity;
// intensity 0 or other kinds leave it unchanged.
void ApplySurfaceWeather(cv::Mat& texture_bgr, SurfaceRole role, const WeatherSpec& spec,
                         uint64_t seed);

}  // namespace optinav::sim
