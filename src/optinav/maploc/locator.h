// Frame-to-map localization against a MapDatabase.
//
// Two methods, combined (the result says which one produced it and how confident it is):
//  - features: ORB/SIFT matching (2-NN + Lowe ratio) against the candidate tiles (each tile's
//    core cell, so overlapping tiles never offer a map point twice), best N per tile, matches in
//    map pixels de-duplicated on a grid, robust homography (USAC MAGSAC++) with degeneracy
//    checks; the frame centre goes through the homography to the map. Candidates come from the
//    prior or, without one, from a global vote against a sample of every tile's descriptors.
//  - orientation correlation (for appearance change, e.g. a map years older than the flight):
//    dense correlation of doubled-angle gradient orientations between the frame, rotated over the
//    heading uncertainty, and the map around the prior, by FFT. Reads the orthophoto itself (path
//    stored in the database, or given). Without a prior it searches the whole map, coarse to
//    fine, over headings and scales.
//
// Frames from a real camera: roll/pitch (attitude convention in aerial_camera.h) rectify the
// frame to a nadir view first; the full camera pose then comes from the map-to-image homography
// of the features or of the correlation's block matches (planar PnP, the given attitude and
// altitude as priors). The result's
// position is the vehicle's (the camera's nadir point); the image centre's ground point is
// reported separately.
//
// Headings are degrees clockwise from north of the frame's up direction (image -y), which with
// the attitude convention is the vehicle's yaw.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "optinav/camera/camera.h"
#include "optinav/maploc/map_db.h"

