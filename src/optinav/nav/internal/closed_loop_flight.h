// The true vehicle of a closed-loop mission flown with the map-aided navigator (`optinav mission
// --estimator nav`): a vehicle at constant air speed turning at a commanded rate (ramped in over
// command_ramp_s, then a first-order lag, so the roll rate is continuous; the bank of a coordinated
// turn limited to max_bank_deg), pushed by a constant wind, with a smooth altitude profile and
// smooth gust roll/pitch. Its states have the derivatives the IMU sees (sim::ImuSensor): velocity
// and acceleration in closed form, the angular velocity from the attitude's derivative; the
// position is the integral of the velocity (Simpson's rule on 1 ms steps), so the IMU and the
// rendered frames agree to well below the sensors' noise.
//
// World: ENU about the mission's start (metres), z = height above the map plane. Body: x nose,
// y left, z up (the IMU frame of sim/trajectory.h).
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "optinav/nav/frame_effects.h"
#include "optinav/sim/trajectory.h"

namespace optinav::nav {

struct FlightModelOptions {
  double air_speed_m_s = 30;
  double altitude_m = 640;         // mean height above the map plane
  double altitude_variation = 0;   // +- fraction (AltitudeProfile)
  double max_bank_deg = 20;        // limits the turn rate: g tan(bank) / speed
  double turn_lag_s = 1.0;         // the turn rate follows the command with this time constant
  double command_ramp_s = 0.2;     // a new command is reached over this time (no roll-rate step)
  double gust_tilt_deg = 0;        // smooth gust roll and pitch, each within +- this
  Eigen::Vector2d wind_m_s{0, 0};  // east, north
  uint64_t seed = 1;
};

class ClosedLoopFlight {
 public:
  ClosedLoopFlight(const FlightModelOptions& options, const Eigen::Vector2d& start_xy,
                   double heading_deg);

  // The turn rate to hold from now on (rad/s, positive clockwise seen from above, i.e. towards
  // the right wing), clamped to the bank limit.
  void Command(double turn_rate_rad_s);
  // Flies to t (>= the current time; the flight starts at t = 0).
  void AdvanceTo(int64_t t_ns);
  // The state at the current time.
  sim::BodyState State() const;
  // The true heading of the nose (deg clockwise from north) at the current time.
  double heading_deg() const;

 private:
  void Evaluate(double t, double* heading, double* rate) const;  // the current segment
  double CommandAt(double t) const;
  double Heading(double t) const;   // rad, clockwise from north, within the current segment
  double TurnRate(double t) const;  // rad/s
  double Height(double t) const;
  Eigen::Vector3d Velocity(double t) const;
  Eigen::Matrix3d WorldFromBody(double t) const;

  FlightModelOptions options_;
  AltitudeProfile altitude_;
  double gust_amp_[2][3] = {}, gust_freq_[2][3] = {}, gust_phase_[2][3] = {};
  double max_rate_ = 0;
  // The current segment (a constant command since t0): heading and turn rate at t0.
  double t0_ = 0, heading0_ = 0, rate0_ = 0, from_ = 0, command_ = 0;
  double t_ = 0;
  Eigen::Vector2d xy_;
};

}  // namespace optinav::nav
