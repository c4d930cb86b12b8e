// Uniform quintic B-splines that interpolate samples, with analytic derivatives.
//
// Degree 5 makes the curve C4: position, velocity, acceleration, jerk and snap are continuous,
// so a body attitude derived from acceleration and jerk (a drone tilting with its thrust) has a
// continuous, differentiable angular velocity, which keeps simulated IMU data physically sane.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace optinav::sim {

class QuinticSpline {
 public:
  QuinticSpline() = default;
  // Interpolates `samples` (one row per sample, any number of columns) taken every `dt_s`
  // seconds from t = 0, with zero first and second derivatives at both ends (the curve starts
  // and ends at rest). Needs at least 2 samples and dt_s > 0.
  QuinticSpline(const Eigen::MatrixXd& samples, double dt_s);

  // The `order`-th derivative (0..4) at time t_s; outside [0, duration] the curve holds its end
  // value and derivatives are zero.
  Eigen::VectorXd Evaluate(double t_s, int order = 0) const;
  double duration_s() const { return dt_s_ * (num_samples_ - 1); }
  int dimension() const { return static_cast<int>(control_.cols()); }

 private:
  Eigen::MatrixXd control_;  // (num_samples + 4) x dimension
  double dt_s_ = 1.0;
  int num_samples_ = 0;
};

}  // namespace optinav::sim
