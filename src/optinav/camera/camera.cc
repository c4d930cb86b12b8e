#include "optinav/camera/camera.h"

#include <cmath>
#include <limits>

#include <Eigen/SVD>

#include "optinav/util/error.h"

namespace optinav::camera {

DistortionModel ParseDistortionModel(const std::string& name) {
  if (name == "none" || name.empty()) return DistortionModel::kNone;
  if (name == "radial-tangential" || name == "radtan") return DistortionModel::kRadialTangential;
  if (name == "equidistant" || name == "equi" || name == "fisheye") {
    return DistortionModel::kEquidistant;
  }
  throw Error("unknown distortion model '" + name +
              "' (expected none, radial-tangential or equidistant)");
}

std::string DistortionModelName(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadialTangential:
      return "radial-tangential";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "none";
}

PinholeCamera PinholeCamera::FromHorizontalFov(int width, int height, double hfov_rad) {
  if (!(hfov_rad > 0 && hfov_rad < M_PI)) {
    throw Error("horizontal field of view must be in (0, 180) deg");
  }
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 0.5 * width / std::tan(0.5 * hfov_rad);
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  c.Validate();
  return c;
}

void PinholeCamera::Validate() const {
  if (width <= 0 || height <= 0) {
    throw Error("camera resolution must be positive, got " + std::to_string(width) + "x" +
                    std::to_string(height),
                {.field = "resolution"});
  }
  if (!(fx > 0) || !(fy > 0) || !std::isfinite(fx) || !std::isfinite(fy) || !std::isfinite(cx) ||
      !std::isfinite(cy)) {
    throw Error("camera intrinsics must be finite with positive focal lengths",
                {.field = "intrinsics"});
  }
  for (double k : coeffs) {
    if (!std::isfinite(k)) {
      throw Error("camera distortion coefficients must be finite",
                  {.field = "distortion_coefficients"});
    }
  }
}

Eigen::Matrix3d PinholeCamera::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

PinholeCamera PinholeCamera::Scaled(double factor) const {
  PinholeCamera c = *this;
  c.width = static_cast<int>(std::lround(width * factor));
  c.height = static_cast<int>(std::lround(height * factor));
  c.fx = fx * factor;
  c.fy = fy * factor;
  // Pixel centres: continuous coordinate u + 0.5 scales, so c' = (c + 0.5) * f - 0.5.
  c.cx = (cx + 0.5) * factor - 0.5;
  c.cy = (cy + 0.5) * factor - 0.5;
  return c;
}

Eigen::Vector2d PinholeCamera::Distort(const Eigen::Vector2d& n) const {
  switch (distortion) {
    case DistortionModel::kNone:
      return n;
    case DistortionModel::kRadialTangential: {
      const double k1 = coeffs[0], k2 = coeffs[1], p1 = coeffs[2], p2 = coeffs[3];
      const double x = n.x(), y = n.y();
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (k1 + r2 * k2);
      return {x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
              y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y};
    }
    case DistortionModel::kEquidistant: {
      const double r = n.norm();
      if (r < 1e-12) return n;
      const double th = std::atan(r), th2 = th * th;
      const double thd =
          th * (1 + th2 * (coeffs[0] + th2 * (coeffs[1] + th2 * (coeffs[2] + th2 * coeffs[3]))));
      return n * (thd / r);
    }
  }
  return n;
}

Eigen::Vector2d PinholeCamera::Undistort(const Eigen::Vector2d& d) const {
  if (distortion == DistortionModel::kNone) return d;
  if (distortion == DistortionModel::kEquidistant) {
    // Invert theta_d(theta) by Newton, then r = tan(theta).
    const double rd = d.norm();
    if (rd < 1e-12) return d;
    double th = rd;
    for (int it = 0; it < 20; ++it) {
      const double th2 = th * th;
      const double f =
          th * (1 + th2 * (coeffs[0] + th2 * (coeffs[1] + th2 * (coeffs[2] + th2 * coeffs[3])))) -
          rd;
      const double df =
          1 + th2 * (3 * coeffs[0] +
                     th2 * (5 * coeffs[1] + th2 * (7 * coeffs[2] + th2 * 9 * coeffs[3])));
      const double step = f / df;
      th -= step;
      if (std::abs(step) < 1e-14) break;
    }
    return d * (std::tan(th) / rd);
  }
  // Radial-tangential: Gauss-Newton on Distort(n) = d with a numeric Jacobian.
  Eigen::Vector2d n = d;
  for (int it = 0; it < 20; ++it) {
    const Eigen::Vector2d r = Distort(n) - d;
    if (r.squaredNorm() < 1e-26) break;
    Eigen::Matrix2d j;
    const double h = 1e-7;
    for (int c = 0; c < 2; ++c) {
      Eigen::Vector2d np = n;
      np[c] += h;
      j.col(c) = (Distort(np) - Distort(n)) / h;
    }
    n -= j.partialPivLu().solve(r);
  }
  return n;
}

Eigen::Vector2d PinholeCamera::NormalizedToPixel(const Eigen::Vector2d& normalized) const {
  const Eigen::Vector2d d = Distort(normalized);
  return {fx * d.x() + cx, fy * d.y() + cy};
}

std::optional<Eigen::Vector2d> PinholeCamera::Project(const Eigen::Vector3d& p_in_cam) const {
  if (!(p_in_cam.z() > 1e-9)) return std::nullopt;
  return NormalizedToPixel(p_in_cam.head<2>() / p_in_cam.z());
}

Eigen::Vector2d PinholeCamera::PixelToNormalized(const Eigen::Vector2d& pixel) const {
  return Undistort({(pixel.x() - cx) / fx, (pixel.y() - cy) / fy});
}

Eigen::Vector3d PinholeCamera::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d n = PixelToNormalized(pixel);
  return {n.x(), n.y(), 1.0};
}

