// Ceres factors of the sliding-window backend.
//
// Parameter blocks (all double arrays owned by the backend):
//   pose         7: world_from_body position (x y z), rotation quaternion (x y z w, Eigen order),
//                   on ceres::ProductManifold<EuclideanManifold<3>, EigenQuaternionManifold>
//   speed_bias   9: velocity in world (m/s), gyro bias (rad/s), accel bias (m/s^2)
//   point        3: landmark position in world (m)
#pragma once

#include <functional>
#include <memory>
#include <type_traits>
#include <vector>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include "optinav/geometry/lie.h"
#include "optinav/vio/imu_preintegration.h"

namespace optinav::vio {

constexpr int kPoseSize = 7;
constexpr int kPoseTangentSize = 6;
constexpr int kSpeedBiasSize = 9;
constexpr int kPointSize = 3;

// The manifold of pose blocks (one shared instance; Ceres problems must not take ownership).
const ceres::Manifold* PoseManifold();

// IMU preintegration + bias random walk between states i and j: 15 residuals
// (r_phi, r_v, r_p, r_bg, r_ba) whitened by the 15x15 covariance. Blocks: pose_i, speed_bias_i,
// pose_j, speed_bias_j.
ceres::CostFunction* CreateImuFactor(const ImuPreintegration& preintegration,
                                     const Eigen::Vector3d& gravity = GravityInWorld());

// A wheeled ground vehicle's velocity lies along its body x axis (no side-slip, no vertical
// motion through the body: the non-holonomic constraint of land-vehicle navigation): 2 residuals,
// the body-frame velocity's y / sigma_lateral and z / sigma_vertical (m/s; a sigma <= 0 leaves
// that residual at 0). Blocks: pose, speed_bias. Holds for a body frame with x forward and its
// origin near the rear axle (a car's IMU at the rear axle, the simulator's car).
ceres::CostFunction* CreateGroundVehicleFactor(double sigma_lateral_m_s, double sigma_vertical_m_s);

// The same constraint without IMU (stereo-only: no velocity state), between two consecutive
// poses a and b dt_s apart: the chord p_b - p_a in the body frame halfway between the two
// attitudes (R_a Exp(Log(R_a^T R_b) / 2), the heading at the arc's middle, exact on an arc of
// constant curvature) is along x. 2 residuals: its y / (sigma_lateral dt) and z /
// (sigma_vertical dt), i.e. the mean body-frame velocity's components. Blocks: pose_a, pose_b.
ceres::CostFunction* CreateGroundVehiclePairFactor(double dt_s, double sigma_lateral_m_s,
                                                   double sigma_vertical_m_s);
// The same with the vehicle's forward axis in the body frame estimated: a third block (2) holds
// its yaw and pitch (rad; the axis is Rz(yaw) Ry(pitch) x, the residuals the chord's components
// along Rz(yaw) Ry(pitch) y and z). A camera-to-vehicle boresight error, or a small bias in the
// odometry's translation direction, is then one constant, not a rotation of every step.
ceres::CostFunction* CreateGroundVehiclePairFactorWithBoresight(double dt_s,
                                                                double sigma_lateral_m_s,
                                                                double sigma_vertical_m_s);

// The state at time t predicted from an anchor state i (its pose and speed-bias blocks) and the
// IMU preintegrated from i to t, with first-order bias corrections:
//   p_t = p_i + v_i dt + g dt^2 / 2 + R_i dp,  v_t = v_i + g dt + R_i dv,  R_t = R_i dR
// What every timed factor (GNSS, map fixes, barometer, velocity) evaluates.
class TimedStatePredictor {
 public:
  TimedStatePredictor(const ImuPreintegration& pre, const Eigen::Vector3d& gravity)
      : dt_(pre.dt_s()),
        delta_R_(pre.delta_R()),
        delta_v_(pre.delta_v()),
        delta_p_(pre.delta_p()),
        dR_dbg_(pre.dR_dbg()),
        dv_dbg_(pre.dv_dbg()),
        dv_dba_(pre.dv_dba()),
        dp_dbg_(pre.dp_dbg()),
        dp_dba_(pre.dp_dba()),
        bg0_(pre.linearization_bias().gyro),
        ba0_(pre.linearization_bias().accel),
        gravity_(gravity) {}

