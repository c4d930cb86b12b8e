#include "optinav/vio/factors.h"

#include <algorithm>
#include <map>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <ceres/autodiff_cost_function.h>
#include <ceres/product_manifold.h>

#include "optinav/util/error.h"

namespace optinav::vio {

namespace {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

template <typename T>
Eigen::Quaternion<T> ExpT(const Vec3<T>& v) {
  T wxyz[4];
  const T aa[3] = {v[0], v[1], v[2]};
  ceres::AngleAxisToQuaternion(aa, wxyz);
  return Eigen::Quaternion<T>(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
}

template <typename T>
Vec3<T> LogT(const Eigen::Quaternion<T>& q) {
  const T wxyz[4] = {q.w(), q.x(), q.y(), q.z()};
  T aa[3];
  ceres::QuaternionToAngleAxis(wxyz, aa);
  return {aa[0], aa[1], aa[2]};
}

class ImuFunctor {
 public:
  ImuFunctor(const ImuPreintegration& pre, const Eigen::Vector3d& gravity)
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
        gravity_(gravity) {
    // Whitening: sqrt_info^T sqrt_info = covariance^-1 (regularised: tiny intervals are
    // nearly singular in rotation-velocity coupling).
    Matrix15d cov = pre.FullCovariance();
    cov.diagonal().array() += 1e-12;
    const Matrix15d info = cov.inverse();
    const Matrix15d symmetric = 0.5 * (info + info.transpose());
    sqrt_info_ = Eigen::LLT<Matrix15d>(symmetric).matrixL().transpose();
  }

  template <typename T>
  bool operator()(const T* pose_i, const T* sb_i, const T* pose_j, const T* sb_j,
                  T* residuals) const {
    const Eigen::Map<const Vec3<T>> p_i(pose_i), p_j(pose_j);
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i + 3), q_j(pose_j + 3);
    const Eigen::Map<const Vec3<T>> v_i(sb_i), bg_i(sb_i + 3), ba_i(sb_i + 6);
    const Eigen::Map<const Vec3<T>> v_j(sb_j), bg_j(sb_j + 3), ba_j(sb_j + 6);
    const Vec3<T> dbg = bg_i - bg0_.cast<T>();
    const Vec3<T> dba = ba_i - ba0_.cast<T>();
    const Eigen::Quaternion<T> dR = delta_R_.cast<T>() * ExpT<T>(dR_dbg_.cast<T>() * dbg);
    const Vec3<T> dv = delta_v_.cast<T>() + dv_dbg_.cast<T>() * dbg + dv_dba_.cast<T>() * dba;
    const Vec3<T> dp = delta_p_.cast<T>() + dp_dbg_.cast<T>() * dbg + dp_dba_.cast<T>() * dba;
    const Eigen::Quaternion<T> qi_inv = q_i.conjugate();
    const Vec3<T> g = gravity_.cast<T>();
    const T dt(dt_);
    Eigen::Matrix<T, 15, 1> r;
    r.template segment<3>(0) = LogT<T>(dR.conjugate() * (qi_inv * q_j));
    r.template segment<3>(3) = qi_inv * (v_j - v_i - g * dt) - dv;
    r.template segment<3>(6) = qi_inv * (p_j - p_i - v_i * dt - T(0.5) * g * dt * dt) - dp;
    r.template segment<3>(9) = bg_j - bg_i;
    r.template segment<3>(12) = ba_j - ba_i;
    Eigen::Map<Eigen::Matrix<T, 15, 1>> out(residuals);
    out = sqrt_info_.cast<T>() * r;
    return true;
  }

 private:
  double dt_;
  Eigen::Quaterniond delta_R_;
  Eigen::Vector3d delta_v_, delta_p_;
  Eigen::Matrix3d dR_dbg_, dv_dbg_, dv_dba_, dp_dbg_, dp_dba_;
  Eigen::Vector3d bg0_, ba0_, gravity_;
  Matrix15d sqrt_info_;
};

class ReprojectionFunctor {
 public:
  ReprojectionFunctor(const Rigid3d& cam_from_body, const Eigen::Vector2d& observed, double scale)
      : cam_from_body_(cam_from_body), observed_(observed), scale_(scale) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residuals) const {
    const Eigen::Map<const Vec3<T>> p(pose), x_world(point);
    const Eigen::Map<const Eigen::Quaternion<T>> q(pose + 3);
    const Vec3<T> p_in_body = q.conjugate() * (x_world - p);
    const Vec3<T> p_in_cam =
        cam_from_body_.rotation.cast<T>() * p_in_body + cam_from_body_.translation.cast<T>();
    // Points at or behind the camera: a large constant residual (no gradient towards them).
    if (p_in_cam.z() < T(1e-3)) {
      residuals[0] = residuals[1] = T(scale_);
      return true;
    }
    residuals[0] = T(scale_) * (p_in_cam.x() / p_in_cam.z() - T(observed_.x()));
    residuals[1] = T(scale_) * (p_in_cam.y() / p_in_cam.z() - T(observed_.y()));
    return true;
  }