bool PinholeCamera::InImage(const Eigen::Vector2d& pixel, double border) const {
  return pixel.x() >= border - 0.5 && pixel.y() >= border - 0.5 &&
         pixel.x() <= width - 0.5 - border && pixel.y() <= height - 0.5 - border;
}

Eigen::Matrix3d StereoRig::Essential() const {
  return Hat(right_from_left.translation) * right_from_left.rotation.toRotationMatrix();
}

double EpipolarDistance(const Eigen::Matrix3d& essential, const Eigen::Vector2d& left_normalized,
                        const Eigen::Vector2d& right_normalized) {
  const Eigen::Vector3d line = essential * left_normalized.homogeneous();
  const double scale = line.head<2>().norm();
  if (!(scale > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(right_normalized.homogeneous().dot(line)) / scale;
}

std::optional<Eigen::Vector3d> TriangulateTwoView(const Rigid3d& cam1_from_world,
                                                  const Rigid3d& cam2_from_world,
                                                  const Eigen::Vector2d& n1,
                                                  const Eigen::Vector2d& n2) {
  const Eigen::Matrix<double, 3, 4> p1 = cam1_from_world.ToMatrix3x4();
  const Eigen::Matrix<double, 3, 4> p2 = cam2_from_world.ToMatrix3x4();
  Eigen::Matrix4d a;
  a.row(0) = n1.x() * p1.row(2) - p1.row(0);
  a.row(1) = n1.y() * p1.row(2) - p1.row(1);
  a.row(2) = n2.x() * p2.row(2) - p2.row(0);
  a.row(3) = n2.y() * p2.row(2) - p2.row(1);
  Eigen::JacobiSVD<Eigen::Matrix4d> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  if (std::abs(h[3]) < 1e-12) return std::nullopt;
  const Eigen::Vector3d p = h.head<3>() / h[3];
  // Parallel rays: the smallest singular value is not separated from the next.
  const auto& s = svd.singularValues();
  if (s[2] < 1e-12 * s[0]) return std::nullopt;
  if ((cam1_from_world * p).z() <= 0 || (cam2_from_world * p).z() <= 0) return std::nullopt;
  return p;
}

}  // namespace optinav::camera
