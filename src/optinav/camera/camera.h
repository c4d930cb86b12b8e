// Pinhole cameras with radial-tangential or equidistant distortion, and stereo rigs.
//
// Conventions: the camera frame has x right, y down, z forward (optical axis). "Normalized"
// coordinates are (x/z, y/z) of an undistorted ray; "pixel" coordinates are what the image holds
// (distorted when the camera has distortion), with (0, 0) the centre of the top-left pixel.
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "optinav/geometry/lie.h"

namespace optinav::camera {

enum class DistortionModel { kNone, kRadialTangential, kEquidistant };

// "none", "radial-tangential" (also "radtan"), "equidistant" (also "equi", "fisheye").
// Throws Error on anything else.
DistortionModel ParseDistortionModel(const std::string& name);
std::string DistortionModelName(DistortionModel model);

struct PinholeCamera {
  int width = 0, height = 0;              // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  DistortionModel distortion = DistortionModel::kNone;
  // radial-tangential: k1 k2 p1 p2 (Kalibr/OpenCV order); equidistant: k1 k2 k3 k4
  // (Kannala-Brandt).
  std::array<double, 4> coeffs{0, 0, 0, 0};

  // A distortion-free camera with the principal point at the image centre and the given
  // horizontal field of view (radians).
  static PinholeCamera FromHorizontalFov(int width, int height, double hfov_rad);

  // Throws Error when the size or focal lengths are not positive/finite; its field names the
  // sensor.yaml key to fix (resolution, intrinsics, distortion_coefficients).
  void Validate() const;

  Eigen::Matrix3d K() const;
  // The same camera for an image resized by `factor` (both axes).
  PinholeCamera Scaled(double factor) const;

  // Normalized undistorted -> normalized distorted and back (the inverse is iterative,
  // converging to ~1e-12 inside the image for the usual coefficient ranges).
  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted_normalized) const;

  // Pixel of a point in the camera frame; nullopt behind (or too close to) the camera.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_in_cam) const;
  // Pixel of normalized undistorted coordinates.
  Eigen::Vector2d NormalizedToPixel(const Eigen::Vector2d& normalized) const;
  // Normalized undistorted coordinates of a pixel (removes distortion).
  Eigen::Vector2d PixelToNormalized(const Eigen::Vector2d& pixel) const;
  // Ray (x, y, 1) in the camera frame through a pixel.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;

  bool InImage(const Eigen::Vector2d& pixel, double border = 0.0) const;
};

// Two cameras; `right_from_left` maps left-camera points into the right camera frame.
struct StereoRig {
  PinholeCamera left, right;
  Rigid3d right_from_left;

  double Baseline() const { return right_from_left.translation.norm(); }
  // Essential matrix E = [t]x R of right_from_left: x_r^T E x_l = 0 for normalized points.
  Eigen::Matrix3d Essential() const;
};

// Distance of the right point to the epipolar line of the left one, in normalized units
// (x pixels: the focal length); infinity when the line is undefined.
double EpipolarDistance(const Eigen::Matrix3d& essential, const Eigen::Vector2d& left_normalized,
                        const Eigen::Vector2d& right_normalized);

// Linear (DLT) triangulation of one point seen in two views with known poses
// (cam_from_world for each), from normalized undistorted coordinates. Returns the point in the
// world frame; nullopt when the rays are (nearly) parallel or the point is behind a camera.
std::optional<Eigen::Vector3d> TriangulateTwoView(const Rigid3d& cam1_from_world,
                                                  const Rigid3d& cam2_from_world,
                                                  const Eigen::Vector2d& normalized1,
                                                  const Eigen::Vector2d& normalized2);

}  // namespace optinav::camera
