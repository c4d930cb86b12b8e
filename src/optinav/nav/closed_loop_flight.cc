#include "optinav/nav/internal/closed_loop_flight.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "optinav/nav/map_aided_nav.h"

namespace optinav::nav {

namespace {
constexpr double kDeg = M_PI / 180.0;
constexpr double kDerivativeStep = 1e-3;  // s, central differences of the smooth profiles
}  // namespace

ClosedLoopFlight::ClosedLoopFlight(const FlightModelOptions& options,
                                   const Eigen::Vector2d& start_xy, double heading_deg)
    : options_(options),
      altitude_(options.altitude_variation, options.seed ^ 0x41c7u),
      heading0_(heading_deg * kDeg),
      xy_(start_xy) {
  max_rate_ = sim::kGravity * std::tan(options.max_bank_deg * kDeg) / options.air_speed_m_s;
  std::mt19937_64 rng(options.seed ^ 0x9e3779b97f4a7c15ull);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto axis = 0; axis < 2; ++axis) {
    double sum = 0;
    for (int i = 0; i < 3; ++i) {
      gust_amp_[axis][i] = 0.3 + u(rng);
      gust_freq_[axis][i] = 2 * M_PI / (4 + 16 * u(rng));  // periods of 4-20 s
      gust_phase_[axis][i] = 2 * M_PI * u(rng);
      sum += gust_amp_[axis][i];
    }
    for (double& a : gust_amp_[axis]) a /= sum;  // |sum of sinusoids| <= 1
  }
}

void ClosedLoopFlight::Command(double turn_rate_rad_s) {
  const double c = std::clamp(turn_rate_rad_s, -max_rate_, max_rate_);
  heading0_ = Heading(t_);
  rate0_ = TurnRate(t_);
  from_ = CommandAt(t_);
  t0_ = t_;
  command_ = c;
}

double ClosedLoopFlight::CommandAt(double t) const {
  const double u = t - t0_, ramp = options_.command_ramp_s;
  return u >= ramp ? command_ : from_ + (command_ - from_) * u / ramp;
}

// The turn rate r obeys r' = (c(t) - r) / lag with the command c(t) ramping linearly from `from_`
// to `command_` over command_ramp_s, then held: r' is continuous, so is the roll rate of the
// bank that follows r. Closed forms for both pieces.
void ClosedLoopFlight::Evaluate(double t, double* heading, double* rate) const {
  const double tau = options_.turn_lag_s, ramp = options_.command_ramp_s;
  const double slope = (command_ - from_) / ramp;
  auto in_ramp = [&](double u, double* h, double* r) {
    const double a = rate0_ - from_ + slope * tau, e = std::exp(-u / tau);
    *r = from_ + slope * (u - tau) + a * e;
    *h = heading0_ + from_ * u + slope * (0.5 * u * u - tau * u) + a * tau * (1 - e);
  };
  const double u = t - t0_;
  if (u <= ramp) {
    in_ramp(u, heading, rate);
    return;
  }
  double h_end, r_end;
  in_ramp(ramp, &h_end, &r_end);
  const double v = u - ramp, e = std::exp(-v / tau);
  *rate = command_ + (r_end - command_) * e;
  *heading = h_end + command_ * v + (r_end - command_) * tau * (1 - e);
}

double ClosedLoopFlight::Heading(double t) const {
  double h, r;
  Evaluate(t, &h, &r);
  return h;
}

double ClosedLoopFlight::TurnRate(double t) const {
  double h, r;
  Evaluate(t, &h, &r);
  return r;
}

double ClosedLoopFlight::Height(double t) const {
  return options_.altitude_m * altitude_.Factor(t);
}

Eigen::Vector3d ClosedLoopFlight::Velocity(double t) const {
  const double psi = Heading(t), e = kDerivativeStep;
  return {options_.air_speed_m_s * std::sin(psi) + options_.wind_m_s.x(),
          options_.air_speed_m_s * std::cos(psi) + options_.wind_m_s.y(),
          (Height(t + e) - Height(t - e)) / (2 * e)};
}

Eigen::Matrix3d ClosedLoopFlight::WorldFromBody(double t) const {
  auto gust = [&](int axis) {
    double v = 0;
    for (int i = 0; i < 3; ++i)
      v += gust_amp_[axis][i] * std::sin(gust_freq_[axis][i] * t + gust_phase_[axis][i]);
    return options_.gust_tilt_deg * v;
  };
  const double bank =
      std::atan(options_.air_speed_m_s * TurnRate(t) / sim::kGravity) / kDeg;  // right wing down
  const double climb = std::atan2(Velocity(t).z(), options_.air_speed_m_s) / kDeg;
  return EnuFromBodyOfAttitude(bank + gust(0), climb + gust(1), Heading(t) / kDeg);
}

void ClosedLoopFlight::AdvanceTo(int64_t t_ns) {
  const double t = t_ns * 1e-9;
  while (t_ < t) {
    const double h = std::min(1e-3, t - t_);
    xy_ += h / 6 * (Velocity(t_) + 4 * Velocity(t_ + h / 2) + Velocity(t_ + h)).head<2>();
    t_ += h;
  }
  t_ = std::max(t_, t);
}

double ClosedLoopFlight::heading_deg() const {
  const double d = std::fmod(Heading(t_) / kDeg, 360.0);
  return d < 0 ? d + 360 : d;
}

sim::BodyState ClosedLoopFlight::State() const {
  sim::BodyState s;
  s.t_ns = std::llround(t_ * 1e9);
  const Eigen::Matrix3d r = WorldFromBody(t_);
  s.world_from_body =
      Rigid3d(Eigen::Quaterniond(r).normalized(), Eigen::Vector3d(xy_.x(), xy_.y(), Height(t_)));
  s.velocity_in_world = Velocity(t_);
  const double psi = Heading(t_), e = kDerivativeStep;
  s.acceleration_in_world =
      Eigen::Vector3d(options_.air_speed_m_s * TurnRate(t_) * std::cos(psi),
                      -options_.air_speed_m_s * TurnRate(t_) * std::sin(psi),
                      (Height(t_ + e) - 2 * Height(t_) + Height(t_ - e)) / (e * e));
  // The body rate: R(t - h)^T R(t + h) = exp(2 h [w]x) up to O(h^2).
  constexpr double h = 1e-4;
  const Eigen::AngleAxisd d(WorldFromBody(t_ - h).transpose() * WorldFromBody(t_ + h));
  s.angular_velocity_in_body = d.axis() * d.angle() / (2 * h);
  return s;
}

}  // namespace optinav::nav
