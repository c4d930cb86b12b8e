// Test helper: a smooth analytic body trajectory with exact IMU readings (angular velocity in
// the body frame, specific force in the body frame), for preintegration and backend tests.
#pragma once

#include <cmath>

#include "optinav/geometry/lie.h"
#include "optinav/vio/imu_preintegration.h"

namespace optinav::vio {

// Position on a wavy circle; attitude R = Rz(yaw) Ry(pitch) Rx(roll) with smooth angles.
struct AnalyticTrajectory {
  double radius_m = 2.0, omega = 0.5, height_m = 1.2, bob_m = 0.3;
  double yaw0 = 0.3, yaw_amp = 0.6, pitch_amp = 0.15, roll_amp = 0.1;
  double yaw_rate = 0.0;  // a steady turn added to the yaw (rad/s)

  // A car on a flat circle: level, heading along the velocity (body x forward, no side-slip);
  // `yaw_offset` turns the body x axis that far left of the velocity.
  static AnalyticTrajectory Car(double yaw_offset = 0.0) {
    AnalyticTrajectory c;
    c.bob_m = 0, c.pitch_amp = 0, c.roll_amp = 0, c.yaw_amp = 0;
    c.yaw0 = M_PI / 2 + yaw_offset;
    c.yaw_rate = c.omega;
    return c;
  }

  Eigen::Vector3d Position(double t) const {
    return {radius_m * std::cos(omega * t), radius_m * std::sin(omega * t),
            height_m + bob_m * std::sin(0.7 * t)};
  }
  Eigen::Vector3d Velocity(double t) const {
    return {-radius_m * omega * std::sin(omega * t), radius_m * omega * std::cos(omega * t),
            0.7 * bob_m * std::cos(0.7 * t)};
  }
  Eigen::Vector3d Acceleration(double t) const {
    return {-radius_m * omega * omega * std::cos(omega * t),
            -radius_m * omega * omega * std::sin(omega * t), -0.49 * bob_m * std::sin(0.7 * t)};
  }
  // Euler angles and their rates.
  Eigen::Vector3d Angles(double t) const {  // yaw, pitch, roll
    return {yaw0 + yaw_rate * t + yaw_amp * std::sin(0.4 * t), pitch_amp * std::sin(0.9 * t),
            roll_amp * std::sin(1.3 * t)};
  }
  Eigen::Vector3d AngleRates(double t) const {
    return {yaw_rate + 0.4 * yaw_amp * std::cos(0.4 * t), 0.9 * pitch_amp * std::cos(0.9 * t),
            1.3 * roll_amp * std::cos(1.3 * t)};
  }
  Eigen::Quaterniond Rotation(double t) const {
    const Eigen::Vector3d a = Angles(t);
    return Eigen::Quaterniond(Eigen::AngleAxisd(a[0], Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(a[1], Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(a[2], Eigen::Vector3d::UnitX()));
  }
  // Body angular velocity: Rx^T Ry^T yaw' e_z + Rx^T pitch' e_y + roll' e_x.
  Eigen::Vector3d GyroAt(double t) const {
    const Eigen::Vector3d a = Angles(t), d = AngleRates(t);
    const Eigen::Matrix3d rx = Eigen::AngleAxisd(a[2], Eigen::Vector3d::UnitX()).matrix();
    const Eigen::Matrix3d ry = Eigen::AngleAxisd(a[1], Eigen::Vector3d::UnitY()).matrix();
    return rx.transpose() * ry.transpose() * Eigen::Vector3d(0, 0, d[0]) +
           rx.transpose() * Eigen::Vector3d(0, d[1], 0) + Eigen::Vector3d(d[2], 0, 0);
  }
  // Specific force in the body frame: R^T (a - g).
  Eigen::Vector3d AccelAt(double t) const {
    return Rotation(t).conjugate() * (Acceleration(t) - GravityInWorld());
  }
  NavState StateAt(double t) const {
    NavState s;
    s.world_from_body_rotation = Rotation(t);
    s.position = Position(t);
    s.velocity = Velocity(t);
    return s;
  }
  Rigid3d Pose(double t) const { return {Rotation(t), Position(t)}; }
};

}  // namespace optinav::vio
