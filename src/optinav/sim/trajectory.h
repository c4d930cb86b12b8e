// Continuous body trajectories with analytic derivatives, for drones and cars.
//
// Frames: the world is local ENU about the GNSS origin (x east, y north, z up); the body frame
// is x forward, y left, z up (the IMU frame). A trajectory is a quintic spline of the position
// (C4) plus an attitude model:
//  - thrust-aligned (drones): body z along the specific force a + g, body x towards a yaw
//    given by its own spline: a multirotor tilts as it accelerates (and, with air drag, into
//    its air speed and the wind: SetAirDrag);
//  - yaw-pitch-roll (cars): R = Rz(yaw) Ry(pitch) Rx(roll), each angle a spline.
// Velocity, acceleration and the body angular velocity come from the spline derivatives
// in closed form (the angular velocity of the thrust-aligned model needs the jerk), so IMU
// samples are exact up to floating point.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "optinav/geometry/lie.h"
#include "optinav/sim/internal/spline.h"

namespace optinav::sim {

inline constexpr double kGravity = 9.81;  // m/s^2, along -z of the world

struct BodyState {
  int64_t t_ns = 0;
  Rigid3d world_from_body;
  Eigen::Vector3d velocity_in_world = Eigen::Vector3d::Zero();         // m/s
  Eigen::Vector3d acceleration_in_world = Eigen::Vector3d::Zero();     // m/s^2, without gravity
  Eigen::Vector3d angular_velocity_in_body = Eigen::Vector3d::Zero();  // rad/s
};

// The driver's commands of a car route at one time (AirSim records them).
struct CarControls {
  double throttle = 0, steering = 0, brake = 0;  // [0, 1], steering [-1, 1] (+ right)
  bool handbrake = false;
  double speed_m_s = 0;
  int gear = 0;  // 0 neutral/parked, 1 forward
};

class BodyTrajectory {
 public:
  enum class Attitude { kThrustAligned, kYawPitchRoll };

  // `position`: 3 columns (world metres); `attitude`: 1 column (yaw, rad) for kThrustAligned or
  // 3 columns (yaw, pitch, roll, rad) for kYawPitchRoll. Both splines start at `start_ns`.
  BodyTrajectory(QuinticSpline position, QuinticSpline attitude, Attitude model, int64_t start_ns);

  BodyState At(int64_t t_ns) const;
  int64_t start_ns() const { return start_ns_; }
  int64_t end_ns() const;
  // Length of the path sampled every `step_s` seconds.
  double PathLength(double step_s = 0.05) const;

  // Air drag of a multirotor (thrust-aligned routes only): a drag force -m k (v - wind) that the
  // thrust must balance too, so body z lies along a + g e_z + k (v - wind) and the vehicle leans
  // into its air speed and the wind as a real one does (k = `drag_per_s`, 1/s; 0: no drag, body
  // z along a + g e_z). The accelerometer still measures a + g e_z, the drag being a force it
  // feels: only the attitude (and with it the angular velocity) changes.
  void SetAirDrag(double drag_per_s, const Eigen::Vector3d& wind_in_world);

  // Car routes carry the commands that drove them, sampled every controls_dt_s from start.
  void SetControls(std::vector<CarControls> controls, double dt_s);
  std::optional<CarControls> ControlsAt(int64_t t_ns) const;

 private:
  QuinticSpline position_, attitude_;
  Attitude model_;
  int64_t start_ns_;
  double drag_per_s_ = 0;
  Eigen::Vector3d wind_in_world_ = Eigen::Vector3d::Zero();
  std::vector<CarControls> controls_;
  double controls_dt_s_ = 0;
};

// Ground height (world z, metres) at a world x, y.
using HeightFunction = std::function<double(double x, double y)>;

struct DroneWaypoint {
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();
  std::optional<double> yaw_rad;  // none: face along the path
};

// A spline through the waypoints, one segment per waypoint pair, each lasting the mean segment
// length / speed (so the speed is about `speed_m_s` when waypoints are about evenly spaced).
// Starts and ends at rest. Needs at least 2 distinct waypoints.
BodyTrajectory MakeDroneTrajectory(const std::vector<DroneWaypoint>& waypoints, double speed_m_s,
                                   int64_t start_ns);

struct RandomDroneRouteOptions {
  double speed_m_s = 5.0;
  double altitude_m = 20.0;  // above the ground below each waypoint
  double duration_s = 60.0;
  double segment_s = 2.0;                                    // time between waypoints
  Eigen::Vector2d area_min{-100, -100}, area_max{100, 100};  // stay inside (world x, y)
  Eigen::Vector2d start{0, 0};
};

// A seeded smooth random flight: a heading random walk kept inside the area, altitude varying
// by +-15 %, yaw within +-25 deg of the heading.
std::vector<DroneWaypoint> RandomDroneWaypoints(const RandomDroneRouteOptions& options,
                                                const HeightFunction& ground, uint64_t seed);

// The car route of the AirSim weather dataset (SEEDS.md part 1; its Table 2): throttle/steering
// steps with stop conditions in AirSim's NED coordinates (x north, y east; the car starts at the
// origin facing north), driven through a kinematic bicycle model with a speed-dependent turn
// radius, then smoothed into a spline sampled every 0.25 s. The dataset's figures give ~745 m in
// the urban world and ~875 m in the terrain world; those differ only in the two end conditions
// below.
struct CarRouteOptions {
  double leg3_end_x_m = -110;   // "forward until x = -110" (urban) / -140 (terrain)
  double leg4_end_y_m = 16.5;   // "forward until y = 16.5" (urban) / -30 (terrain)
  double max_duration_s = 600;  // safety stop
  static CarRouteOptions Urban() { return {}; }
  static CarRouteOptions Terrain() { return {.leg3_end_x_m = -140, .leg4_end_y_m = -30}; }
};
BodyTrajectory MakeCarTrajectory(const CarRouteOptions& options, const HeightFunction& ground,
                                 int64_t start_ns);

}  // namespace optinav::sim
