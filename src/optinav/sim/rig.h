// Sensor rigs: two cameras on a body (the IMU frame: x forward, y left, z up).
#pragma once

#include <cmath>

#include <Eigen/Geometry>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"

namespace optinav::sim {

struct SensorRig {
  camera::PinholeCamera left, right;
  Rigid3d body_from_left, body_from_right;
  double camera_rate_hz = 20.0;

  camera::StereoRig Stereo() const {
    return {left, right, body_from_right.Inverse() * body_from_left};
  }
  // Both images resized by `factor` (intrinsics scaled with them).
  SensorRig Scaled(double factor) const {
    SensorRig r = *this;
    r.left = left.Scaled(factor);
    r.right = right.Scaled(factor);
    return r;
  }
};

// body_from_cam for a camera looking along body x, pitched down by `down_rad`, at `position`.
inline Rigid3d ForwardCamera(const Eigen::Vector3d& position, double down_rad) {
  Eigen::Matrix3d r;  // columns: camera x (right), y (down), z (forward) in the body frame
  r << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Quaterniond pitch(Eigen::AngleAxisd(down_rad, Eigen::Vector3d::UnitY()));
  return Rigid3d((pitch * Eigen::Quaterniond(r)).normalized(), position);
}

// The car rig of the AirSim weather dataset (SEEDS.md part 1): two 800x600 cameras, 90 deg
// horizontal field of view, no distortion, 0.52 m baseline, 1.9 m above the road (the body frame
// sits on the road), a stereo pair every 30 ms.
inline SensorRig CarRig() {
  SensorRig r;
  r.left = r.right = camera::PinholeCamera::FromHorizontalFov(800, 600, M_PI / 2);
  r.body_from_left = ForwardCamera({0, 0.26, 1.9}, 0);
  r.body_from_right = ForwardCamera({0, -0.26, 1.9}, 0);
  r.camera_rate_hz = 1.0 / 0.03;
  return r;
}

// A EuRoC-like drone rig: 752x480, EuRoC cam0 focal length (458.65 px, ~79 deg), 0.11 m
// baseline, looking forward and 30 deg down, 20 Hz.
inline SensorRig DroneRig() {
  SensorRig r;
  camera::PinholeCamera c;
  c.width = 752;
  c.height = 480;
  c.fx = c.fy = 458.65;
  c.cx = 375.5;
  c.cy = 239.5;
  r.left = r.right = c;
  r.body_from_left = ForwardCamera({0.05, 0.055, 0}, 30 * M_PI / 180);
  r.body_from_right = ForwardCamera({0.05, -0.055, 0}, 30 * M_PI / 180);
  r.camera_rate_hz = 20.0;
  return r;
}

// The nadir mapping camera (`mav0/cam2`), mounted as the attitude convention of docs/FORMATS.md
// has it: looking straight down the body's -z, the image top towards the nose (body x), the image
// right towards the right wing (body -y). Centred on the IMU.
inline Rigid3d NadirCameraMount() {
  Eigen::Matrix3d r;  // columns: camera x (right), y (down in the image), z (optical axis)
  r << 0, -1, 0, -1, 0, 0, 0, 0, -1;
  return Rigid3d(Eigen::Quaterniond(r).normalized(), Eigen::Vector3d::Zero());
}

struct NadirCameraOptions {
  bool enabled = false;  // `optinav sim` turns it on for drone routes
  int width = 640, height = 480;
  double hfov_deg = 90;
  double rate_hz = 5;
  camera::PinholeCamera Camera() const {
    return camera::PinholeCamera::FromHorizontalFov(width, height, hfov_deg * M_PI / 180);
  }
};

}  // namespace optinav::sim