 private:
  Rigid3d cam_from_body_;
  Eigen::Vector2d observed_;
  double scale_;
};

// The same residual as ReprojectionFunctor with hand-written Jacobians (the window solves
// evaluate thousands of these per iteration; autodiff's 10-wide dual numbers cost about 3x more).
// The Jacobian is the exact derivative of the function of the 7 ambient pose parameters (the
// quaternion rotation written as Eigen evaluates it, valid off the unit sphere too), so Ceres'
// product with the manifold's PlusJacobian gives the tangent-space Jacobian, and it equals
// autodiff's to rounding (test Reprojection.AnalyticJacobianMatchesAutoDiff).
class ReprojectionCost : public ceres::SizedCostFunction<2, kPoseSize, kPointSize> {
 public:
  ReprojectionCost(const Rigid3d& cam_from_body, const Eigen::Vector2d& observed, double scale)
      : cam_from_body_rotation_(cam_from_body.rotation.normalized().toRotationMatrix()),
        cam_from_body_translation_(cam_from_body.translation),
        observed_(observed),
        scale_(scale) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const double* pose = parameters[0];
    const Eigen::Map<const Eigen::Vector3d> p(pose), x_world(parameters[1]);
    // body_from_world rotation applied as Eigen does for q^-1 = (w, -u):
    //   f(d) = d - 2 w (u x d) + 2 u x (u x d) = M d.
    const Eigen::Vector3d u(pose[3], pose[4], pose[5]);
    const double w = pose[6];
    const Eigen::Vector3d d = x_world - p;
    const Eigen::Matrix3d u_hat = Hat(u);
    const Eigen::Matrix3d M = Eigen::Matrix3d::Identity() - 2.0 * w * u_hat + 2.0 * u_hat * u_hat;
    const Eigen::Vector3d p_in_body = M * d;
    const Eigen::Vector3d p_in_cam =
        cam_from_body_rotation_ * p_in_body + cam_from_body_translation_;
    // Points at or behind the camera: a large constant residual (no gradient towards them).
    if (p_in_cam.z() < 1e-3) {
      residuals[0] = residuals[1] = scale_;
      if (jacobians) {
        if (jacobians[0]) std::fill_n(jacobians[0], 2 * kPoseSize, 0.0);
        if (jacobians[1]) std::fill_n(jacobians[1], 2 * kPointSize, 0.0);
      }
      return true;
    }
    const double inv_z = 1.0 / p_in_cam.z();
    const double x_n = p_in_cam.x() * inv_z, y_n = p_in_cam.y() * inv_z;
    residuals[0] = scale_ * (x_n - observed_.x());
    residuals[1] = scale_ * (y_n - observed_.y());
    if (!jacobians) return true;
    // d residual / d p_in_body = d r / d p_in_cam * R_cam_from_body.
    Eigen::Matrix<double, 2, 3> dr_dcam;
    dr_dcam << scale_ * inv_z, 0.0, -scale_ * x_n * inv_z,  //
        0.0, scale_ * inv_z, -scale_ * y_n * inv_z;
    const Eigen::Matrix<double, 2, 3> dr_dbody = dr_dcam * cam_from_body_rotation_;
    const Eigen::Matrix<double, 2, 3> dr_dworld = dr_dbody * M;
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, 2, kPointSize, Eigen::RowMajor>> j(jacobians[1]);
      j = dr_dworld;
    }
    if (jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, 2, kPoseSize, Eigen::RowMajor>> j(jacobians[0]);
      j.leftCols<3>() = -dr_dworld;
      // df/du = 2 w [d]x + 2 (u d^T + (u.d) I - 2 d u^T), df/dw = -2 u x d.
      const Eigen::Matrix3d df_du =
          2.0 * w * Hat(d) + 2.0 * (u * d.transpose() + u.dot(d) * Eigen::Matrix3d::Identity() -
                                    2.0 * d * u.transpose());
      j.middleCols<3>(3) = dr_dbody * df_du;
      j.col(6) = dr_dbody * (-2.0 * u.cross(d));
    }
    return true;
  }

 private:
  static Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
  }

  Eigen::Matrix3d cam_from_body_rotation_;
  Eigen::Vector3d cam_from_body_translation_;
  Eigen::Vector2d observed_;
  double scale_;
};

