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
#include <vector>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include "optinav/geometry/lie.h"
#include "optinav/vio/internal/imu_preintegration.h"

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

// Reprojection of a world point into a camera of the rig. `observed` is the undistorted
// normalised image point (x/z, y/z); the residual is in pixels (scaled by focal_px / sigma_px).
// Blocks: pose, point. Analytic Jacobians (exact derivatives w.r.t. the 7 ambient pose
// parameters; Ceres applies the pose manifold's PlusJacobian).
ceres::CostFunction* CreateReprojectionFactor(const Rigid3d& cam_from_body,
                                              const Eigen::Vector2d& observed, double focal_px,
                                              double sigma_px);
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
// size.
LinearPrior Marginalize(const std::vector<const ResidualSpec*>& residuals,
                        const std::vector<double*>& marginalize,
                        const std::function<const ceres::Manifold*(const double*)>& manifold_of,
                        const std::function<int(const double*)>& size_of);

// A random walk on one block of a prior: that block's value is replaced by value + w,
// w ~ N(0, covariance) (in its tangent space), i.e. the prior forgets part of what it knew about
// it. Exact in information form: the old block is eliminated from the joint with the new one.
LinearPrior AddRandomWalk(const LinearPrior& prior, const double* block,
                          const Eigen::MatrixXd& covariance);

}  // namespace optinav::vio
