// Frame-to-frame visual odometry for a downward-looking camera over flat ground: ORB features of
// consecutive frames, 2-NN + ratio matching, a robust homography. Between map fixes it tells the
// mission how far and in which direction the drone moved, so one missed or bad fix does not
// leave it blind.
#pragma once

#include <memory>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/features/features.h"

namespace optinav::nav {

struct OdometryOptions {
  int max_features = 500;
  int orb_levels = 3;
  float ratio = 0.8f;
  // Contrast-limited adaptive histogram equalisation before detection (clip limit; 0: off),
  // over clahe_tiles x clahe_tiles cells. Haze halves the contrast a FAST threshold sees: on
  // the mission's 50 % fog frames (640x480 at 640 m) ORB keeps 63 corners and 29 homography
  // inliers per pair without it, 499 and 244 with it (docs/NAV.md).
  double clahe_clip_limit = 2.0;
  int clahe_tiles = 8;
  features::HomographyOptions homography{.reprojection_threshold_px = 3.0, .min_inliers = 20};
  std::string Check() const;  // "" when valid
};

struct OdometryStep {
  bool ok = false;
  std::string reason;         // why not, when !ok
  cv::Matx33d prev_from_cur;  // previous-frame px ~ H * current-frame px
  int inliers = 0;
  double extraction_ms = 0, total_ms = 0;
};

class FrameOdometry {
 public:
  explicit FrameOdometry(const OdometryOptions& options = {});
  ~FrameOdometry();
  // The motion from the previous frame to `gray` (8-bit); the first frame after construction or
  // Reset() returns !ok with reason "first frame".
  OdometryStep Track(const cv::Mat& gray);
  void Reset();

 private:
  OdometryOptions options_;
  std::unique_ptr<features::FeatureExtractor> extractor_;
  cv::Ptr<cv::CLAHE> clahe_;
  features::Features previous_;
  bool has_previous_ = false;
};

// The local similarity of a frame-to-frame homography at pixel `at`: how the current frame's up
// direction appears in the previous frame (rotation, clockwise positive, radians) and its scale.
struct LocalSimilarity {
  double rotation_rad = 0, scale = 1;
  cv::Point2d translation_px;  // where `at` lands in the previous frame, minus `at`
};
LocalSimilarity SimilarityAt(const cv::Matx33d& prev_from_cur, const cv::Point2d& at);

}  // namespace optinav::nav