class PriorCost : public ceres::CostFunction {
 public:
  explicit PriorCost(const LinearPrior& prior) : prior_(prior) {
    set_num_residuals(static_cast<int>(prior_.J.rows()));
    for (const LinearPrior::Block& b : prior_.blocks)
      mutable_parameter_block_sizes()->push_back(b.ambient_size);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, prior_.J.rows());
    r = prior_.r0;
    int offset = 0;
    for (size_t k = 0; k < prior_.blocks.size(); ++k) {
      const LinearPrior::Block& b = prior_.blocks[k];
      Eigen::VectorXd delta(b.tangent_size);
      if (b.manifold) {
        b.manifold->Minus(parameters[k], b.x0.data(), delta.data());
      } else {
        for (int i = 0; i < b.ambient_size; ++i) delta[i] = parameters[k][i] - b.x0[i];
      }
      r += prior_.J.middleCols(offset, b.tangent_size) * delta;
      if (jacobians && jacobians[k]) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
            jacobians[k], prior_.J.rows(), b.ambient_size);
        if (b.manifold) {
          Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> minus_jac(
              b.tangent_size, b.ambient_size);
          b.manifold->MinusJacobian(parameters[k], minus_jac.data());
          jac = prior_.J.middleCols(offset, b.tangent_size) * minus_jac;
        } else {
          jac = prior_.J.middleCols(offset, b.tangent_size);
        }
      }
      offset += b.tangent_size;
    }
    return true;
  }

 private:
  LinearPrior prior_;
};

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// H = J^T J, b = J^T r0 -> (J, r0) of a prior (eigen-decomposition; null directions dropped).
void FactorInformation(const Eigen::MatrixXd& H, const Eigen::VectorXd& b, LinearPrior* prior,
                       bool jacobi_scaling) {
  // On the Jacobi-scaled matrix D H D (D = diag(H)^-1/2), as in Marginalize: the threshold that
  // separates null directions must not drop information that is only small in its units.
  const Eigen::Index n = H.rows();
  const Eigen::MatrixXd hs = 0.5 * (H + H.transpose());
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i)
    d[i] = jacobi_scaling && hs(i, i) > 0 ? 1.0 / std::sqrt(hs(i, i)) : 1.0;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(d.asDiagonal() * hs * d.asDiagonal());
  const Eigen::VectorXd l = eig.eigenvalues();
  const double max_l = std::max(l.maxCoeff(), 1e-12);
  Eigen::VectorXd sqrt_l(n), inv_sqrt_l(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const bool keep = l[i] > 1e-10 * max_l;
    sqrt_l[i] = keep ? std::sqrt(l[i]) : 0.0;
    inv_sqrt_l[i] = keep ? 1.0 / std::sqrt(l[i]) : 0.0;
  }
  // H = D^-1 V L V^T D^-1: J = L^1/2 V^T D^-1, r0 = L^-1/2 V^T D b (J^T r0 = b).
  prior->J = sqrt_l.asDiagonal() * eig.eigenvectors().transpose() * d.cwiseInverse().asDiagonal();
  prior->r0 = inv_sqrt_l.asDiagonal() * eig.eigenvectors().transpose() * (d.asDiagonal() * b);
}

