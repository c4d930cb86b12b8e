// Closed-form visual-inertial alignment for the in-motion initialisation.
//
// Input: a short run of stereo visual odometry (body poses in the odometry's own frame "vo",
// metric thanks to the stereo baseline but with an unknown direction of gravity) and the IMU
// preintegrated between consecutive poses. Output: the gyroscope bias, the gravity vector in the
// vo frame and the velocity at every pose, from two linear least-squares problems:
//   1. gyro bias: R_k^T R_k+1 = dR_k(bg)  ->  dR_dbg_k * d_bg = Log(dR_k^T R_k^T R_k+1), twice,
//      re-integrating at the new bias in between;
//   2. velocities and gravity, with the accelerometer bias held at its prior value:
//        p_k+1 - p_k = v_k dt + 1/2 g dt^2 + R_k dp_k
//        v_k+1 - v_k = g dt + R_k dv_k
//      each row whitened by its noise (odometry position noise, preintegration covariance plus
//      the accelerometer-bias prior), solved once freely and then three times with |g| fixed to
//      9.81 m/s^2 (two tangent parameters of the gravity direction).
// The stereo baseline fixes the scale, so unlike a monocular alignment there is no scale unknown.
// world_from_vo is the smallest rotation taking the estimated gravity to -z (yaw is the caller's
// gauge choice).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "optinav/geometry/lie.h"
#include "optinav/vio/imu_preintegration.h"

namespace optinav::vio {

struct ViAlignmentOptions {
  double position_sigma_m = 0.01;  // noise of the odometry position of each pose
  double accel_bias_sigma = 0.05;  // m/s^2, prior on the accelerometer bias (held fixed)
  // The unconstrained gravity norm must be within this fraction of 9.81 m/s^2.
  double max_gravity_norm_error = 0.1;
  // Whitened residual RMS of the final solve above which the alignment is rejected (the
  // odometry and the IMU disagree: a wrong track, a bad pose, a wrong calibration).
  double max_whitened_rms = 3.0;
  double max_whitened_residual = 8.0;  // largest single whitened residual
};

struct ViAlignmentResult {
  bool ok = false;
  std::string failure;  // why not ok
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_vo = Eigen::Vector3d::Zero();  // norm 9.81 when ok
  std::vector<Eigen::Vector3d> velocities_vo;            // one per pose
  Eigen::Quaterniond world_from_vo = Eigen::Quaterniond::Identity();
  // Diagnostics.
  double unconstrained_gravity_norm = 0;
  double whitened_rms = 0;  // of the final velocity/gravity solve
  double max_whitened_residual = 0;
  double position_rms_m = 0;  // unwhitened position-row residual RMS
  // Standard deviation of the gravity direction (rad), from the final solve's covariance.
  double tilt_sigma_rad = 0;
  double first_velocity_sigma_m_s = 0;  // of the first pose's velocity, per axis
};

// `vo_from_body[k]` at time `t_ns[k]` (strictly increasing), `preintegrations[k]` from pose k to
// k+1 (so one fewer), all at the same linearisation bias (its accelerometer part is the prior
// kept fixed). At least 3 poses.
ViAlignmentResult SolveViAlignment(const std::vector<int64_t>& t_ns,
                                   const std::vector<Rigid3d>& vo_from_body,
                                   std::vector<ImuPreintegration> preintegrations,
                                   const ViAlignmentOptions& options = {});

}  // namespace optinav::vio
