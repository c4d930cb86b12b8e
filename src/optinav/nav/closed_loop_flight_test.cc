#include "optinav/nav/internal/closed_loop_flight.h"

#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "optinav/nav/map_aided_nav.h"

namespace optinav::nav {
namespace {

Eigen::Matrix3d Exp(const Eigen::Vector3d& w) {
  const double a = w.norm();
  return a > 0 ? Eigen::AngleAxisd(a, w / a).toRotationMatrix() : Eigen::Matrix3d::Identity();
}

// The IMU of the true vehicle (exact, 200 Hz) integrated by a strapdown mechanisation lands where
// the vehicle is: the frames rendered at its positions and the IMU tell the same story. Turns,
// climbs, gusts and wind all on; the command changes every 0.2 s as guidance does.
TEST(ClosedLoopFlight, ImuIntegratesToTheTrajectory) {
  FlightModelOptions o;
  o.air_speed_m_s = 25;
  o.altitude_m = 500;
  o.altitude_variation = 0.1;
  o.gust_tilt_deg = 8;
  o.wind_m_s = {4, -3};
  o.seed = 7;
  ClosedLoopFlight flight(o, {100, -50}, 30);
  const int64_t dt_ns = 5'000'000;
  const double dt = 5e-3;
  sim::BodyState s = flight.State();
  Eigen::Matrix3d r = s.world_from_body.rotation.toRotationMatrix();
  Eigen::Vector3d p = s.world_from_body.translation, v = s.velocity_in_world;
  const Eigen::Vector3d g(0, 0, -sim::kGravity);
  double max_bank = 0;
  for (int k = 1; k <= 30 * 200; ++k) {
    if (k % 40 == 0) flight.Command(0.2 * std::sin(k * 1e-3));  // up to the bank limit
    // Trapezoid on the measurements at both ends of the step (what the IMU would give).
    const Eigen::Vector3d w0 = s.angular_velocity_in_body;
    const Eigen::Vector3d f0 =
        s.world_from_body.rotation.conjugate() * (s.acceleration_in_world - g);
    flight.AdvanceTo(k * dt_ns);
    s = flight.State();
    const Eigen::Vector3d w1 = s.angular_velocity_in_body;
    const Eigen::Vector3d f1 =
        s.world_from_body.rotation.conjugate() * (s.acceleration_in_world - g);
    const Eigen::Matrix3d r1 = r * Exp(0.5 * (w0 + w1) * dt);
    const Eigen::Vector3d a = 0.5 * (r * f0 + r1 * f1) + g;
    p += v * dt + 0.5 * a * dt * dt;
    v += a * dt;
    r = r1;
    double roll, pitch, heading;
    AttitudeOfEnuFromBody(s.world_from_body.rotation.toRotationMatrix(), &roll, &pitch, &heading);
    max_bank = std::max(max_bank, std::abs(roll));
  }
  const double dp = (p - s.world_from_body.translation).norm();
  const double dr =
      Eigen::AngleAxisd(r.transpose() * s.world_from_body.rotation.toRotationMatrix()).angle() *
      180 / M_PI;
  std::printf("30 s of flight: strapdown vs truth %.3f m, %.4f deg; max |roll| %.1f deg\n", dp, dr,
              max_bank);
  EXPECT_LT(dp, 0.5);
  EXPECT_LT(dr, 0.02);
  EXPECT_LE(max_bank, 20.0 + 8.0 + 1e-9);  // the bank limit plus gusts
  EXPECT_GT(max_bank, 15.0);               // the commands did saturate the turn rate
}

TEST(ClosedLoopFlight, TurnRateFollowsTheCommandWithItsLag) {
  FlightModelOptions o;
  o.air_speed_m_s = 30;
  ClosedLoopFlight flight(o, {0, 0}, 0);
  flight.Command(0.05);
  flight.AdvanceTo(1'000'000'000);  // one time constant
  // The turn rate is the angular velocity about the world's up axis (clockwise: about -z); the
  // command ramps in over 0.2 s, then the lag.
  const sim::BodyState s1 = flight.State();
  const double turn = -(s1.world_from_body.rotation * s1.angular_velocity_in_body).z();
  EXPECT_NEAR(turn, 0.05 * (1 - std::exp(-0.9)), 3e-3);
  flight.AdvanceTo(10'000'000'000);
  // A coordinated turn: bank atan(V r / g), heading clockwise (to the right wing).
  double roll, pitch, heading;
  AttitudeOfEnuFromBody(flight.State().world_from_body.rotation.toRotationMatrix(), &roll, &pitch,
                        &heading);
  EXPECT_NEAR(roll, std::atan(30 * 0.05 / sim::kGravity) * 180 / M_PI, 0.05);
  EXPECT_NEAR(heading, flight.heading_deg(), 1e-6);
  EXPECT_GT(heading, 10.0);
  EXPECT_LT(heading, 180.0);
  flight.Command(10.0);  // clamped
  flight.AdvanceTo(30'000'000'000);
  EXPECT_NEAR(flight.State().velocity_in_world.head<2>().norm(), 30, 1e-6);
  AttitudeOfEnuFromBody(flight.State().world_from_body.rotation.toRotationMatrix(), &roll, &pitch,
                        &heading);
  EXPECT_NEAR(roll, o.max_bank_deg, 0.01);
}

}  // namespace
}  // namespace optinav::nav