class GroundVehicleFunctor {
 public:
  GroundVehicleFunctor(double sigma_lateral, double sigma_vertical)
      : w_lateral_(sigma_lateral > 0 ? 1.0 / sigma_lateral : 0.0),
        w_vertical_(sigma_vertical > 0 ? 1.0 / sigma_vertical : 0.0) {}
  template <typename T>
  bool operator()(const T* pose, const T* speed_bias, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> world_from_body(pose + 3);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> v_world(speed_bias);
    const Eigen::Matrix<T, 3, 1> v_body = world_from_body.conjugate() * v_world;
    residual[0] = T(w_lateral_) * v_body.y();
    residual[1] = T(w_vertical_) * v_body.z();
    return true;
  }

 private:
  double w_lateral_, w_vertical_;
};

class GroundVehiclePairFunctor {
 public:
  GroundVehiclePairFunctor(double dt, double sigma_lateral, double sigma_vertical)
      : w_lateral_(sigma_lateral > 0 ? 1.0 / (sigma_lateral * dt) : 0.0),
        w_vertical_(sigma_vertical > 0 ? 1.0 / (sigma_vertical * dt) : 0.0) {}
  template <typename T>
  bool operator()(const T* pose_a, const T* pose_b, T* residual) const {
    const T zero[2] = {T(0), T(0)};
    return (*this)(pose_a, pose_b, zero, residual);
  }
  template <typename T>
  bool operator()(const T* pose_a, const T* pose_b, const T* boresight, T* residual) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(pose_a), p_b(pose_b);
    const Eigen::Map<const Eigen::Quaternion<T>> world_from_a(pose_a + 3), world_from_b(pose_b + 3);
    // Half of the rotation a -> b: the unit quaternion (1 + w, v) / |.| of the shorter way.
    Eigen::Quaternion<T> a_from_b = world_from_a.conjugate() * world_from_b;
    if (a_from_b.w() < T(0)) a_from_b.coeffs() = -a_from_b.coeffs();
    Eigen::Quaternion<T> a_from_mid(a_from_b.w() + T(1), a_from_b.x(), a_from_b.y(), a_from_b.z());
    a_from_mid.normalize();
    Eigen::Matrix<T, 3, 1> chord = (world_from_a * a_from_mid).conjugate() * (p_b - p_a);
    // Into the vehicle's axes: Ry(pitch)^T Rz(yaw)^T.
    const T cy = cos(boresight[0]), sy = sin(boresight[0]);
    const T cp = cos(boresight[1]), sp = sin(boresight[1]);
    const T x1 = cy * chord.x() + sy * chord.y(), y1 = -sy * chord.x() + cy * chord.y();
    chord = Eigen::Matrix<T, 3, 1>(cp * x1 - sp * chord.z(), y1, sp * x1 + cp * chord.z());
    residual[0] = T(w_lateral_) * chord.y();
    residual[1] = T(w_vertical_) * chord.z();
    return true;
  }

 private:
  double w_lateral_, w_vertical_;
};

}  // namespace

const ceres::Manifold* PoseManifold() {
  static const auto* manifold =
      new ceres::ProductManifold<ceres::EuclideanManifold<3>, ceres::EigenQuaternionManifold>();
  return manifold;
}

ceres::CostFunction* CreateImuFactor(const ImuPreintegration& preintegration,
                                     const Eigen::Vector3d& gravity) {
  return new ceres::AutoDiffCostFunction<ImuFunctor, 15, kPoseSize, kSpeedBiasSize, kPoseSize,
                                         kSpeedBiasSize>(new ImuFunctor(preintegration, gravity));
}

ceres::CostFunction* CreateGroundVehicleFactor(double sigma_lateral_m_s,
                                               double sigma_vertical_m_s) {
  return new ceres::AutoDiffCostFunction<GroundVehicleFunctor, 2, kPoseSize, kSpeedBiasSize>(
      new GroundVehicleFunctor(sigma_lateral_m_s, sigma_vertical_m_s));
}

