#include "optinav/geometry/trajectory.h"

#include <algorithm>

namespace optinav {

void Trajectory::Reserve(size_t n, bool with_time) {
  positions.reserve(n);
  rotations.reserve(n);
  if (with_time) t_ns.reserve(n);
}

void Trajectory::Add(int64_t t, const Rigid3d& pose) {
  t_ns.push_back(t);
  Add(pose);
}

void Trajectory::Add(const Rigid3d& pose) {
  positions.push_back(pose.translation);
  rotations.push_back(pose.rotation.toRotationMatrix());
}

void Trajectory::AddMatrix(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& position) {
  positions.push_back(position);
  rotations.push_back(rotation);
}

Eigen::Quaterniond Trajectory::quaternion(size_t i) const {
  return Eigen::Quaterniond(rotations[i]).normalized();
}

Rigid3d Trajectory::pose(size_t i) const { return {quaternion(i), positions[i]}; }

Trajectory Trajectory::Subset(const std::vector<size_t>& indices) const {
  Trajectory out;
  out.Reserve(indices.size(), has_timestamps());
  for (size_t i : indices) {
    if (has_timestamps()) out.t_ns.push_back(t_ns[i]);
    out.positions.push_back(positions[i]);
    out.rotations.push_back(rotations[i]);
  }
  return out;
}

void Trajectory::KeepOnly(const std::vector<size_t>& indices) {
  bool increasing = true;
  for (size_t k = 1; k < indices.size() && increasing; ++k)
    increasing = indices[k] > indices[k - 1];
  if (!increasing) {
    *this = Subset(indices);
    return;
  }
  // indices[k] >= k, so copying forward never reads an overwritten element.
  for (size_t k = 0; k < indices.size(); ++k) {
    const size_t i = indices[k];
    if (i == k) continue;
    if (has_timestamps()) t_ns[k] = t_ns[i];
    positions[k] = positions[i];
    rotations[k] = rotations[i];
  }
  if (has_timestamps()) t_ns.resize(indices.size());
  positions.resize(indices.size());
  rotations.resize(indices.size());
}

void Trajectory::Transform(const Sim3d& s) {
  Transform(s.scale, s.rotation.toRotationMatrix(), s.translation);
}

void Trajectory::Transform(double scale, const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  const Eigen::Matrix3d sr = scale * r;
  for (auto& p : positions) p = sr * p + t;
  for (auto& rot : rotations) rot = r * rot;
}

double Trajectory::PathLength() const {
  double length = 0;
  for (size_t i = 1; i < positions.size(); ++i) length += (positions[i] - positions[i - 1]).norm();
  return length;
}

std::optional<Rigid3d> Trajectory::InterpolateAt(int64_t t) const {
  if (!has_timestamps() || t < t_ns.front() || t > t_ns.back()) return std::nullopt;
  const auto it = std::lower_bound(t_ns.begin(), t_ns.end(), t);
  const size_t j = static_cast<size_t>(it - t_ns.begin());
  if (t_ns[j] == t) return pose(j);
  const size_t i = j - 1;
  const double alpha = static_cast<double>(t - t_ns[i]) / static_cast<double>(t_ns[j] - t_ns[i]);
  return InterpolatePose(pose(i), pose(j), alpha);
}

}  // namespace optinav