  template <typename T>
  void operator()(const T* pose, const T* speed_bias,
                  std::type_identity_t<Eigen::Matrix<T, 3, 1>>* p_t,
                  std::type_identity_t<Eigen::Matrix<T, 3, 1>>* v_t,
                  std::type_identity_t<Eigen::Quaternion<T>>* q_t) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Vec3> p_i(pose), v_i(speed_bias), bg(speed_bias + 3), ba(speed_bias + 6);
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose + 3);
    const Vec3 dbg = bg - bg0_.cast<T>(), dba = ba - ba0_.cast<T>();
    const T dt(dt_);
    if (p_t) {
      const Vec3 dp = delta_p_.cast<T>() + dp_dbg_.cast<T>() * dbg + dp_dba_.cast<T>() * dba;
      *p_t = p_i + v_i * dt + T(0.5) * gravity_.cast<T>() * dt * dt + q_i * dp;
    }
    if (v_t) {
      const Vec3 dv = delta_v_.cast<T>() + dv_dbg_.cast<T>() * dbg + dv_dba_.cast<T>() * dba;
      *v_t = v_i + gravity_.cast<T>() * dt + q_i * dv;
    }
    if (q_t) {
      const Vec3 rot_corr = dR_dbg_.cast<T>() * dbg;
      T aa[3] = {rot_corr[0], rot_corr[1], rot_corr[2]}, wxyz[4];
      ceres::AngleAxisToQuaternion(aa, wxyz);
      *q_t = q_i * (delta_R_.cast<T>() * Eigen::Quaternion<T>(wxyz[0], wxyz[1], wxyz[2], wxyz[3]));
    }
  }

 private:
  double dt_;
  Eigen::Quaterniond delta_R_;
  Eigen::Vector3d delta_v_, delta_p_;
  Eigen::Matrix3d dR_dbg_, dv_dbg_, dv_dba_, dp_dbg_, dp_dba_;
  Eigen::Vector3d bg0_, ba0_, gravity_;
};

// Reprojection of a world point into a camera of the rig. `observed` is the undistorted
// normalised image point (x/z, y/z); the residual is in pixels (scaled by focal_px / sigma_px).
// Blocks: pose, point. Analytic Jacobians (exact derivatives w.r.t. the 7 ambient pose
// parameters; Ceres applies the pose manifold's PlusJacobian).
ceres::CostFunction* CreateReprojectionFactor(const Rigid3d& cam_from_body,
                                              const Eigen::Vector2d& observed, double focal_px,
                                              double sigma_px);
// The same residual with the body pose held at `world_from_body` (a keyframe that left the
// window). Block: point.
ceres::CostFunction* CreateFixedPoseReprojectionFactor(const Rigid3d& world_from_body,
                                                       const Rigid3d& cam_from_body,
                                                       const Eigen::Vector2d& observed,
                                                       double focal_px, double sigma_px);
// The same residual differentiated by ceres::AutoDiffCostFunction (the reference the analytic
// Jacobians of CreateReprojectionFactor are tested against).
ceres::CostFunction* CreateAutoDiffReprojectionFactor(const Rigid3d& cam_from_body,
                                                      const Eigen::Vector2d& observed,
                                                      double focal_px, double sigma_px);

// A linear (Gaussian) prior on a set of blocks around a linearisation point x0:
//   r = r0 + J * Minus(x, x0)
// with Minus the block's manifold difference. Used for the initial prior and for the
// marginalisation prior that the Schur complement leaves behind.
struct LinearPrior {
  struct Block {
    double* values = nullptr;  // the live parameter block
    int ambient_size = 0, tangent_size = 0;
    const ceres::Manifold* manifold;  // nullptr: Euclidean
    std::vector<double> x0;           // linearisation point
  };
  std::vector<Block> blocks;
  Eigen::MatrixXd J;  // rows x sum(tangent sizes)
  Eigen::VectorXd r0;

  bool empty() const { return blocks.empty() || J.rows() == 0; }
  bool Involves(const double* values) const;
  ceres::CostFunction* CreateCostFunction() const;
};

// One residual block with everything needed to add it to a problem or to linearise it.
struct ResidualSpec {
  std::unique_ptr<ceres::CostFunction> cost;
  const ceres::LossFunction* loss = nullptr;  // not owned
  std::vector<double*> blocks;
};

// Schur-complement marginalisation: linearises `residuals` at the current values, eliminates
// the blocks in `marginalize` and returns the prior left on the remaining blocks they touch.
// `manifold_of` maps a block to its manifold (nullptr for Euclidean), `size_of` to its ambient
// size. Directions with information below 1e-10 of the largest are gauge directions (dropped);
// `jacobi_scaling` compares them on D H D, D = diag(H)^-1/2, instead of H (for windows whose
// blocks differ by many orders of magnitude in information: map-aided navigation, docs/NAV.md).
LinearPrior Marginalize(const std::vector<const ResidualSpec*>& residuals,
                        const std::vector<double*>& marginalize,
                        const std::function<const ceres::Manifold*(const double*)>& manifold_of,
                        const std::function<int(const double*)>& size_of,
                        bool jacobi_scaling = false);

// A random walk on one block of a prior: that block's value is replaced by value + w,
// w ~ N(0, covariance) (in its tangent space), i.e. the prior forgets part of what it knew about
// it. Exact in information form: the old block is eliminated from the joint with the new one.
LinearPrior AddRandomWalk(const LinearPrior& prior, const double* block,
                          const Eigen::MatrixXd& covariance, bool jacobi_scaling = false);

}  // namespace optinav::vio
