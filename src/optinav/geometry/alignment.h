// Least-squares alignment of point sets (and hence trajectories by their positions).
//
// Umeyama (1991), "Least-squares estimation of transformation parameters between two point
// patterns": finds target_from_source minimising sum |target_i - (c R source_i + t)|^2, the way
// evo's trajectory alignment uses it (scale c = 1 unless with_scale).
#pragma once

#include <vector>

#include "optinav/geometry/lie.h"

namespace optinav {

// Throws optinav::Error when there are fewer than 3 pairs, the sizes differ, or the points are
// degenerate (covariance rank below 2), which makes the rotation undetermined.
Sim3d UmeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                       const std::vector<Eigen::Vector3d>& target, bool with_scale,
                       size_t max_pairs = 0);

// 4-DoF alignment: rotation about the gravity axis z (yaw) and translation, no scale. The right
// choice for visual-inertial estimates, whose roll and pitch are observable.
// Throws optinav::Error when there are fewer than 3 pairs or the horizontal spread is zero.
Sim3d PositionYawAlignment(const std::vector<Eigen::Vector3d>& source,
                           const std::vector<Eigen::Vector3d>& target, size_t max_pairs = 0);

}  // namespace optinav
