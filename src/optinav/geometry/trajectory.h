// A trajectory: poses world_from_body, optionally with timestamps (int64 nanoseconds).
// Stored as parallel arrays so position-only work (APE translation, alignment) touches
// only the positions. Rotations are kept as the 3x3 matrices of the source, not re-orthonormalised:
// KITTI files store matrices rounded to a few digits, and evaluation must treat them exactly as
// evo does (inverse = transpose) to reproduce its numbers.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "optinav/geometry/lie.h"

namespace optinav {

struct Trajectory {
  std::vector<int64_t> t_ns;               // empty when the source has no timestamps
  std::vector<Eigen::Vector3d> positions;  // world_from_body translation
  std::vector<Eigen::Matrix3d> rotations;  // world_from_body rotation

  size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_timestamps() const { return !t_ns.empty(); }

  void Reserve(size_t n, bool with_time);
  void Add(int64_t t, const Rigid3d& world_from_body);
  void Add(const Rigid3d& world_from_body);  // for trajectories without timestamps
  // Appends a pose given as a (possibly slightly non-orthonormal) rotation matrix.
  void AddMatrix(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& position);
  // The pose with its rotation as a unit quaternion (nearest rotation).
  Rigid3d pose(size_t i) const;
  Eigen::Quaterniond quaternion(size_t i) const;

  // Keeps the poses at `indices` (in that order, repeats allowed).
  Trajectory Subset(const std::vector<size_t>& indices) const;
  // The same in place; no allocation when the indices strictly increase.
  void KeepOnly(const std::vector<size_t>& indices);

  // Left-multiplies every pose by a similarity (scale applies to positions only).
  void Transform(const Sim3d& target_from_source);
  // Same with an explicit matrix: R_i <- r R_i, p_i <- scale r p_i + t.
  void Transform(double scale, const Eigen::Matrix3d& r, const Eigen::Vector3d& t);

  // Sum of distances between consecutive positions (metres).
  double PathLength() const;

  // Pose at `t` by slerp/linear interpolation between the bracketing samples; nullopt outside
  // [t_front, t_back] or without timestamps. Binary search: O(log n).
  std::optional<Rigid3d> InterpolateAt(int64_t t) const;
};

}  // namespace optinav