ceres::CostFunction* CreateGroundVehiclePairFactor(double dt_s, double sigma_lateral_m_s,
                                                   double sigma_vertical_m_s) {
  OPTINAV_CHECK(dt_s > 0);
  return new ceres::AutoDiffCostFunction<GroundVehiclePairFunctor, 2, kPoseSize, kPoseSize>(
      new GroundVehiclePairFunctor(dt_s, sigma_lateral_m_s, sigma_vertical_m_s));
}

ceres::CostFunction* CreateGroundVehiclePairFactorWithBoresight(double dt_s,
                                                                double sigma_lateral_m_s,
                                                                double sigma_vertical_m_s) {
  OPTINAV_CHECK(dt_s > 0);
  return new ceres::AutoDiffCostFunction<GroundVehiclePairFunctor, 2, kPoseSize, kPoseSize, 2>(
      new GroundVehiclePairFunctor(dt_s, sigma_lateral_m_s, sigma_vertical_m_s));
}

ceres::CostFunction* CreateReprojectionFactor(const Rigid3d& cam_from_body,
                                              const Eigen::Vector2d& observed, double focal_px,
                                              double sigma_px) {
  return new ReprojectionCost(cam_from_body, observed, focal_px / sigma_px);
}

namespace {

// ReprojectionCost with its pose block held at a value of its own.
class FixedPoseReprojectionCost : public ceres::SizedCostFunction<2, kPointSize> {
 public:
  FixedPoseReprojectionCost(const Rigid3d& world_from_body, const Rigid3d& cam_from_body,
                            const Eigen::Vector2d& observed, double scale)
      : inner_(cam_from_body, observed, scale) {
    const Eigen::Quaterniond q = world_from_body.rotation.normalized();
    pose_[0] = world_from_body.translation.x();
    pose_[1] = world_from_body.translation.y();
    pose_[2] = world_from_body.translation.z();
    pose_[3] = q.x(), pose_[4] = q.y(), pose_[5] = q.z(), pose_[6] = q.w();
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const double* inner_parameters[2] = {pose_, parameters[0]};
    double* inner_jacobians[2] = {nullptr, jacobians ? jacobians[0] : nullptr};
    return inner_.Evaluate(inner_parameters, residuals, jacobians ? inner_jacobians : nullptr);
  }

 private:
  ReprojectionCost inner_;
  double pose_[kPoseSize];
};

}  // namespace

ceres::CostFunction* CreateFixedPoseReprojectionFactor(const Rigid3d& world_from_body,
                                                       const Rigid3d& cam_from_body,
                                                       const Eigen::Vector2d& observed,
                                                       double focal_px, double sigma_px) {
  return new FixedPoseReprojectionCost(world_from_body, cam_from_body, observed,
                                       focal_px / sigma_px);
}

ceres::CostFunction* CreateAutoDiffReprojectionFactor(const Rigid3d& cam_from_body,
                                                      const Eigen::Vector2d& observed,
                                                      double focal_px, double sigma_px) {
  return new ceres::AutoDiffCostFunction<ReprojectionFunctor, 2, kPoseSize, kPointSize>(
      new ReprojectionFunctor(cam_from_body, observed, focal_px / sigma_px));
}

bool LinearPrior::Involves(const double* values) const {
  return std::any_of(blocks.begin(), blocks.end(),
                     [&](const Block& b) { return b.values == values; });
}

ceres::CostFunction* LinearPrior::CreateCostFunction() const { return new PriorCost(*this); }

