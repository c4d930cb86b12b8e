// One simulated sequence, end to end: world, route, sensors, rendering, weather, and a dataset
// on disk in EuRoC/ASL or AirSim format (docs/FORMATS.md); optionally a nadir mapping camera
// (mav0/cam2) and a barometer (mav0/baro0), in the EuRoC layout in both formats (AirSim: cam2/
// and baro0/ at the top of the folder).
//
// Output safety: the output folder must not exist or be empty (unless `force`, which clears
// it); images are written as frames are rendered, every text file is written atomically after
// the last frame, and `sim_complete.json` (options and counts) is written last of all: a
// folder without it is an interrupted run. The same options and seed give byte-identical
// files.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "optinav/sim/camera_noise.h"
#include "optinav/sim/rig.h"
#include "optinav/sim/sensors.h"
#include "optinav/sim/weather.h"
#include "optinav/sim/world.h"

namespace optinav::sim {

enum class DatasetFormat { kEuroc, kAirsim };

struct SimulationOptions {
  WorldOptions world;         // kind, ortho path, seed (set from `seed`), weather (from below)
  WeatherSpec weather;        // image and surface effects
  std::string route = "car";  // "car", "drone" or "drone:FILE" (io/waypoints.h)
  double duration_s = 0;      // 0: the whole car route, 60 s for drones
  DatasetFormat format = DatasetFormat::kEuroc;
  uint64_t seed = 1;
  std::string out_dir;
  double speed_m_s = 5.0;    // drone routes
  double altitude_m = 20.0;  // drone routes, above ground
  // Drone routes: air drag (1/s; 0: none) and a steady wind (m/s, east and north): the drone
  // leans into its air speed (BodyTrajectory::SetAirDrag). 0.1 and 4 m/s tilt a drone flying
  // 25 m/s into the wind by 16 deg.
  double drag_per_s = 0.0;
  Eigen::Vector2d wind_m_s = Eigen::Vector2d::Zero();
  double scale = 1.0;  // image size factor (intrinsics follow)
  bool force = false;  // clear a non-empty out_dir
  ImuOptions imu;
  GnssOptions gnss;
  BaroOptions baro;              // baro0/ when enabled
  NadirCameraOptions nadir;      // cam2/ when enabled (its own size: `scale` does not apply)
  std::optional<SensorRig> rig;  // default: CarRig() for car routes, DroneRig() for drones
  int png_compression = 1;       // 0-9; 1 is fast and still compresses well
  // The cameras' noise and 8-bit rounding (sim/camera_noise.h), on every camera; recorded in
  // the completion marker.
  CameraNoiseOptions camera_noise;

  // Empty when valid, else a message naming the offending option and value.
  std::string Check() const;
};

struct SimulationSummary {
  size_t frames = 0, imu_samples = 0, gnss_samples = 0;
  size_t nadir_frames = 0, baro_samples = 0;
  double duration_s = 0, path_length_m = 0;
  double wall_s = 0;
  size_t world_triangles = 0;
  int width = 0, height = 0;  // image size
};

// The renderer's version, written to the completion marker (sim_complete.json "renderer"):
// rendering code changes that change the images bump it, so that the benchmarks' --reuse renders
// older sequences again. 1 (markers without the key): nearest-mip-level texture sampling;
// 2 (2026-12-05): trilinear sampling.
inline constexpr int kRendererVersion = 2;

// Whether `dir` holds a finished rendering of `options` by this renderer version: its
// sim_complete.json names the same world (and orthophoto), route, weather, frozen particles or
// not, asphalt (a marker without the key is tiled), camera noise (without the key: none), seed,
// format, scale, requested duration and, on drone routes, speed, altitude, drag and wind. The
// sensors' options (IMU, GNSS, baro, nadir camera, rig) are not compared. When it does not, `why`
// (if given) names the first difference. The benchmarks' --reuse keeps a sequence only when this
// holds.
bool IsRenderingOf(const std::string& dir, const SimulationOptions& options,
                   std::string* why = nullptr);

// Runs the simulation. `progress(done, total)` is called after each stereo frame. Throws Error
// for bad input (unknown route file, unusable orthophoto, output folder not empty, write
// failures), leaving no completion marker.
SimulationSummary RunSimulation(const SimulationOptions& options,
                                const std::function<void(size_t, size_t)>& progress = {});

class Renderer;
// One stereo pair with weather at body pose `world_from_body` and time t_ns: the two cameras
// render (and get their weather) concurrently.
void RenderStereo(const Renderer& renderer, const SensorRig& rig, const Rigid3d& world_from_body,
                  int64_t t_ns, const WeatherSpec& weather, uint64_t seed,
                  const CameraNoiseOptions& noise, cv::Mat* left, cv::Mat* right);

// One nadir frame with weather (the camera at body_from_cam of `nadir`: NadirCameraMount()).
cv::Mat RenderNadir(const Renderer& renderer, const NadirCameraOptions& nadir,
                    const Rigid3d& world_from_body, int64_t t_ns, const WeatherSpec& weather,
                    uint64_t seed, const CameraNoiseOptions& noise);

// The weather document's 36 sequences: for `urban` and `terrain`, default, rain, snow, leaves
// (at 50 %), fog and dust at 25/50/75/100 %, and for urban also road wetness/snow/leaves at
// 25/50/75/100 %. Names like "urban_fog_50".
struct SuiteEntry {
  std::string name;
  WorldKind world;
  WeatherSpec weather;
};
std::vector<SuiteEntry> WeatherSuite();

}  // namespace optinav::sim
