// Camera frames synthesised from an orthophoto, as the orthophoto-navigation thesis (SEEDS.md part
// 3) does (crop around the true position, rotate by the heading, crop larger then centre-crop),
// plus what real flights add: altitude (scale) and camera tilt (perspective). Used by tests,
// benchmarks and missions.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geo/geo.h"
#include "optinav/geo/raster.h"
#include "optinav/maploc/aerial_camera.h"

namespace optinav::maploc {

struct FrameSpec {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // ground point under the frame centre
  double heading_deg = 0;  // frame up direction, clockwise from map up (-y)
  double gsd_m = 1.0;      // metres per frame pixel at the centre
  int width = 640, height = 480;
  double tilt_deg = 0;          // camera pitch away from nadir (perspective)
  double tilt_azimuth_deg = 0;  // direction of the tilt in the frame (0 = towards frame up)
  double focal_px = 0;          // for the perspective of a tilt; 0: from a 60 deg FOV
};

// Renders the frame from the raster (map resolution map_gsd_m); pixels outside the map are 0.
// Returns also the 3x3 homography frame px -> map px when `frame_to_map` is given.
cv::Mat SynthesizeFrame(const geo::GeoRaster& raster, double map_gsd_m, const FrameSpec& spec,
                        cv::Matx33d* frame_to_map = nullptr);

// A true perspective view of the map from a camera at `pose` (attitude convention in
// aerial_camera.h) with the intrinsics of `camera` (distortion ignored: a pinhole view). Pixels
// outside the map are 0. Throws Error when a frame corner sees no ground (the horizon is in
// view). `map_from_image`, when given, receives the image px -> map px homography.
cv::Mat RenderAerialFrame(const geo::GeoRaster& raster, double map_gsd_m, const AerialPose& pose,
                          const camera::PinholeCamera& camera,
                          Eigen::Matrix3d* map_from_image = nullptr);

// What a real camera does to the light after the geometry: optics blur, exposure (gain, gamma),
// sensor noise and JPEG compression. Neutral by default.
struct CameraEffects {
  double gain = 1, gamma = 1, blur_sigma_px = 0, noise_sigma = 0;
  int jpeg_quality = 0;  // 1-100; 0: no compression
};

// Applies the effects to an 8-bit grey frame in that order: Gaussian blur, gain and gamma
// (out = 255 (gain in / 255)^gamma, clipped), Gaussian noise (seeded), JPEG round trip
// (cv::imencode/imdecode). The same input, effects and seed give the same output.
// `jpeg`, when given, receives the encoded bytes (empty without compression): writing them to
// a .jpg file gives exactly the returned image back.
cv::Mat ApplyCameraEffects(const cv::Mat& gray, const CameraEffects& effects, uint64_t seed,
                           std::vector<uchar>* jpeg = nullptr);

// The developers' perspective-frame generator (issue 18's acceptance set): seeded random vehicle
// poses over an orthophoto, true perspective views, camera effects, and the values a flight would
// give locate (with their errors). Defaults are the acceptance set's.
struct PerspectiveFrameOptions {
  int width = 256, height = 256;
  double hfov_deg = 90;
  double altitude_m = 640;  // nominal; each frame's altitude is uniform in the factor range
  double altitude_min_factor = 0.8, altitude_max_factor = 1.25;
  double max_pitch_deg = 15, max_roll_deg = 10;  // uniform in +- these
  double gain_min = 0.7, gain_max = 1.3;
  double gamma_min = 0.8, gamma_max = 1.25;
  double max_blur_sigma_px = 1.2, max_noise_sigma = 5;  // uniform in [0, max]
  int jpeg_quality_min = 55, jpeg_quality_max = 90;     // uniform integer; 0, 0: no JPEG
  // The errors of what locate is given (all uniform): altitude +- fraction, roll and pitch
  // +- degrees, heading +- degrees, and the prior's distance from the truth (uniform over a disk).
  double altitude_error_rel = 0.10;
  double attitude_error_deg = 1.0;
  double heading_error_deg = 10.0;
  double prior_offset_m = 250.0;
  double prior_radius_m = 300.0;
  std::string Check() const;  // "" when valid, else names the field
};

struct PerspectiveFrame {
  cv::Mat image;            // 8-bit grey, width x height
  std::vector<uchar> jpeg;  // its JPEG file (empty when the frame has no compression)
  camera::PinholeCamera camera;
  CameraEffects effects;
  // The truth. `pose` is in the raster's pixels with its yaw relative to the raster's up
  // direction; `heading_deg` is the same yaw clockwise from true north.
  AerialPose pose;
  double heading_deg = 0;
  geo::LatLon latlon;         // the vehicle's nadir point
  Eigen::Vector2d centre_px;  // the image centre's ground point, raster pixels
  geo::LatLon centre_latlon;
  // Image px -> raster px: image pixel centres at integers (as camera::PinholeCamera), raster
  // pixels as GDAL ((0, 0) is the raster's corner).
  Eigen::Matrix3d map_from_image;
  // What locate is given: the prior (`prior_radius_m` from the options), heading (true north,
  // with `heading_sigma_deg` = the options' heading error), altitude and attitude.
  geo::LatLon prior;
  double prior_radius_m = 0;
  double given_heading_deg = 0, heading_sigma_deg = 0;
  double given_altitude_m = 0, given_roll_deg = 0, given_pitch_deg = 0;
};

// `count` frames of the raster, frame i drawn from its own stream of `seed` (so the first k of
// a larger set are the same frames). Vehicles are placed so the whole frame sees the raster
// (a pose whose footprint leaves it is drawn again). Throws Error when the options are invalid
// (field named) or the raster is too small for the footprint.
std::vector<PerspectiveFrame> MakePerspectiveFrames(const geo::GeoRaster& raster, int count,
                                                    const PerspectiveFrameOptions& options,
                                                    uint64_t seed);

// Metres per pixel of a raster at its centre (for rasters in metric or geographic CRSs).
double RasterGsdMetres(const geo::GeoRaster& raster);

// True bearing (degrees clockwise from north) of the raster's up direction (-y) at pixel `px`:
// the yaw of an AerialPose (relative to raster up) plus this is a heading from true north.
double RasterUpBearingDeg(const geo::GeoRaster& raster, const Eigen::Vector2d& px);

}  // namespace optinav::maploc