LinearPrior Marginalize(const std::vector<const ResidualSpec*>& residuals,
                        const std::vector<double*>& marginalize,
                        const std::function<const ceres::Manifold*(const double*)>& manifold_of,
                        const std::function<int(const double*)>& size_of, bool jacobi_scaling) {
  // Order: marginalised blocks first, then the kept blocks in order of appearance.
  std::vector<double*> order(marginalize.begin(), marginalize.end());
  std::map<const double*, int> index;
  for (size_t i = 0; i < order.size(); ++i) index[order[i]] = static_cast<int>(i);
  for (const ResidualSpec* spec : residuals)
    for (double* b : spec->blocks)
      if (!index.count(b)) {
        index[b] = static_cast<int>(order.size());
        order.push_back(b);
      }
  std::vector<int> offset(order.size() + 1, 0), tangent(order.size()), ambient(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    const ceres::Manifold* m = manifold_of(order[i]);
    ambient[i] = size_of(order[i]);
    tangent[i] = m ? m->TangentSize() : ambient[i];
    offset[i + 1] = offset[i] + tangent[i];
  }
  int m_dim = 0;
  for (size_t i = 0; i < marginalize.size(); ++i) m_dim += tangent[i];
  const int n = offset.back();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);

  for (const ResidualSpec* spec : residuals) {
    const int rows = spec->cost->num_residuals();
    const size_t nb = spec->blocks.size();
    Eigen::VectorXd r(rows);
    std::vector<RowMatrix> jac_global(nb);
    std::vector<double*> jac_ptrs(nb);
    for (size_t k = 0; k < nb; ++k) {
      jac_global[k].resize(rows, size_of(spec->blocks[k]));
      jac_ptrs[k] = jac_global[k].data();
    }
    if (!spec->cost->Evaluate(spec->blocks.data(), r.data(), jac_ptrs.data())) continue;
    // Robust loss: scale by sqrt(rho') (first-order, as iteratively reweighted least squares).
    double weight = 1.0;
    if (spec->loss) {
      double rho[3];
      spec->loss->Evaluate(r.squaredNorm(), rho);
      weight = std::sqrt(std::max(rho[1], 0.0));
    }
    r *= weight;
    std::vector<Eigen::MatrixXd> jac_local(nb);
    for (size_t k = 0; k < nb; ++k) {
      const int idx = index.at(spec->blocks[k]);
      const ceres::Manifold* m = manifold_of(spec->blocks[k]);
      if (m) {
        RowMatrix plus_jac(ambient[idx], tangent[idx]);
        m->PlusJacobian(spec->blocks[k], plus_jac.data());
        jac_local[k] = weight * jac_global[k] * plus_jac;
      } else {
        jac_local[k] = weight * jac_global[k];
      }
    }
    for (size_t k = 0; k < nb; ++k) {
      const int ik = index.at(spec->blocks[k]);
      b.segment(offset[ik], tangent[ik]) += jac_local[k].transpose() * r;
      for (size_t l = 0; l < nb; ++l) {
        const int il = index.at(spec->blocks[l]);
        H.block(offset[ik], offset[il], tangent[ik], tangent[il]) +=
            jac_local[k].transpose() * jac_local[l];
      }
    }
  }

  // Schur complement on the marginalised part (pseudo-inverse: gauge directions of a landmark
  // seen once are rank-deficient). The eigenvalue threshold is applied to the Jacobi-scaled
  // matrix D Hmm D (D = diag(Hmm)^-1/2): the blocks mix units whose information differs by 15
  // orders of magnitude (a bias random walk over 0.2 s against a position known to 15 m), and an
  // unscaled relative threshold would take the weak position directions for gauge directions,
  // dropping their Schur term and leaving an overconfident prior.
  const int r_dim = n - m_dim;
  const Eigen::MatrixXd Hmm =
      0.5 * (H.topLeftCorner(m_dim, m_dim) + H.topLeftCorner(m_dim, m_dim).transpose());
  Eigen::VectorXd d(m_dim);
  for (int i = 0; i < m_dim; ++i)
    d[i] = jacobi_scaling && Hmm(i, i) > 0 ? 1.0 / std::sqrt(Hmm(i, i)) : 1.0;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_mm(d.asDiagonal() * Hmm * d.asDiagonal());
  const Eigen::VectorXd lm = eig_mm.eigenvalues();
  const double max_lm = lm.size() ? std::max(lm.maxCoeff(), 1e-12) : 1.0;
  Eigen::VectorXd inv_lm(lm.size());
  for (int i = 0; i < lm.size(); ++i) inv_lm[i] = lm[i] > 1e-10 * max_lm ? 1.0 / lm[i] : 0.0;
  const Eigen::MatrixXd Hmm_inv = d.asDiagonal() * eig_mm.eigenvectors() * inv_lm.asDiagonal() *
                                  eig_mm.eigenvectors().transpose() * d.asDiagonal();
  const Eigen::MatrixXd Hrm = H.bottomLeftCorner(r_dim, m_dim);
  Eigen::MatrixXd Hs = H.bottomRightCorner(r_dim, r_dim) - Hrm * Hmm_inv * Hrm.transpose();
  Hs = 0.5 * (Hs + Hs.transpose());
  const Eigen::VectorXd bs = b.tail(r_dim) - Hrm * Hmm_inv * b.head(m_dim);

  LinearPrior prior;
  if (r_dim == 0) return prior;
  FactorInformation(Hs, bs, &prior, jacobi_scaling);
  for (size_t i = marginalize.size(); i < order.size(); ++i) {
    LinearPrior::Block block;
    block.values = order[i];
    block.ambient_size = ambient[i];
    block.tangent_size = tangent[i];
    block.manifold = manifold_of(order[i]);
    block.x0.assign(order[i], order[i] + ambient[i]);
    prior.blocks.push_back(block);
  }
  return prior;
}