namespace optinav::maploc {

struct PreparedFrame;  // a frame undistorted and rectified for matching (locator.cc)

struct Prior {
  std::optional<geo::LatLon> position;  // approximate position
  double radius_m = 500.0;              // how far the truth may be from it
  // The prediction of the orthophoto-navigation thesis (SEEDS.md part 3): more centres (e.g. the
  // last fix moved along the bearing to the target and deviated bearings); candidates are tiles
  // within radius_m of any centre.
  std::vector<geo::LatLon> extra_centres;
  std::optional<double> heading_deg;  // frame up direction, clockwise from north
  double heading_sigma_deg = 10.0;    // half-width of the heading search
  std::optional<double> altitude_m;   // approximate altitude above ground
  double altitude_sigma_rel = 0.1;    // its 1-sigma error, fraction
  // Camera attitude from the autopilot (aerial_camera.h convention), degrees; unknown: nadir
  // assumed for the search, estimated by the features method.
  std::optional<double> roll_deg, pitch_deg;
  double attitude_sigma_deg = 1.5;  // 1-sigma error of roll and pitch
  // The orientation correlation must confirm the place by its blocks even with a position
  // (LocateOptions::oc_require_blocks for this call): for a fix that is to confirm another one,
  // where a distinct peak near a wrong position would only echo it.
  bool require_confirmed = false;
};

struct LocateOptions {
  float ratio = 0.8f;  // Lowe's ratio (ORB, SIFT, BRISK maps)
  // XFeat maps: mutual nearest neighbours with this ratio (features::MatchMutual; docs/MAPDB.md),
  // the network file ("" = features::DefaultXFeatModelPath()) and OpenCV's thread count for its
  // forward pass (0 = OpenCV's default).
  // 1 (mutual nearest neighbours only): farmland repeats, so the second nearest is often nearly
  // as close as the nearest; a ratio of 0.9 removed most true matches (docs/MAPDB.md).
  float xfeat_ratio = 1.0f;
  // Without a heading, XFeat (not rotation invariant: 30 deg off halves its matches, 45 deg
  // loses them) sees the frame at this many rotations spread over the circle (one forward pass
  // each).
  int xfeat_rotations = 8;
  std::string model_path;
  int xfeat_threads = 0;
  int top_n_per_tile = 300;           // best matches kept per tile
  int max_candidate_tiles = 9;        // nearest tiles to the prior that are matched
  int global_verify_tiles = 3;        // best-voted tiles verified (with neighbours) globally
  int global_features_per_tile = 64;  // map features per tile that vote in a global search
  int global_query_features = 500;    // frame features that vote
  double dedupe_cell_px = 2.0;        // grid cell (map pixels at feature resolution)
  features::HomographyOptions homography{.reprojection_threshold_px = 4.0, .min_inliers = 15};
  bool allow_orientation_correlation = true;
  double oc_heading_step_deg = 3.0;  // heading step of the coarse correlation search
  int oc_coarse_px = 64;             // frame size across at the coarse correlation level
  double oc_min_peak_ratio = 1.15;   // best peak / best peak elsewhere
  // Distinct places verified by block matching: all of them globally, with a prior the next
  // ones only while the best is not clearly confirmed.
  int oc_global_verify = 4;
  int oc_min_block_inliers = 12;  // consistent block matches that confirm a place
  // Without a confirmation by the blocks, a distinct correlation peak with a prior is still a
  // fix (a similarity, less exact) unless this is set.
  bool oc_require_blocks = false;
  int frame_features = 1024;  // features taken from the frame
  // ORB pyramid levels for the frame (x1.2 each). The map tiles carry 8 levels, so 4 on the
  // frame still covers the altitude changes tested (+-30 %), at ~40 % less extraction time.
  int frame_orb_levels = 4;
  std::string ortho_path;  // overrides the database's orthophoto path (for OC)
  // The camera: hfov_deg (> 0) with the principal point at the frame centre for any frame size,
  // or `camera` (intrinsics and distortion; a frame of another size with the same aspect scales
  // it). Neither: the map's build field of view.
  double hfov_deg = 0;
  std::optional<camera::PinholeCamera> camera;
  std::string Check() const;
};

struct StageTimes {
  double extraction_ms = 0, matching_ms = 0, estimation_ms = 0, total_ms = 0;
};

struct LocateResult {
  bool localized = false;
  std::string reason;                      // why not (or "ok")
  std::string method;                      // "features" | "orientation-correlation" | ""
  std::vector<std::string> methods_tried;  // in the order Locate tried them
  // The vehicle's position (the camera's nadir point).
  Eigen::Vector2d map_px = Eigen::Vector2d::Zero();  // map pixels
  Eigen::Vector2d crs_xy = Eigen::Vector2d::Zero();  // in the map CRS
  geo::LatLon latlon;
  // The ground point under the frame centre.
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  geo::LatLon centre_latlon;
  double heading_deg = 0;  // yaw: frame up direction, clockwise from north
  // Estimated from the image when a homography was found (features, or the correlation's
  // confirming blocks); else the inputs.
  double roll_deg = 0, pitch_deg = 0;
  double scale = 0;       // map pixels per frame pixel at the centre
  double altitude_m = 0;  // estimated height above the map plane
  // 1-sigma horizontal uncertainty of the position, metres (calibrated: docs/MAPDB.md).
  double position_sigma_m = 0;
  int inliers = 0;
  double inlier_ratio = 0;
  double confidence = 0;  // [0, 1]
  std::vector<int> candidate_tiles;
  StageTimes times;
};

class Locator {
 public:
  // Keeps a reference to `db`, which must outlive the locator.
  Locator(const MapDatabase& db, const LocateOptions& options = {});
  ~Locator();
  // Which method is tried first; the other runs only when the first fails. Orientation
  // correlation first pays when features keep failing (a map years older than the frames: they
  // then cost a third of the correlation's time for nothing). kAdaptive, the default, learns it
  // from the frames this locator has seen: features first until they have failed on 3 frames in
  // a row, then correlation first, with features first again on every 10th call to notice when
  // they work again (any success resets the count).
  enum class Order { kAdaptive, kFeaturesFirst, kCorrelationFirst };
  // `frame`: 8-bit grey or BGR. Never throws on bad frames: the result says why. Not thread-safe
  // (caches and the adaptive order): one locator per thread.
  LocateResult Locate(const cv::Mat& frame, const Prior& prior = {},
                      Order order = Order::kAdaptive);
  // Forgets what kAdaptive has learnt (a new flight).
  void ResetAdaptiveOrder();

  // Individual methods (for tests and benchmarks).
  LocateResult LocateByFeatures(const cv::Mat& gray, const Prior& prior);
  LocateResult LocateByOrientationCorrelation(const cv::Mat& gray, const Prior& prior);

  // Map pixel <-> lat/lon for callers.
  geo::LatLon PixelToLatLon(const Eigen::Vector2d& px) const;
  Eigen::Vector2d LatLonToPixel(const geo::LatLon& ll) const;
  // Heading (deg from north) of a direction given in map pixels, and back.
  double PixelDirectionToHeading(const Eigen::Vector2d& dir_px) const;
  Eigen::Vector2d HeadingToPixelDirection(double heading_deg) const;

 private:
  LocateResult FeaturesOn(const PreparedFrame& frame, const Prior& prior);
  LocateResult CorrelationOn(const PreparedFrame& frame, const Prior& prior);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace optinav::maploc
