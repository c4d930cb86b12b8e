#include "optinav/sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "optinav/geometry/angles.h"
#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

Eigen::Vector3d Vee(const Eigen::Matrix3d& w) { return {w(2, 1), w(0, 2), w(1, 0)}; }

// Derivative of n = v / |v| given v and dv/dt.
Eigen::Vector3d NormalizedRate(const Eigen::Vector3d& n, const Eigen::Vector3d& v_dot,
                               double v_norm) {
  return (v_dot - n * n.dot(v_dot)) / v_norm;
}

// Attitude of a multirotor: body z along the specific force, body x towards the yaw.
void ThrustAligned(const Eigen::Vector3d& acc, const Eigen::Vector3d& jerk, double yaw,
                   double yaw_rate, Eigen::Matrix3d* r, Eigen::Vector3d* omega_in_body) {
  const Eigen::Vector3d f = acc + Eigen::Vector3d(0, 0, kGravity);
  const double nf = f.norm();
  OPTINAV_CHECK_MSG(nf > 1e-3, "free fall: thrust direction undefined");
  const Eigen::Vector3d z = f / nf, z_dot = NormalizedRate(z, jerk, nf);
  const Eigen::Vector3d xc(std::cos(yaw), std::sin(yaw), 0);
  const Eigen::Vector3d xc_dot = yaw_rate * Eigen::Vector3d(-std::sin(yaw), std::cos(yaw), 0);
  const Eigen::Vector3d u = z.cross(xc), u_dot = z_dot.cross(xc) + z.cross(xc_dot);
  const double nu = u.norm();
  OPTINAV_CHECK_MSG(nu > 1e-6, "tilt of 90 deg: yaw undefined");
  const Eigen::Vector3d y = u / nu, y_dot = NormalizedRate(y, u_dot, nu);
  const Eigen::Vector3d x = y.cross(z), x_dot = y_dot.cross(z) + y.cross(z_dot);
  r->col(0) = x;
  r->col(1) = y;
  r->col(2) = z;
  Eigen::Matrix3d r_dot;
  r_dot << x_dot, y_dot, z_dot;
  *omega_in_body = Vee(r->transpose() * r_dot);
}

// R = Rz(yaw) Ry(pitch) Rx(roll) and the body angular velocity from the angle rates.
void YawPitchRoll(const Eigen::Vector3d& ypr, const Eigen::Vector3d& ypr_dot, Eigen::Matrix3d* r,
                  Eigen::Vector3d* omega_in_body) {
  const double yaw = ypr[0], pitch = ypr[1], roll = ypr[2];
  *r = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
        Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
        Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
           .toRotationMatrix();
  const double sp = std::sin(pitch), cp = std::cos(pitch), sr = std::sin(roll), cr = std::cos(roll);
  const double dy = ypr_dot[0], dp = ypr_dot[1], dr = ypr_dot[2];
  *omega_in_body = Eigen::Vector3d(dr - dy * sp, dp * cr + dy * sr * cp, -dp * sr + dy * cr * cp);
}

}  // namespace

BodyTrajectory::BodyTrajectory(QuinticSpline position, QuinticSpline attitude, Attitude model,
                               int64_t start_ns)
    : position_(std::move(position)),
      attitude_(std::move(attitude)),
      model_(model),
      start_ns_(start_ns) {
  OPTINAV_CHECK(position_.dimension() == 3);
  OPTINAV_CHECK(attitude_.dimension() == (model == Attitude::kThrustAligned ? 1 : 3));
}

int64_t BodyTrajectory::end_ns() const {
  return start_ns_ + static_cast<int64_t>(std::llround(
                         std::min(position_.duration_s(), attitude_.duration_s()) * 1e9));
}

