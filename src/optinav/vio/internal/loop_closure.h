// Loop closure for the VIO output: re-observed places found among earlier keyframes, a relative
// pose from ORB matches and PnP, and a pose graph that corrects the trajectory.
//
// The odometry keeps running in its own world frame; the closer keeps a correction
// (world_corrected_from_world) per keyframe and the pipeline applies it to every frame's estimate
// (drift correction of the output, as VINS-Mono does it; ORB-SLAM3 likewise saves its trajectory
// after its loop corrections).
//
// Per keyframe: ORB features in both images; left-right matches (Hamming, ratio test) whose rays
// meet the epipolar constraint within `stereo_epipolar_px` are triangulated into 3D points of the
// left camera frame.
// Detection, at each keyframe: earlier keyframes of the same track at least `min_separation_s`
// and `min_separation_m` of path back, whose corrected position lies within
// `search_radius_m + search_radius_fraction * path since them` of the current corrected
// position and whose optical axis is within `max_view_angle_deg` of the current one, nearest
// first (at most `max_candidates`): their 3D points against the current left features (Hamming,
// ratio test), PnP RANSAC (`pnp_px`), refined on the inliers. A loop is accepted with at least
// `min_inliers` inliers and a relative pose that agrees with the corrected odometry within the
// search radius and the view angle.
// Pose graph (Ceres): one 6-DoF pose per keyframe of the track; odometry edges between
// consecutive keyframes (sigma growing with the distance between them) and loop edges (tighter,
// Cauchy loss); the track's first keyframe is held fixed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"
#include "optinav/util/timer.h"
#include "optinav/vio/backend.h"

namespace optinav::vio {

struct LoopClosureOptions {
  // Where it runs: stereo-only mode by default; stereo-imu mode only when asked (its 6-DoF pose
  // graph does not keep gravity's direction exactly). Never with GNSS fusion (the ENU alignment
  // ties to the uncorrected odometry).
  bool stereo_only = true;
  bool stereo_imu = false;
  int orb_features = 2000;             // in the left image
  double stereo_epipolar_px = 1.5;     // left-right match: distance to the epipolar line
  double max_depth_baselines = 100.0;  // triangulated points farther than this x baseline dropped
  double min_separation_s = 15.0;      // a candidate is at least this old ...
  double min_separation_m = 30.0;      // ... and this far back along the path
  double search_radius_m = 5.0;        // candidate within this + fraction x path since it
  double search_radius_fraction = 0.01;
  double max_view_angle_deg = 40.0;  // between the optical axes
  int max_candidates = 5;            // tried per keyframe, nearest first
  double match_ratio = 0.8;          // Lowe's ratio test
  double pnp_px = 2.0;               // PnP RANSAC threshold, pixels
  int min_inliers = 25;
  double min_interval_s = 1.0;  // between two accepted loops
  // After a loop, a new one must agree with the odometry chained through the last loop within
  // this + search_radius_fraction x the chained path (the search radius alone allows metres).
  double loop_consistency_m = 0.5;
  // Pose-graph sigmas: odometry per metre between keyframes (with floors), loop edges. The
  // odometry sigmas must allow the drift stereo odometry really has (about 1 % of the distance
  // on the car route): tighter ones make a correct loop of several metres look like an outlier
  // to the loop edges' Cauchy loss, and the loop corrects only a fraction of the drift.
  double odometry_sigma_m_per_m = 0.05;
  double odometry_min_sigma_m = 0.02;
  double odometry_sigma_rad_per_m = 0.002;
  double odometry_min_sigma_rad = 0.001;
  double loop_sigma_m = 0.05;
  double loop_sigma_rad = 0.005;

  std::string Check() const;  // empty when valid
};

struct LoopEdge {
  int64_t t_old_ns = 0, t_new_ns = 0;  // the two keyframes
  Rigid3d old_body_from_new_body;      // measured
  int inliers = 0;
  double correction_m = 0;  // how far the loop moved the new keyframe
};

class LoopCloser {
 public:
  LoopCloser(const camera::StereoRig& rig, const Rigid3d& body_from_cam0,
             const LoopClosureOptions& options);

  // A keyframe's estimate (odometry world) and its stereo images (8-bit grey), in time order.
  // Returns true when it closed a loop (the corrections changed).
  bool AddKeyframe(const StateEstimate& state, const cv::Mat& left, const cv::Mat& right);
  // A new track starts at `t_ns` (after a re-initialisation: another world frame). Earlier
  // keyframes keep their corrections but are no longer searched or optimised.
  void NewTrack(int64_t t_ns);
  // world_corrected_from_world for a frame at `t_ns`: that of the track's last keyframe at or
  // before it (identity before the track's first keyframe).
  Rigid3d CorrectionAt(int64_t t_ns) const;

  const std::vector<LoopEdge>& loops() const { return loops_; }
  // Records sub-stage times (loop_closure.orb, .stereo) when set.
  void set_timing(TimingStats* timing) { timing_ = timing; }
  size_t keyframes() const { return keyframes_.size(); }

 private:
  struct Keyframe {
    int64_t t_ns = 0;
    int track = 0;
    Rigid3d odometry;     // world_from_body as estimated
    Rigid3d correction;   // world_corrected_from_world
    double path_m = 0;    // odometry path length from the track's first keyframe
    cv::Mat descriptors;  // left ORB, all features
    std::vector<Eigen::Vector2d> normalized;  // left features, undistorted normalized
    cv::Mat point_descriptors;                // left features with a stereo point
    std::vector<Eigen::Vector3d> points;      // in the left camera frame
  };
  Keyframe Describe(const StateEstimate& state, const cv::Mat& left, const cv::Mat& right) const;
  // The relative pose cand_body_from_cur_body from matches, or false.
  bool Match(const Keyframe& candidate, const Keyframe& current, const Rigid3d& predicted,
             double radius_m, Rigid3d* cand_body_from_cur_body, int* inliers) const;
  void Optimize();

  camera::StereoRig rig_;
  Rigid3d body_from_cam0_;
  LoopClosureOptions options_;
  cv::Ptr<cv::Feature2D> orb_;
  Eigen::Matrix3d essential_;  // of right_from_left: x_r^T E x_l = 0
  std::vector<Keyframe> keyframes_;
  std::vector<LoopEdge> loops_;
  std::vector<std::pair<size_t, size_t>> loop_indices_;  // into keyframes_, with loops_
  TimingStats* timing_ = nullptr;
  int track_ = 0;
  std::vector<int64_t> track_starts_ns_;  // of tracks 1, 2, ... (track 0 starts first)
  size_t track_first_ = 0;                // index of the track's first keyframe
};

}  // namespace optinav::vio
