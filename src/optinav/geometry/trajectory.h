// A trajectory: poses world_from_body, optionally with timestamps (int64 nanoseconds).
// Stored as parallel arrays so position-only work (APE translation, alignment) touches
// only the positions.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "optinav/geometry/lie.h"

namespace optinav {

struct Trajectory {
  std::vector<int64_t> t_ns;                    // empty when the source has no timestamps
  std::vector<Eigen::Vector3d> positions;       // world_from_body translation
  std::vector<Eigen::Quaterniond> rotations;    // world_from_body rotation

  size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_timestamps() const { return !t_ns.empty(); }

  void Reserve(size_t n, bool with_time);
  void Add(int64_t t, const Rigid3d& world_from_body);
  void Add(const Rigid3d& world_from_body);  // for trajectories without timestamps
  Rigid3d pose(size_t i) const { return {rotations[i], positions[i]}; }

  // Keeps the poses at `indices` (in that order, repeats allowed).
  Trajectory Subset(const std::vector<size_t>& indices) const;

  // Left-multiplies every pose by a similarity (scale applies to positions only).
  void Transform(const Sim3d& target_from_source);

  // Sum of distances between consecutive positions (metres).
  double PathLength() const;

  // Pose at `t` by slerp/linear interpolation between the bracketing samples; nullopt outside
  // [t_front, t_back] or without timestamps. Binary search: O(log n).
  std::optional<Rigid3d> InterpolateAt(int64_t t) const;
};

}  // namespace optinav
