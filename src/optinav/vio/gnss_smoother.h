// Smoothing of the GNSS fusion over the whole run: the live output maps each frame to ENU with the
// alignment known right after it, a causal estimate that moves with every GNSS sample (with 3 m
// noise it bends the trajectory's shape by more than the VIO drifts). The smoother re-estimates
// the alignment enu_from_world at every frame from all the samples the fusion accepted, earlier
// and later, under the same drift model (a random walk of [tx, ty, tz, yaw] per metre travelled,
// plus the inflations the fusion's drift test made), in one batch least-squares problem per VIO
// track:
//   walk  (frame i -> i+1):  (Rz(y_i+1) p_i + t_i+1 - Rz(y_i) p_i - t_i) / sigma_t,
//                            (y_i+1 - y_i) / sigma_yaw
//   GNSS  (sample at t):     (Rz(y_i) antenna_world(t) + t_i - z) / sigma, with the fusion's norm
// where p_i is the frame's world position and antenna_world(t) the VIO pose interpolated to t with
// the lever arm. The VIO trajectory in the world frame is kept as it is: only how it sits in ENU
// changes, slowly, where the GNSS says it drifted.
#pragma once

#include <optional>
#include <vector>

#include "optinav/geometry/trajectory.h"
#include "optinav/vio/estimator.h"
#include "optinav/vio/gnss_fusion.h"

namespace optinav::vio {

struct GnssSmoothing {
  // Per estimate (same order): the smoothed enu_from_world; nullopt where the live output has no
  // alignment either. A track with fewer than 3 accepted samples keeps its live alignments.
  std::vector<std::optional<WorldAlignment>> enu_from_world;
  int tracks_smoothed = 0;
  size_t samples = 0;
  double solve_s = 0;
};

// The live alignment of every estimate: each frame's own, frames before the first alignment the
// first one (all nullopt when there is none).
std::vector<std::optional<WorldAlignment>> LiveAlignments(
    const std::vector<FrameEstimate>& estimates);

// `estimates` in time order (world frame, with the live alignments); `track_starts`: the index of
// the first estimate of each VIO track after the first (VioRunResult::track_starts); `used` /
// `inflations` as GnssFusion records them (`inflations` in time order).
GnssSmoothing SmoothGnssAlignment(const std::vector<FrameEstimate>& estimates,
                                  const std::vector<size_t>& track_starts,
                                  const std::vector<GnssSample>& used,
                                  const std::vector<AlignmentInflation>& inflations,
                                  const GnssFusionOptions& options);

// The estimates (of the body, or of the left camera with body_from_cam) in ENU through
// per-estimate alignments (as from GnssSmoothing); estimates without one are left out.
Trajectory EstimatesToEnuTrajectory(
    const std::vector<FrameEstimate>& estimates,
    const std::vector<std::optional<WorldAlignment>>& enu_from_world,
    const std::optional<Rigid3d>& body_from_cam = std::nullopt);

}  // namespace optinav::vio