LinearPrior AddRandomWalk(const LinearPrior& prior, const double* block,
                          const Eigen::MatrixXd& covariance, bool jacobi_scaling) {
  int offset = -1, size = 0, total = 0;
  for (const LinearPrior::Block& b : prior.blocks) {
    if (b.values == block) offset = total, size = b.tangent_size;
    total += b.tangent_size;
  }
  if (offset < 0 || prior.empty()) return prior;
  OPTINAV_CHECK(covariance.rows() == size && covariance.cols() == size);
  // Information over (x, a): H = J^T J, b = J^T r0. With a' = a + w, eliminating a leaves
  //   H'xx = Hxx - Hxa M^-1 Hax,  H'xa' = Hxa M^-1 Q^-1,  H'a'a' = Q^-1 - Q^-1 M^-1 Q^-1,
  //   b'x = bx - Hxa M^-1 ba,     b'a' = Q^-1 M^-1 ba,     M = Haa + Q^-1.
  const Eigen::MatrixXd H = prior.J.transpose() * prior.J;
  const Eigen::VectorXd b = prior.J.transpose() * prior.r0;
  std::vector<int> rest;
  for (int i = 0; i < total; ++i)
    if (i < offset || i >= offset + size) rest.push_back(i);
  const int nx = static_cast<int>(rest.size());
  Eigen::MatrixXd Hxx(nx, nx), Hxa(nx, size);
  Eigen::VectorXd bx(nx);
  for (int i = 0; i < nx; ++i) {
    bx[i] = b[rest[i]];
    for (int j = 0; j < nx; ++j) Hxx(i, j) = H(rest[i], rest[j]);
    for (int j = 0; j < size; ++j) Hxa(i, j) = H(rest[i], offset + j);
  }
  const Eigen::MatrixXd Haa = H.block(offset, offset, size, size);
  const Eigen::VectorXd ba = b.segment(offset, size);
  const Eigen::MatrixXd Qinv = covariance.inverse();
  const Eigen::MatrixXd Minv = (Haa + Qinv).inverse();
  Eigen::MatrixXd Hn(total, total);
  Eigen::VectorXd bn(total);
  const Eigen::MatrixXd Hxx_new = Hxx - Hxa * Minv * Hxa.transpose();
  const Eigen::MatrixXd Hxa_new = Hxa * Minv * Qinv;
  for (int i = 0; i < nx; ++i) {
    bn[rest[i]] = bx[i] - (Hxa.row(i) * Minv * ba)(0);
    for (int j = 0; j < nx; ++j) Hn(rest[i], rest[j]) = Hxx_new(i, j);
    for (int j = 0; j < size; ++j)
      Hn(rest[i], offset + j) = Hn(offset + j, rest[i]) = Hxa_new(i, j);
  }
  Hn.block(offset, offset, size, size) = Qinv - Qinv * Minv * Qinv;
  bn.segment(offset, size) = Qinv * Minv * ba;
  LinearPrior out;
  out.blocks = prior.blocks;
  FactorInformation(Hn, bn, &out, jacobi_scaling);
  return out;
}

}  // namespace optinav::vio