BodyState BodyTrajectory::At(int64_t t_ns) const {
  const double t = (t_ns - start_ns_) * 1e-9;
  BodyState s;
  s.t_ns = t_ns;
  s.world_from_body.translation = position_.Evaluate(t, 0);
  s.velocity_in_world = position_.Evaluate(t, 1);
  s.acceleration_in_world = position_.Evaluate(t, 2);
  Eigen::Matrix3d r;
  if (model_ == Attitude::kThrustAligned) {
    // The thrust balances gravity, the acceleration and the drag -k (v - wind) (constant wind:
    // its rate is k a).
    ThrustAligned(s.acceleration_in_world + drag_per_s_ * (s.velocity_in_world - wind_in_world_),
                  position_.Evaluate(t, 3) + drag_per_s_ * s.acceleration_in_world,
                  attitude_.Evaluate(t, 0)[0], attitude_.Evaluate(t, 1)[0], &r,
                  &s.angular_velocity_in_body);
  } else {
    YawPitchRoll(attitude_.Evaluate(t, 0), attitude_.Evaluate(t, 1), &r,
                 &s.angular_velocity_in_body);
  }
  s.world_from_body.rotation = Eigen::Quaterniond(r).normalized();
  return s;
}

void BodyTrajectory::SetAirDrag(double drag_per_s, const Eigen::Vector3d& wind_in_world) {
  OPTINAV_CHECK_MSG(std::isfinite(drag_per_s) && drag_per_s >= 0 && wind_in_world.allFinite(),
                    "air drag must be finite and >= 0, the wind finite");
  OPTINAV_CHECK_MSG(model_ == Attitude::kThrustAligned || drag_per_s == 0,
                    "air drag applies to thrust-aligned (drone) trajectories only");
  drag_per_s_ = drag_per_s;
  wind_in_world_ = wind_in_world;
}

double BodyTrajectory::PathLength(double step_s) const {
  double len = 0;
  const int64_t step_ns = static_cast<int64_t>(step_s * 1e9);
  Eigen::Vector3d prev = At(start_ns_).world_from_body.translation;
  for (int64_t t = start_ns_ + step_ns; t <= end_ns(); t += step_ns) {
    const Eigen::Vector3d p = At(t).world_from_body.translation;
    len += (p - prev).norm();
    prev = p;
  }
  return len;
}

void BodyTrajectory::SetControls(std::vector<CarControls> controls, double dt_s) {
  controls_ = std::move(controls);
  controls_dt_s_ = dt_s;
}

std::optional<CarControls> BodyTrajectory::ControlsAt(int64_t t_ns) const {
  if (controls_.empty()) return std::nullopt;
  const double k = std::floor((t_ns - start_ns_) * 1e-9 / controls_dt_s_ + 1e-9);
  const size_t i = static_cast<size_t>(std::clamp(k, 0.0, controls_.size() - 1.0));
  return controls_[i];
}

BodyTrajectory MakeDroneTrajectory(const std::vector<DroneWaypoint>& waypoints, double speed_m_s,
                                   int64_t start_ns) {
  if (waypoints.size() < 2) throw Error("a drone route needs at least 2 waypoints");
  if (!(speed_m_s > 0)) throw Error("drone speed must be positive", {.field = "speed"});
  const int n = static_cast<int>(waypoints.size());
  double length = 0;
  for (int i = 1; i < n; ++i) {
    length += (waypoints[i].position_in_world - waypoints[i - 1].position_in_world).norm();
  }
  if (length < 1e-3) throw Error("drone waypoints do not move");
  const double dt = length / (n - 1) / speed_m_s;
  Eigen::MatrixXd pos(n, 3), yaw(n, 1);
  double prev_yaw = 0;
  for (int i = 0; i < n; ++i) {
    pos.row(i) = waypoints[i].position_in_world.transpose();
    double y;
    if (waypoints[i].yaw_rad) {
      y = *waypoints[i].yaw_rad;
    } else {
      const Eigen::Vector3d d = waypoints[std::min(i + 1, n - 1)].position_in_world -
                                waypoints[std::max(i - 1, 0)].position_in_world;
      y = d.head<2>().norm() > 1e-6 ? std::atan2(d.y(), d.x()) : prev_yaw;
    }
    // Unwrap so the spline turns the short way.
    if (i > 0) y = prev_yaw + WrapRadPi(y - prev_yaw);
    yaw(i, 0) = prev_yaw = y;
  }
  return BodyTrajectory(QuinticSpline(pos, dt), QuinticSpline(yaw, dt),
                        BodyTrajectory::Attitude::kThrustAligned, start_ns);
}

