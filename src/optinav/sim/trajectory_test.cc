#include "optinav/sim/trajectory.h"

#include <cstdio>

#include <gtest/gtest.h>

#include "optinav/sim/sensors.h"
#include "optinav/util/testing.h"

namespace optinav::sim {
namespace {

constexpr int64_t kStart = 1'700'000'000'000'000'000;

// An aggressive flight: waypoints 9 m apart, 1.5 s each, with climbs, dives and fast yaw.
BodyTrajectory AggressiveFlight() {
  RandomDroneRouteOptions o;
  o.speed_m_s = 6;
  o.segment_s = 1.5;
  o.duration_s = 12;
  o.altitude_m = 10;
  auto wps = RandomDroneWaypoints(
      o, [](double x, double y) { return 0.0; }, 7);
  for (size_t i = 0; i < wps.size(); ++i) {
    wps[i].position_in_world.z() += (i % 2 ? 2.0 : -2.0);
    *wps[i].yaw_rad += (i % 3 ? 0.4 : -0.4);
  }
  return MakeDroneTrajectory(wps, 6.0, kStart);
}

TEST(Spline, InterpolatesAndStartsAtRest) {
  Eigen::MatrixXd s(5, 2);
  s << 0, 0, 1, 2, 3, -1, 4, 0, 2, 5;
  const QuinticSpline spline(s, 0.5);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR((spline.Evaluate(0.5 * i) - s.row(i).transpose()).norm(), 0, 1e-12) << i;
  }
  EXPECT_NEAR(spline.Evaluate(0, 1).norm(), 0, 1e-12);
  EXPECT_NEAR(spline.Evaluate(2.0, 2).norm(), 0, 1e-12);
  // Derivatives agree with finite differences of the lower order, also across knots (C4).
  for (int order = 1; order <= 4; ++order) {
    for (double t : {0.3, 0.5, 0.99, 1.0, 1.7}) {
      const double h = 1e-5;
      const Eigen::VectorXd fd =
          (spline.Evaluate(t + h, order - 1) - spline.Evaluate(t - h, order - 1)) / (2 * h);
      EXPECT_NEAR((fd - spline.Evaluate(t, order)).norm(), 0, 1e-4 * (1 + fd.norm()))
          << "order " << order << " t " << t;
    }
  }
}

// Angular velocity and acceleration of both attitude models agree with finite differences.
void CheckDerivatives(const BodyTrajectory& traj, const char* what) {
  double worst_w = 0, worst_a = 0;
  for (int64_t t = traj.start_ns() + 300'000'000; t < traj.end_ns() - 300'000'000;
       t += 97'000'000) {
    const int64_t h = 10'000;  // 10 us
    const BodyState s = traj.At(t), a = traj.At(t - h), b = traj.At(t + h);
    const Eigen::Vector3d w_fd =
        LogSO3(a.world_from_body.rotation.conjugate() * b.world_from_body.rotation) /
        (2 * h * 1e-9);
    const Eigen::Vector3d a_fd = (b.velocity_in_world - a.velocity_in_world) / (2 * h * 1e-9);
    worst_w = std::max(worst_w, (w_fd - s.angular_velocity_in_body).norm());
    worst_a = std::max(worst_a, (a_fd - s.acceleration_in_world).norm());
  }
  std::printf("%s: worst |omega - finite difference| %.2e rad/s, |a - fd| %.2e m/s^2\n", what,
              worst_w, worst_a);
  EXPECT_LT(worst_w, 1e-5);
  EXPECT_LT(worst_a, 1e-5);
}

TEST(Trajectory, AnalyticDerivativesMatchFiniteDifferences) {
  CheckDerivatives(AggressiveFlight(), "drone");
  const auto hills = [](double x, double y) { return 3 * std::sin(x / 20) * std::cos(y / 25); };
  CheckDerivatives(MakeCarTrajectory(CarRouteOptions::Terrain(), hills, kStart), "car");
}

// Air drag and wind: the angular velocity stays exact (the thrust direction's rate takes the
// drag's), and at a steady velocity the drone leans into its air speed by atan(k |v - w| / g).
TEST(Trajectory, AirDragLeansTheDroneIntoItsAirSpeed) {
  BodyTrajectory drag = AggressiveFlight();
  drag.SetAirDrag(0.1, Eigen::Vector3d(3, -4, 0));
  CheckDerivatives(drag, "drone with drag and wind");
  // The middle of a straight, level 180 m leg east (9.3 m/s there, not accelerating), a 5 m/s
  // wind from the east (towards the west): air speed 14.3 m/s, tilt atan(1.43 / 9.81) = 8.3
  // deg, body z leaning east; without drag it flies level.
  std::vector<DroneWaypoint> wps(4);
  for (int i = 0; i < 4; ++i) wps[i].position_in_world = Eigen::Vector3d(60.0 * i, 0, 10);
  BodyTrajectory leg = MakeDroneTrajectory(wps, 12.0, kStart);
  const int64_t mid = (leg.start_ns() + leg.end_ns()) / 2;
  const Eigen::Vector3d still_z = leg.At(mid).world_from_body.rotation * Eigen::Vector3d::UnitZ();
  leg.SetAirDrag(0.1, Eigen::Vector3d(-5, 0, 0));
  const BodyState s = leg.At(mid);
  const Eigen::Vector3d z = s.world_from_body.rotation * Eigen::Vector3d::UnitZ();
  const double expected =
      std::atan(0.1 * (s.velocity_in_world - Eigen::Vector3d(-5, 0, 0)).norm() / kGravity);
  std::printf(
      "mid-leg at %.2f m/s into a 5 m/s wind: tilt %.3f deg (expected %.3f), %.3f "
      "deg without drag\n",
      s.velocity_in_world.norm(), std::acos(z.z()) * 180 / M_PI, expected * 180 / M_PI,
      std::acos(still_z.z()) * 180 / M_PI);
  EXPECT_NEAR(std::acos(z.z()), expected, 2e-3);
  EXPECT_GT(z.x(), 0.1) << "leans forward, into its air speed";
  EXPECT_LT(std::acos(still_z.z()), 0.01);
}

// Integrates noise-free IMU samples with RK4 (mid-step values by 4-point cubic interpolation)
// from the true initial state and compares with the ground truth.
TEST(Trajectory, IntegratingNoiseFreeImuReproducesGroundTruth) {
  const BodyTrajectory traj = AggressiveFlight();
  ImuOptions opt;
  opt.noise_free = true;
  const auto imu = SimulateImu(traj, opt, 1);
  const double dt = 1.0 / opt.rate_hz;
  const size_t n_steps = static_cast<size_t>(10.0 / dt);  // 10 s
  ASSERT_GT(imu.size(), n_steps + 2);
  BodyState s0 = traj.At(imu[1].t_ns);
  Eigen::Quaterniond q = s0.world_from_body.rotation;
  Eigen::Vector3d v = s0.velocity_in_world, p = s0.world_from_body.translation;
  double max_speed = 0, max_rate = 0, max_acc = 0;
  using State = Eigen::Matrix<double, 10, 1>;
  auto deriv = [](const State& x, const Eigen::Vector3d& w, const Eigen::Vector3d& f) {
    const Eigen::Quaterniond q(x[0], x[1], x[2], x[3]);
    const Eigen::Quaterniond qd = q * Eigen::Quaterniond(0, w.x(), w.y(), w.z());
    State d;
    d.head<4>() << 0.5 * qd.w(), 0.5 * qd.x(), 0.5 * qd.y(), 0.5 * qd.z();
    d.segment<3>(4) = q.normalized() * f - Eigen::Vector3d(0, 0, kGravity);
    d.tail<3>() = x.segment<3>(4);
    return d;
  };
  auto mid = [&](size_t k, auto member) {
    return (-(imu[k - 1].*member) + 9 * (imu[k].*member) + 9 * (imu[k + 1].*member) -
            (imu[k + 2].*member)) /
           16.0;
  };
  for (size_t k = 1; k < n_steps + 1; ++k) {
    State x;
    x << q.w(), q.x(), q.y(), q.z(), v, p;
    const Eigen::Vector3d w0 = imu[k].gyro_rad_s, w2 = imu[k + 1].gyro_rad_s;
    const Eigen::Vector3d f0 = imu[k].accel_m_s2, f2 = imu[k + 1].accel_m_s2;
    const Eigen::Vector3d w1 = mid(k, &ImuMeasurement::gyro_rad_s);
    const Eigen::Vector3d f1 = mid(k, &ImuMeasurement::accel_m_s2);
    const State k1 = deriv(x, w0, f0), k2 = deriv(x + 0.5 * dt * k1, w1, f1),
                k3 = deriv(x + 0.5 * dt * k2, w1, f1), k4 = deriv(x + dt * k3, w2, f2);
    x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    q = Eigen::Quaterniond(x[0], x[1], x[2], x[3]).normalized();
    v = x.segment<3>(4);
    p = x.tail<3>();
    max_speed = std::max(max_speed, v.norm());
    max_rate = std::max(max_rate, w0.norm());
    max_acc = std::max(max_acc, (f0 - q.conjugate() * Eigen::Vector3d(0, 0, kGravity)).norm());
  }
  const BodyState truth = traj.At(imu[n_steps + 1].t_ns);
  const double pos_err = (p - truth.world_from_body.translation).norm();
  const double rot_err = RotationAngle(q.conjugate() * truth.world_from_body.rotation);
  std::printf(
      "10 s of flight (max speed %.1f m/s, max rate %.1f deg/s, max |a| %.1f m/s^2): position "
      "error %.2e m (threshold 1e-2), rotation error %.2e rad\n",
      max_speed, max_rate * 180 / M_PI, max_acc, pos_err, rot_err);
  EXPECT_GT(max_rate, 1.0);  // the motion really is aggressive
  EXPECT_GT(max_acc, 3.0);
  EXPECT_LT(pos_err, 0.01);
  EXPECT_LT(rot_err, 1e-4);
}

TEST(Trajectory, CarRoutesHaveTheWeatherDatasetLengths) {
  const auto flat = [](double, double) { return 0.0; };
  const auto hills = [](double x, double y) { return 4 * std::sin(x / 30) * std::cos(y / 40); };
  const BodyTrajectory urban = MakeCarTrajectory(CarRouteOptions::Urban(), flat, kStart);
  const BodyTrajectory terrain = MakeCarTrajectory(CarRouteOptions::Terrain(), hills, kStart);
  const double lu = urban.PathLength(), lt = terrain.PathLength();
  std::printf("car route: urban %.1f m in %.1f s (document 745 m), terrain %.1f m (875 m)\n", lu,
              (urban.end_ns() - kStart) * 1e-9, lt);
  EXPECT_NEAR(lu, 745, 40);
  EXPECT_NEAR(lt, 875, 45);
  // It ends near the start, facing the start direction (north, ENU yaw pi/2), at rest.
  const BodyState end = urban.At(urban.end_ns());
  EXPECT_LT(end.world_from_body.translation.head<2>().norm(), 30);
  EXPECT_LT(end.velocity_in_world.norm(), 1e-9);
  const BodyState start = urban.At(kStart);
  EXPECT_LT(
      RotationAngle(start.world_from_body.rotation * ExpSO3(Eigen::Vector3d(0, 0, -M_PI / 2))),
      1e-9);
  ASSERT_TRUE(urban.ControlsAt(kStart + 5'000'000'000).has_value());
  EXPECT_DOUBLE_EQ(urban.ControlsAt(kStart + 5'000'000'000)->throttle, 0.7);
}

TEST(Sensors, GnssNoiseOutliersAndOutages) {
  const BodyTrajectory traj = AggressiveFlight();
  GnssOptions o;
  o.rate_hz = 10;
  o.sigma_m = 0.5;
  o.outlier_fraction = 0.1;
  o.outlier_magnitude_m = 30;
  o.outages = {{2.0, 3.0}};
  ASSERT_EQ(o.Check(), "");
  const auto gnss = SimulateGnss(traj, o, 3);
  const geo::LocalEnu enu(o.origin, o.origin_height_m);
  int outliers = 0, in_outage = 0;
  double sq = 0;
  int n = 0;
  for (const auto& g : gnss) {
    const double t = (g.t_ns - traj.start_ns()) * 1e-9;
    in_outage += t >= 2.0 && t < 5.0;
    const Eigen::Vector3d truth = traj.At(g.t_ns).world_from_body * o.lever_arm_in_body;
    const double err = (g.position_enu_m - truth).norm();
    if (g.outlier) {
      ++outliers;
      EXPECT_GT(err, 20);
    } else {
      sq += err * err;
      ++n;
    }
    EXPECT_LT((enu.ToEnu({g.lat_deg, g.lon_deg}, g.height_m) - g.position_enu_m).norm(), 1e-4);
  }
  const double rms_per_axis = std::sqrt(sq / n / 3);
  std::printf("gnss: %zu samples, %d outliers, rms per axis %.3f m (sigma 0.5)\n", gnss.size(),
              outliers, rms_per_axis);
  EXPECT_EQ(in_outage, 0);
  EXPECT_GT(outliers, 3);
  EXPECT_NEAR(rms_per_axis, 0.5, 0.1);
  EXPECT_ERROR(ParseOutlierSpec("0.1", "--gnss-outliers"), {.field = "--gnss-outliers"},
               "expected FRACTION:MAGNITUDE_M, e.g. 0.05:20, got '0.1'");
  EXPECT_ERROR(ParseOutageSpec("a:3", "--gnss-outage"), {.field = "--gnss-outage"},
               "expected START_S:DURATION_S, e.g. 30:10, got 'a:3'");
  EXPECT_EQ(ParseOutageSpec("30:10", "x").duration_s, 10);
}

TEST(Sensors, ImuNoiseMatchesTheDensities) {
  const BodyTrajectory traj = AggressiveFlight();
  ImuOptions noisy, exact;
  exact.noise_free = true;
  const auto a = SimulateImu(traj, noisy, 5), b = SimulateImu(traj, exact, 5);
  ASSERT_EQ(a.size(), b.size());
  double sq = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sq += (a[i].gyro_rad_s - b[i].gyro_rad_s - a[i].gyro_bias).squaredNorm();
  }
  const double sigma = std::sqrt(sq / a.size() / 3);
  const double expected = noisy.gyroscope_noise_density * std::sqrt(noisy.rate_hz);
  std::printf("gyro white noise %.3e rad/s (expected %.3e)\n", sigma, expected);
  EXPECT_NEAR(sigma, expected, 0.1 * expected);
}

}  // namespace
}  // namespace optinav::sim
