// Trajectory evaluation with the definitions of evo (github.com/MichaelGrupp/evo), the field's
// reference tool, so numbers are comparable with published ones:
//
//  association   for every stamp of the trajectory with fewer poses, the nearest stamp of the
//                other (first of equals), kept if |dt| <= max_diff; the offset is added to the
//                estimate's stamps. Trajectories without timestamps are matched by index.
//  alignment     Umeyama on the positions (SE3, Sim3, scale only as evo's --correct_scale alone),
//                or 4-DoF position + yaw; optionally on the first N pairs; then optionally
//                --align-origin (est <- ref_0 * est_0^-1 * est).
//  APE           E_i = P_i^-1 Q_i per pose (P estimate, Q reference).
//  RPE           E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), pairs (i, j) chosen on the estimate.
//  relations     trans: |t(E)|; rot: |R(E) - I|_F; full: |E - I|_F; angle_rad / angle_deg:
//                the rotation angle of R(E).
//  statistics    n, rmse, mean, median, std (population), min, max, sse (util/statistics.h).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "optinav/geometry/trajectory.h"
#include "optinav/util/error.h"
#include "optinav/util/statistics.h"

namespace optinav::eval {

struct AssociationOptions {
  double max_diff_s = 0.01;  // largest accepted |t_ref - (t_est + t_offset)|, seconds
  double t_offset_s = 0.0;   // added to the estimate's timestamps, seconds
};

// The two trajectories reduced to matched pairs, in the same order.
struct SyncedPair {
  Trajectory ref, est;
  std::vector<size_t> ref_indices, est_indices;  // indices into the inputs
  size_t max_pairs = 0;                          // size of the shorter input
  bool by_index = false;                         // true when matched by index (no timestamps)
};

// Throws Error when nothing matches, or when index matching is needed and the sizes differ.
// Takes the trajectories by value: pass them with std::move to filter them in place.
SyncedPair Synchronize(Trajectory ref, Trajectory est, const AssociationOptions& options = {});

enum class AlignMode { kNone, kSe3, kSim3, kScale, kPosYaw };
std::optional<AlignMode> ParseAlignMode(const std::string& name);  // none|se3|sim3|scale|posyaw
std::string AlignModeName(AlignMode mode);

struct AlignmentOptions {
  AlignMode mode = AlignMode::kNone;
  size_t n_to_align = 0;      // 0: all pairs; else only the first N
  bool align_origin = false;  // afterwards, make the first poses coincide
};

struct AlignmentResult {
  AlignmentOptions options;
  // The similarity applied to the estimate by the mode (identity for kNone) ...
  Sim3d ref_from_est;
  // ... followed, with align_origin, by this rigid transform.
  std::optional<Rigid3d> origin_correction;
  // The overall transform applied to the estimate's poses (4x4, scale in the top-left block).
  Eigen::Matrix4d Total() const;
};

// Aligns `est` (in place) to `ref`; both must be synchronized pairs. Throws Error when the
// alignment is impossible (fewer than 3 pairs, degenerate positions).
AlignmentResult AlignTrajectory(const Trajectory& ref, Trajectory* est,
                                const AlignmentOptions& options);

enum class PoseRelation { kTranslation, kRotation, kFull, kAngleRad, kAngleDeg };
std::optional<PoseRelation> ParsePoseRelation(const std::string& name);
std::string PoseRelationName(PoseRelation relation);   // as on the command line
std::string PoseRelationTitle(PoseRelation relation);  // "translation part", ...
std::string PoseRelationUnit(PoseRelation relation);   // "m", "deg", "rad" or "" (unit-less)

// The project's one definition (util/statistics.h): evo's figures (median of an even count the
// mean of the two middle values, population std), plus p95. Throws Error for an empty input.
using Statistics = optinav::Statistics;
using optinav::ComputeStatistics;

// Errors of one metric, one per pose (APE) or per pair (RPE).
struct ErrorSeries {
  std::vector<double> errors;
  std::vector<size_t> indices;  // index into the synced pair: the pose, or a pair's second pose
  Statistics stats;
};

ErrorSeries ComputeApe(const Trajectory& ref, const Trajectory& est, PoseRelation relation);

// The weather document's metric (docs SEEDS.md part 1, "mean localization error"): the estimate
// put on the reference's first pose (est <- ref_0 * est_0^-1 * est, no fit over the run, so
// drift counts in full as it does for a SLAM system started at a known pose), then the mean over
// all pairs of the Euclidean distance between the positions. `ref` and `est` are a synchronized
// pair (Synchronize()); throws Error when they are empty or of different sizes.
double MeanErrorAfterStartPose(const Trajectory& ref, const Trajectory& est);

enum class DeltaUnit { kFrames, kMeters, kSeconds, kRadians, kDegrees };
std::optional<DeltaUnit> ParseDeltaUnit(const std::string& name);  // frames|m|s|rad|deg
std::string DeltaUnitName(DeltaUnit unit);

struct RpeOptions {
  double delta = 1.0;
  DeltaUnit unit = DeltaUnit::kFrames;
  PoseRelation relation = PoseRelation::kTranslation;
  bool all_pairs = false;      // all pairs at distance delta, not consecutive non-overlapping
  double rel_delta_tol = 0.1;  // all_pairs with m, s, rad, deg: accept |d - delta| <= tol*delta
  // Returns an empty string when valid, else a message naming the offending option.
  std::string Check() const;
};

// The pose pairs (i, j) of the estimate that RPE compares (evo's id_pairs_from_delta; seconds
// is an optinav extension that follows the same scheme on timestamps).
std::vector<std::pair<size_t, size_t>> SelectRpePairs(const Trajectory& est,
                                                      const RpeOptions& options);

// Throws Error when the options are invalid or no pair is found.
ErrorSeries ComputeRpe(const Trajectory& ref, const Trajectory& est, const RpeOptions& options);

}  // namespace optinav::eval
