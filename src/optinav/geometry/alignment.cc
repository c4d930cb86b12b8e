#include "optinav/geometry/alignment.h"

#include <cmath>
#include <limits>
#include <string>

#include <Eigen/SVD>

#include "optinav/util/error.h"

namespace optinav {
namespace {

size_t CheckedPairCount(const std::vector<Eigen::Vector3d>& source,
                        const std::vector<Eigen::Vector3d>& target, size_t max_pairs) {
  if (source.size() != target.size()) {
    throw Error("alignment needs the same number of source and target points (" +
                std::to_string(source.size()) + " vs " + std::to_string(target.size()) + ")");
  }
  const size_t n = max_pairs > 0 ? std::min(max_pairs, source.size()) : source.size();
  if (n < 3) {
    throw Error("alignment needs at least 3 pose pairs, got " + std::to_string(n));
  }
  return n;
}

}  // namespace

Sim3d UmeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                       const std::vector<Eigen::Vector3d>& target, bool with_scale,
                       size_t max_pairs) {
  const size_t n = CheckedPairCount(source, target, max_pairs);
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero(), mean_y = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_x += source[i];
    mean_y += target[i];
  }
  mean_x /= static_cast<double>(n);
  mean_y /= static_cast<double>(n);
  // Second pass on centred data keeps precision for large offsets (e.g. UTM coordinates).
  double sigma_x = 0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d dx = source[i] - mean_x;
    sigma_x += dx.squaredNorm();
    cov.noalias() += (target[i] - mean_y) * dx.transpose();
  }
  sigma_x /= static_cast<double>(n);
  cov /= static_cast<double>(n);

  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  int rank = 0;
  for (int i = 0; i < 3; ++i) rank += d[i] > std::numeric_limits<double>::epsilon();
  if (rank < 2) {
    throw Error("degenerate point configuration (covariance rank " + std::to_string(rank) +
                "): alignment is not possible");
  }
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) s(2, 2) = -1;
  const Eigen::Matrix3d r = svd.matrixU() * s * svd.matrixV().transpose();
  Sim3d out;
  out.scale = with_scale ? (d.asDiagonal() * s).trace() / sigma_x : 1.0;
  out.rotation = Eigen::Quaterniond(r).normalized();
  out.translation = mean_y - out.scale * (r * mean_x);
  return out;
}

Sim3d PositionYawAlignment(const std::vector<Eigen::Vector3d>& source,
                           const std::vector<Eigen::Vector3d>& target, size_t max_pairs) {
  const size_t n = CheckedPairCount(source, target, max_pairs);
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero(), mean_y = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_x += source[i];
    mean_y += target[i];
  }
  mean_x /= static_cast<double>(n);
  mean_y /= static_cast<double>(n);
  // Maximise sum y_i . Rz(yaw) x_i over the horizontal components: yaw = atan2(B, A).
  double a = 0, b = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = source[i] - mean_x;
    const Eigen::Vector3d y = target[i] - mean_y;
    a += x.x() * y.x() + x.y() * y.y();
    b += x.x() * y.y() - x.y() * y.x();
  }
  if (std::hypot(a, b) <= std::numeric_limits<double>::epsilon()) {
    throw Error("degenerate point configuration: no horizontal spread to determine yaw");
  }
  const double yaw = std::atan2(b, a);
  Sim3d out;
  out.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  out.translation = mean_y - out.rotation * mean_x;
  return out;
}

}  // namespace optinav
