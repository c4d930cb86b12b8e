// IMU preintegration on the manifold (Forster, Carlone, Dellaert, Scaramuzza, "On-Manifold
// Preintegration for Real-Time Visual-Inertial Odometry", T-RO 2017).
//
// Between two states i and j the body-frame IMU samples are summarised as
//   delta_R = prod Exp((w_k - bg) dt_k)
//   delta_v = sum delta_R_k (a_k - ba) dt_k
//   delta_p = sum delta_v_k dt_k + 1/2 delta_R_k (a_k - ba) dt_k^2
// which depend only on the biases, not on the states, so the factor between i and j is
//   R_j = R_i delta_R
//   v_j = v_i + g dt + R_i delta_v
//   p_j = p_i + v_i dt + 1/2 g dt^2 + R_i delta_p
// (g = (0, 0, -9.81) in the gravity-aligned world). A bias change is applied to first order
// through the bias Jacobians; the 9x9 covariance is over the errors (phi, v, p) with
// delta_R_true = delta_R Exp(phi), delta_v_true = delta_v + v_err, delta_p_true = delta_p + p_err.
// The IMU is the body frame (EuRoC's T_BS of imu0 is the identity; other extrinsics are applied
// by the caller).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace optinav::vio {

using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Matrix15d = Eigen::Matrix<double, 15, 15>;

constexpr double kGravityMagnitude = 9.81;
inline Eigen::Vector3d GravityInWorld() { return {0.0, 0.0, -kGravityMagnitude}; }

// Continuous-time IMU noise, as in Kalibr / EuRoC sensor.yaml.
struct ImuNoise {
  double gyro_noise_density = 1.6968e-4;  // rad / s / sqrt(Hz)
  double accel_noise_density = 2.0e-3;    // m / s^2 / sqrt(Hz)
  double gyro_random_walk = 1.9393e-5;    // rad / s^2 / sqrt(Hz)
  double accel_random_walk = 3.0e-3;      // m / s^3 / sqrt(Hz)
};

struct ImuBias {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // rad / s
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // m / s^2
};

// A navigation state in the gravity-aligned world.
struct NavState {
  Eigen::Quaterniond world_from_body_rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // body origin in world, m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // in world, m / s
};

// One IMU sample held constant over [t_ns, t_ns + dt).
struct ImuMeasurement {
  double dt_s = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  // The gyro bias random walk over this sample is this times the noise model's (1: as modelled).
  double gyro_walk_scale = 1.0;
  // Its white noise (gyro and accelerometer) is this times the noise model's (ScaleWhiteNoise).
  double white_noise_scale = 1.0;
};

class ImuPreintegration {
 public:
  ImuPreintegration() = default;
  ImuPreintegration(const ImuBias& linearization_bias, const ImuNoise& noise);

  // Adds one sample held constant for dt_s seconds (dt_s > 0).
  void Integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt_s);
  // Appends all samples of `next` (which must follow this one in time) and re-integrates them
  // at this object's linearisation bias: merging two intervals when a state is dropped.
  void Append(const ImuPreintegration& next);
  // Re-integrates every stored sample around a new linearisation bias.
  void Reintegrate(const ImuBias& linearization_bias);
  // The preintegration of the first `duration_s` seconds (the last sample cut), same bias.
  ImuPreintegration Prefix(double duration_s) const;
  // Scales the gyro bias random walk of every stored sample (FullCovariance): a bias held
  // tighter than the noise model over this interval (scale < 1).
  void ScaleGyroBiasWalk(double scale);
  // Multiplies the white noise (gyro and accelerometer) of every stored sample by `scale` and
  // re-integrates: an interval the IMU is known to have measured worse than modelled.
  void ScaleWhiteNoise(double scale);

  double dt_s() const { return dt_s_; }
  const ImuBias& linearization_bias() const { return bias_; }
  const ImuNoise& noise() const { return noise_; }
  const std::vector<ImuMeasurement>& measurements() const { return measurements_; }

  const Eigen::Quaterniond& delta_R() const { return delta_R_; }
  const Eigen::Vector3d& delta_v() const { return delta_v_; }
  const Eigen::Vector3d& delta_p() const { return delta_p_; }
  // Covariance of (phi, v, p).
  const Matrix9d& covariance() const { return covariance_; }
  // 15x15 covariance of (phi, v, p, bias_gyro change, bias_accel change) over the interval:
  // the preintegration block plus the bias random walk over dt (the gyro's over the samples'
  // scaled time, sum of gyro_walk_scale^2 * dt_s).
  Matrix15d FullCovariance() const;

  const Eigen::Matrix3d& dR_dbg() const { return dR_dbg_; }
  const Eigen::Matrix3d& dv_dbg() const { return dv_dbg_; }
  const Eigen::Matrix3d& dv_dba() const { return dv_dba_; }
  const Eigen::Matrix3d& dp_dbg() const { return dp_dbg_; }
  const Eigen::Matrix3d& dp_dba() const { return dp_dba_; }

  // Deltas corrected to first order for a bias different from the linearisation bias.
  Eigen::Quaterniond CorrectedDeltaR(const ImuBias& bias) const;
  Eigen::Vector3d CorrectedDeltaV(const ImuBias& bias) const;
  Eigen::Vector3d CorrectedDeltaP(const ImuBias& bias) const;

  // State j predicted from state i with the given bias.
  NavState Predict(const NavState& state_i, const ImuBias& bias,
                   const Eigen::Vector3d& gravity = GravityInWorld()) const;
  // The 9-vector residual (r_phi, r_v, r_p) of states i, j with bias (of state i).
  Eigen::Matrix<double, 9, 1> Residual(const NavState& state_i, const NavState& state_j,
                                       const ImuBias& bias,
                                       const Eigen::Vector3d& gravity = GravityInWorld()) const;

 private:
  void Reset();
  void Propagate(const ImuMeasurement& m);
  void Add(const ImuMeasurement& m);  // stored and propagated

  ImuBias bias_;
  ImuNoise noise_;
  std::vector<ImuMeasurement> measurements_;
  double dt_s_ = 0;
  double gyro_walk_s_ = 0;  // sum of gyro_walk_scale^2 * dt_s over the samples
  Eigen::Quaterniond delta_R_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d delta_v_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d delta_p_ = Eigen::Vector3d::Zero();
  Matrix9d covariance_ = Matrix9d::Zero();
  Eigen::Matrix3d dR_dbg_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dv_dbg_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dv_dba_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dp_dbg_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dp_dba_ = Eigen::Matrix3d::Zero();
};

// IMU samples (at their own stamps) turned into measurements covering exactly [t0_ns, t1_ns]:
// each sample is held until the next one; the first and last intervals are cut at t0/t1
// (linear interpolation between the neighbouring samples at the cut points).
struct TimedImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};
std::vector<ImuMeasurement> ImuMeasurementsBetween(const std::vector<TimedImuSample>& samples,
                                                   int64_t t0_ns, int64_t t1_ns);

}  // namespace optinav::vio
