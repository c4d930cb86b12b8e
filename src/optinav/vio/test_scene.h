// Test helper: feature-level synthetic stereo-inertial data. Landmarks on the walls, floor and
// ceiling of a room, observed by a forward-looking stereo rig riding the analytic trajectory,
// with Gaussian pixel noise and an IMU with white noise and constant biases (fixed seeds).
#pragma once

#include <random>
#include <vector>

#include "optinav/vio/backend.h"
#include "optinav/vio/test_trajectory.h"

namespace optinav::vio {

struct SyntheticFrame {
  int64_t t_ns = 0;
  std::vector<StereoObservation> observations;
  std::vector<TimedImuSample> imu;  // samples in (previous frame, this frame]
};

struct SyntheticScene {
  AnalyticTrajectory trajectory;
  RigExtrinsics rig;
  std::vector<Eigen::Vector3d> landmarks;
  double fx = 458.0, cx = 376.0, cy = 240.0;
  int width = 752, height = 480;
  ImuNoise noise;
  ImuBias true_bias;

  SyntheticScene() {
    // Forward-looking rig: camera z = body x, camera x = -body y, camera y = -body z.
    Eigen::Matrix3d body_from_cam;
    body_from_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    const Rigid3d body_from_cam0(Eigen::Quaterniond(body_from_cam), {0.05, 0.055, 0.0});
    const Rigid3d body_from_cam1(Eigen::Quaterniond(body_from_cam), {0.05, -0.055, 0.0});
    rig.cam0_from_body = body_from_cam0.Inverse();
    rig.cam1_from_body = body_from_cam1.Inverse();
    rig.focal_px = fx;
    true_bias.gyro = {0.003, -0.002, 0.004};
    true_bias.accel = {0.04, -0.03, 0.05};
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // Room [-6, 6] x [-6, 6] x [-0.5, 4].
    for (int i = 0; i < 1600; ++i) {
      const int face = i % 6;
      const double a = u(rng), b = u(rng);
      Eigen::Vector3d p;
      if (face == 0) p = {-6, -6 + 12 * a, -0.5 + 4.5 * b};
      if (face == 1) p = {6, -6 + 12 * a, -0.5 + 4.5 * b};
      if (face == 2) p = {-6 + 12 * a, -6, -0.5 + 4.5 * b};
      if (face == 3) p = {-6 + 12 * a, 6, -0.5 + 4.5 * b};
      if (face == 4) p = {-6 + 12 * a, -6 + 12 * b, -0.5};
      if (face == 5) p = {-6 + 12 * a, -6 + 12 * b, 4.0};
      landmarks.push_back(p);
    }
  }

  std::optional<Eigen::Vector2d> Observe(const Rigid3d& cam_from_world,
                                         const Eigen::Vector3d& p_world) const {
    const Eigen::Vector3d p = cam_from_world * p_world;
    if (p.z() < 0.3) return std::nullopt;
    const Eigen::Vector2d n = p.head<2>() / p.z();
    const double u = fx * n.x() + cx, v = fx * n.y() + cy;
    if (u < 0 || v < 0 || u > width - 1 || v > height - 1) return std::nullopt;
    return n;
  }

  // Frames at `rate_hz` over [0, duration_s] with IMU at 200 Hz.
  std::vector<SyntheticFrame> Generate(double duration_s, double rate_hz, double pixel_sigma,
                                       bool imu_noise, unsigned seed,
                                       int max_features = 150) const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    std::vector<SyntheticFrame> frames;
    const int64_t frame_dt_ns = static_cast<int64_t>(1e9 / rate_hz);
    const int64_t imu_dt_ns = 5'000'000;
    Eigen::Vector3d bg = true_bias.gyro, ba = true_bias.accel;
    int64_t imu_t = 0;
    for (int64_t t_ns = 0; t_ns <= static_cast<int64_t>(duration_s * 1e9); t_ns += frame_dt_ns) {
      SyntheticFrame frame;
      frame.t_ns = t_ns;
      for (; imu_t <= t_ns; imu_t += imu_dt_ns) {
        const double t = imu_t * 1e-9;
        TimedImuSample s;
        s.t_ns = imu_t;
        s.gyro = trajectory.GyroAt(t) + bg;
        s.accel = trajectory.AccelAt(t) + ba;
        if (imu_noise) {
          const double sg = noise.gyro_noise_density / std::sqrt(imu_dt_ns * 1e-9);
          const double sa = noise.accel_noise_density / std::sqrt(imu_dt_ns * 1e-9);
          s.gyro += sg * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
          s.accel += sa * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
        }
        frame.imu.push_back(s);
      }
      const Rigid3d body_from_world = trajectory.Pose(t_ns * 1e-9).Inverse();
      const Rigid3d cam0_from_world = rig.cam0_from_body * body_from_world;
      const Rigid3d cam1_from_world = rig.cam1_from_body * body_from_world;
      for (size_t id = 0; id < landmarks.size(); ++id) {
        auto left = Observe(cam0_from_world, landmarks[id]);
        if (!left) continue;
        StereoObservation obs;
        obs.track_id = id + 1;
        const double noise_n = pixel_sigma / fx;
        obs.left = *left + noise_n * Eigen::Vector2d(normal(rng), normal(rng));
        if (auto right = Observe(cam1_from_world, landmarks[id]))
          obs.right = *right + noise_n * Eigen::Vector2d(normal(rng), normal(rng));
        frame.observations.push_back(obs);
      }
      // Keep the lowest ids: stable tracks, as a tracker keeps features until they leave.
      if (static_cast<int>(frame.observations.size()) > max_features)
        frame.observations.resize(max_features);
      frames.push_back(std::move(frame));
    }
    return frames;
  }
};

}  // namespace optinav::vio
