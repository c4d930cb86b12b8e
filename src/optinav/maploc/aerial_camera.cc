#include "optinav/maploc/aerial_camera.h"

#include <cmath>

#include <Eigen/Dense>

#include "optinav/geometry/angles.h"

namespace optinav::maploc {

namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d Scale(double gsd) { return Eigen::Vector3d(gsd, gsd, 1.0).asDiagonal(); }

// [r1 r2 t] of cam_from_ground: ground (X, Y, 1) -> camera coordinates.
Eigen::Matrix3d PlaneToCamera(const Rigid3d& ground_from_camera) {
  const Eigen::Matrix3d r_cg = ground_from_camera.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d t_cg = -r_cg * ground_from_camera.translation;
  Eigen::Matrix3d m;
  m << r_cg.col(0), r_cg.col(1), t_cg;
  return m;
}

}  // namespace

Eigen::Matrix3d NedFromBody(const Attitude& a) {
  return (Eigen::AngleAxisd(a.yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(a.pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(a.roll_deg * kDeg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Attitude AttitudeOf(const Eigen::Matrix3d& r) {
  Attitude a;
  a.yaw_deg = std::atan2(r(1, 0), r(0, 0)) / kDeg;
  if (a.yaw_deg < 0) a.yaw_deg += 360.0;
  a.pitch_deg = std::asin(std::clamp(-r(2, 0), -1.0, 1.0)) / kDeg;
  a.roll_deg = std::atan2(r(2, 1), r(2, 2)) / kDeg;
  return a;
}

Eigen::Matrix3d BodyFromCamera() {
  Eigen::Matrix3d b;
  // Columns: camera x (image right) = right wing, camera y (image down) = tail, z = down.
  b << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  return b;
}

Eigen::Matrix3d GroundFromNed() {
  Eigen::Matrix3d g;
  g << 0, 1, 0, -1, 0, 0, 0, 0, 1;
  return g;
}

Rigid3d GroundFromCamera(const AerialPose& pose, double map_gsd_m) {
  const Eigen::Matrix3d r = GroundFromNed() * NedFromBody(pose.attitude) * BodyFromCamera();
  return Rigid3d(Eigen::Quaterniond(r),
                 Eigen::Vector3d(pose.nadir_px.x() * map_gsd_m, pose.nadir_px.y() * map_gsd_m,
                                 -pose.altitude_m));
}

AerialPose PoseOfCamera(const Rigid3d& ground_from_camera, double map_gsd_m) {
  const Eigen::Matrix3d r_gc = ground_from_camera.rotation.toRotationMatrix();
  const Eigen::Matrix3d ned_from_body =
      GroundFromNed().transpose() * r_gc * BodyFromCamera().transpose();
  AerialPose p;
  p.attitude = AttitudeOf(ned_from_body);
  const Eigen::Vector3d& c = ground_from_camera.translation;
  p.nadir_px = c.head<2>() / map_gsd_m;
  p.altitude_m = -c.z();
  return p;
}

Eigen::Matrix3d MapFromImage(const AerialPose& pose, const Eigen::Matrix3d& K, double map_gsd_m) {
  const Eigen::Matrix3d image_from_ground = K * PlaneToCamera(GroundFromCamera(pose, map_gsd_m));
  return Scale(1.0 / map_gsd_m) * image_from_ground.inverse();
}

std::optional<AerialPose> PoseFromHomography(const Eigen::Matrix3d& map_from_image,
                                             const Eigen::Matrix3d& K, double map_gsd_m) {
  const Eigen::Matrix3d ground_from_image = Scale(map_gsd_m) * map_from_image;
  if (!ground_from_image.allFinite() || std::abs(ground_from_image.determinant()) < 1e-300) {
    return std::nullopt;
  }
  Eigen::Matrix3d m = K.inverse() * ground_from_image.inverse();  // ~ [r1 r2 t]
  const double norm = 0.5 * (m.col(0).norm() + m.col(1).norm());
  if (!(norm > 0)) return std::nullopt;
  m /= norm;
  // The ground point seen at the principal point must lie in front of the camera.
  const Eigen::Vector3d g = ground_from_image * Eigen::Vector3d(K(0, 2), K(1, 2), 1.0);
  if (std::abs(g.z()) < 1e-300) return std::nullopt;
  if ((m * (g / g.z())).z() < 0) m = -m;
  Eigen::Matrix3d r;
  r << m.col(0), m.col(1), m.col(0).cross(m.col(1));
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r_cg = svd.matrixU() * svd.matrixV().transpose();
  if (r_cg.determinant() < 0) return std::nullopt;
  const Eigen::Vector3d centre = -r_cg.transpose() * m.col(2);
  if (!(centre.z() < 0) || !centre.allFinite()) return std::nullopt;  // below the ground
  return PoseOfCamera(Rigid3d(Eigen::Quaterniond(r_cg.transpose()), centre), map_gsd_m);
}

namespace {

// The refinement's state: ground_from_camera rotation and the camera centre (metres).
struct State {
  Eigen::Matrix3d r_gc;
  Eigen::Vector3d c;
  State Plus(const Eigen::Matrix<double, 6, 1>& d) const {
    State s;
    const Eigen::Vector3d w = d.head<3>();
    s.r_gc = r_gc * (w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix()
                                  : Eigen::Matrix3d::Identity());
    s.c = c + d.tail<3>();
    return s;
  }
};

}  // namespace

PoseEstimate RefinePose(const std::vector<Eigen::Vector2d>& image_px,
                        const std::vector<Eigen::Vector2d>& map_px, const Eigen::Matrix3d& K,
                        double map_gsd_m, const AerialPose& initial, const PosePriors& priors) {
  const Rigid3d g0 = GroundFromCamera(initial, map_gsd_m);
  State s{g0.rotation.toRotationMatrix(), g0.translation};
  const size_t n = std::min(image_px.size(), map_px.size());
  const int n_prior = (priors.roll_deg ? 1 : 0) + (priors.pitch_deg ? 1 : 0) +
                      (priors.altitude_m && *priors.altitude_m > 0 ? 1 : 0);
  const int rows = static_cast<int>(2 * n) + n_prior;
  // Residuals in sigmas; `weights` are the Huber weights of the image residuals (1 for priors).
  auto residuals = [&](const State& st) {
    Eigen::VectorXd r(rows);
    const Eigen::Matrix3d r_cg = st.r_gc.transpose();
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d xg(map_px[i].x() * map_gsd_m, map_px[i].y() * map_gsd_m, 0.0);
      const Eigen::Vector3d p = K * (r_cg * (xg - st.c));
      const double z = std::abs(p.z()) > 1e-9 ? p.z() : 1e-9;
      r(2 * i) = (p.x() / z - image_px[i].x()) / priors.pixel_sigma;
      r(2 * i + 1) = (p.y() / z - image_px[i].y()) / priors.pixel_sigma;
    }
    int k = static_cast<int>(2 * n);
    const AerialPose pose = PoseOfCamera(Rigid3d(Eigen::Quaterniond(st.r_gc), st.c), map_gsd_m);
    if (priors.roll_deg) {
      r(k++) = WrapDeg180(pose.attitude.roll_deg - *priors.roll_deg) / priors.attitude_sigma_deg;
    }
    if (priors.pitch_deg) {
      r(k++) = (pose.attitude.pitch_deg - *priors.pitch_deg) / priors.attitude_sigma_deg;
    }
    if (priors.altitude_m && *priors.altitude_m > 0) {
      r(k++) =
          (pose.altitude_m - *priors.altitude_m) / (priors.altitude_sigma_rel * *priors.altitude_m);
    }
    return r;
  };
  constexpr double kHuber = 2.0;  // sigmas
  auto huber_weights = [&](const Eigen::VectorXd& r) {
    Eigen::VectorXd w = Eigen::VectorXd::Ones(rows);
    for (size_t i = 0; i < n; ++i) {
      const double e = std::hypot(r(2 * i), r(2 * i + 1));
      const double wi = e <= kHuber ? 1.0 : kHuber / e;
      w(2 * i) = w(2 * i + 1) = wi;
    }
    return w;
  };
  auto cost = [&](const Eigen::VectorXd& r, const Eigen::VectorXd& w) {
    return (w.array() * r.array().square()).sum();
  };
  // Central differences: rotation steps in radians, position steps scaled by the altitude.
  Eigen::Matrix<double, Eigen::Dynamic, 6> jac(rows, 6);
  auto update_jacobian = [&](const State& at) {
    for (int j = 0; j < 6; ++j) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      const double h = j < 3 ? 1e-6 : 1e-4 * std::max(1.0, std::abs(at.c.z()));
      d(j) = h;
      const Eigen::VectorXd rp = residuals(at.Plus(d));
      d(j) = -h;
      jac.col(j) = (rp - residuals(at.Plus(d))) / (2 * h);
    }
  };
  Eigen::VectorXd r = residuals(s);
  Eigen::VectorXd w = huber_weights(r);
  double lambda = 1e-3;
  for (int iter = 0; iter < 20 && n >= 4; ++iter) {
    update_jacobian(s);
    const Eigen::Matrix<double, 6, 6> a = jac.transpose() * w.asDiagonal() * jac;
    const Eigen::Matrix<double, 6, 1> b = -jac.transpose() * (w.asDiagonal() * r);
    const double c0 = cost(r, w);
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Eigen::Matrix<double, 6, 6> damped = a;
      damped.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 6, 1> d = damped.ldlt().solve(b);
      if (!d.allFinite()) break;
      const State cand = s.Plus(d);
      const Eigen::VectorXd rc = residuals(cand);
      if (cost(rc, w) < c0) {
        s = cand;
        r = rc;
        lambda = std::max(1e-7, lambda / 10);
        improved = true;
        if (d.norm() < 1e-9) iter = 100;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
    w = huber_weights(r);
  }
  PoseEstimate out;
  out.pose = PoseOfCamera(Rigid3d(Eigen::Quaterniond(s.r_gc), s.c), map_gsd_m);
  double sq = 0;
  for (size_t i = 0; i < n; ++i) sq += r(2 * i) * r(2 * i) + r(2 * i + 1) * r(2 * i + 1);
  out.rms_px = n > 0 ? std::sqrt(sq / (2.0 * n)) * priors.pixel_sigma : 0;
  // Covariance of the centre from the (weighted) normal equations, scaled by the residual spread
  // when it exceeds the assumed pixel sigma.
  if (n >= 4) {
    update_jacobian(s);
    const Eigen::Matrix<double, 6, 6> info = jac.transpose() * w.asDiagonal() * jac;
    const Eigen::Matrix<double, 6, 6> cov = info.inverse();
    const double spread = std::max(1.0, out.rms_px / priors.pixel_sigma);
    const Eigen::Matrix2d cxy = cov.block<2, 2>(3, 3) * spread * spread;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cxy);
    out.horizontal_sigma_m = std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()));
    if (!std::isfinite(out.horizontal_sigma_m)) out.horizontal_sigma_m = 0;
  }
  return out;
}

Eigen::Matrix3d NadirFromImage(const Eigen::Matrix3d& K, double roll_deg, double pitch_deg) {
  const Eigen::Matrix3d b = BodyFromCamera();
  const Eigen::Matrix3d nadir_from_camera =
      b.transpose() * NedFromBody({.roll_deg = roll_deg, .pitch_deg = pitch_deg}) * b;
  return K * nadir_from_camera * K.inverse();
}

}  // namespace optinav::maploc