std::vector<DroneWaypoint> RandomDroneWaypoints(const RandomDroneRouteOptions& o,
                                                const HeightFunction& ground, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0, 1);
  const int n = std::max(2, static_cast<int>(std::ceil(o.duration_s / o.segment_s)) + 1);
  const double step = o.speed_m_s * o.segment_s;
  const Eigen::Vector2d centre = 0.5 * (o.area_min + o.area_max);
  Eigen::Vector2d p = o.start;
  double heading = std::uniform_real_distribution<double>(-M_PI, M_PI)(rng);
  std::vector<DroneWaypoint> out;
  for (int i = 0; i < n; ++i) {
    const double alt = o.altitude_m * (1 + std::clamp(0.07 * n01(rng), -0.15, 0.15));
    DroneWaypoint w;
    w.position_in_world = Eigen::Vector3d(p.x(), p.y(), ground(p.x(), p.y()) + alt);
    w.yaw_rad = heading + std::clamp(0.2 * n01(rng), -0.44, 0.44);
    out.push_back(w);
    heading += 0.5 * n01(rng);
    // Near the border, turn towards the centre.
    const Eigen::Vector2d next = p + step * Eigen::Vector2d(std::cos(heading), std::sin(heading));
    const Eigen::Vector2d margin = Eigen::Vector2d::Constant(2 * step);
    if ((next.array() < (o.area_min + margin).array()).any() ||
        (next.array() > (o.area_max - margin).array()).any()) {
      const Eigen::Vector2d to_c = centre - p;
      const double want = std::atan2(to_c.y(), to_c.x());
      heading += 0.6 * WrapRadPi(want - heading);
    }
    p += step * Eigen::Vector2d(std::cos(heading), std::sin(heading));
  }
  return out;
}

BodyTrajectory MakeCarTrajectory(const CarRouteOptions& options, const HeightFunction& ground,
                                 int64_t start_ns) {
  // Stop conditions of the car route of the AirSim weather dataset (SEEDS.md part 1; its Table 2),
  // in NED (x north, y east, psi clockwise from north); |qw| = |cos(psi / 2)| of the car's attitude
  // quaternion.
  enum class Until { kXAbove, kXBelow, kYAbove, kYBelow, kQwBelow, kQwAbove, kStopped };
  struct Step {
    double throttle, steering;
    Until until;
    double value;
  };
  const Step steps[] = {{0.7, 0, Until::kXAbove, 115},
                        {0.5, 0.5, Until::kQwBelow, 0.72},
                        {0.7, 0, Until::kYAbove, 112},
                        {0.5, 0.5, Until::kQwBelow, 0.035},
                        {0.7, 0, Until::kXBelow, options.leg3_end_x_m},
                        {0.5, 0.5, Until::kQwAbove, 0.68},
                        {0.7, 0, Until::kYBelow, options.leg4_end_y_m},
                        {0.5, 0.5, Until::kQwAbove, 0.999},
                        {0.7, 0, Until::kXAbove, 0},
                        {0, 0, Until::kStopped, 0}};
  // Vehicle model: v' = 4 throttle - 0.35 v (8 m/s top speed at throttle 0.7), handbrake
  // -6 m/s^2; kinematic bicycle with 2.9 m wheelbase, 17.8 deg full steering lock (an 18.5 m
  // turn radius at steering 0.5, which reproduces the dataset's route lengths), steering
  // rate limited to 0.3 rad/s.
  const double dt = 0.01, wheelbase = 2.9, max_steer = 0.311, steer_rate = 0.3;
  const double hold_s = 1.0, sample_dt = 0.25;
  const int per_sample = static_cast<int>(std::lround(sample_dt / dt));
  double x = 0, y = 0, psi = 0, v = 0, delta = 0, t = 0;
  std::vector<Eigen::Vector3d> xy_psi;
  std::vector<CarControls> controls;
  auto record = [&](const CarControls& c) {
    xy_psi.emplace_back(x, y, psi);
    CarControls cc = c;
    cc.speed_m_s = v;
    controls.push_back(cc);
  };
  const int hold_samples = static_cast<int>(hold_s / sample_dt);
  for (int i = 0; i < hold_samples; ++i) record({});
  int step_index = 0, k = 0;
  CarControls cmd;
  while (step_index < static_cast<int>(std::size(steps)) && t < options.max_duration_s) {
    const Step& s = steps[step_index];
    const double qw = std::abs(std::cos(psi / 2));
    bool done = false;
    switch (s.until) {
      case Until::kXAbove:
        done = x >= s.value;
        break;
      case Until::kXBelow:
        done = x <= s.value;
        break;
      case Until::kYAbove:
        done = y >= s.value;
        break;
      case Until::kYBelow:
        done = y <= s.value;
        break;
      case Until::kQwBelow:
        done = qw <= s.value;
        break;
      case Until::kQwAbove:
        done = qw >= s.value;
        break;
      case Until::kStopped:
        done = v <= 0;
        break;
    }
    if (done) {
      ++step_index;
      continue;
    }
    const bool handbrake = s.until == Until::kStopped;
    cmd = {.throttle = s.throttle,
           .steering = s.steering,
           .brake = handbrake ? 1.0 : 0.0,
           .handbrake = handbrake,
           .gear = 1};
    const double want = s.steering * max_steer;
    delta += std::clamp(want - delta, -steer_rate * dt, steer_rate * dt);
    const double acc = handbrake ? -6.0 : 4.0 * s.throttle - 0.35 * v;
    // NED: x north, y east; psi clockwise from north (positive steering turns right).
    x += v * std::cos(psi) * dt;
    y += v * std::sin(psi) * dt;
    psi += v * std::tan(delta) / wheelbase * dt;
    v = std::max(0.0, v + acc * dt);
    t += dt;
    if (++k % per_sample == 0) record(cmd);
  }
  if (step_index < static_cast<int>(std::size(steps))) {
    throw Error("car route did not finish within max_duration_s");
  }
  for (int i = 0; i < hold_samples; ++i) record({.handbrake = true});
  const int n = static_cast<int>(xy_psi.size());
  Eigen::MatrixXd pos(n, 3), ypr(n, 3);
  const double h = 0.5;  // finite-difference step for the ground slope (m)
  for (int i = 0; i < n; ++i) {
    // NED -> ENU: east = y_ned, north = x_ned; ENU yaw = pi/2 - psi.
    const double e = xy_psi[i].y(), nn = xy_psi[i].x(), yaw = M_PI / 2 - xy_psi[i].z();
    const double z = ground(e, nn);
    const Eigen::Vector2d grad((ground(e + h, nn) - ground(e - h, nn)) / (2 * h),
                               (ground(e, nn + h) - ground(e, nn - h)) / (2 * h));
    const Eigen::Vector2d fwd(std::cos(yaw), std::sin(yaw)), left(-fwd.y(), fwd.x());
    pos.row(i) << e, nn, z;
    ypr.row(i) << yaw, -std::atan(grad.dot(fwd)), std::atan(grad.dot(left));
  }
  BodyTrajectory traj(QuinticSpline(pos, sample_dt), QuinticSpline(ypr, sample_dt),
                      BodyTrajectory::Attitude::kYawPitchRoll, start_ns);
  traj.SetControls(std::move(controls), sample_dt);
  return traj;
}

}  // namespace optinav::sim
