#include "optinav/nav/internal/frame_odometry.h"

#include <cmath>

#include "optinav/util/error.h"
#include "optinav/util/timer.h"

namespace optinav::nav {

std::string OdometryOptions::Check() const {
  if (max_features < 20) return "odometry max_features must be >= 20";
  if (orb_levels < 1) return "odometry orb_levels must be >= 1";
  if (!(ratio > 0 && ratio <= 1)) return "odometry ratio must be in (0, 1]";
  if (!(clahe_clip_limit >= 0)) return "odometry clahe_clip_limit must be >= 0";
  if (clahe_tiles < 1 || clahe_tiles > 64) return "odometry clahe_tiles must be 1..64";
  return homography.Check();
}

FrameOdometry::FrameOdometry(const OdometryOptions& options) : options_(options) {
  if (const std::string e = options.Check(); !e.empty()) throw Error(e);
  features::ExtractorOptions eo;
  eo.type = features::FeatureType::kOrb;
  eo.max_features = options.max_features;
  eo.orb_levels = options.orb_levels;
  extractor_ = features::CreateFeatureExtractor(eo);
  if (options.clahe_clip_limit > 0)
    clahe_ = cv::createCLAHE(options.clahe_clip_limit,
                             cv::Size(options.clahe_tiles, options.clahe_tiles));
}

FrameOdometry::~FrameOdometry() = default;

void FrameOdometry::Reset() {
  has_previous_ = false;
  previous_ = {};
}

OdometryStep FrameOdometry::Track(const cv::Mat& gray) {
  Timer total;
  OdometryStep step;
  Timer extraction;
  cv::Mat equalised;
  if (clahe_) clahe_->apply(gray, equalised);
  features::Features current = extractor_->Extract(clahe_ ? equalised : gray);
  step.extraction_ms = extraction.ElapsedMs();
  if (!has_previous_) {
    step.reason = "first frame";
  } else if (current.size() < 8 || previous_.size() < 8) {
    step.reason = "too few features";
  } else {
    const std::vector<cv::DMatch> matches = features::MatchWithRatio(
        current.descriptors, previous_.descriptors, current.norm, options_.ratio);
    std::vector<cv::Point2f> src, dst;
    for (const cv::DMatch& m : matches) {
      src.push_back(current.keypoints[m.queryIdx].pt);
      dst.push_back(previous_.keypoints[m.trainIdx].pt);
    }
    const features::HomographyResult h =
        features::EstimateHomography(src, dst, options_.homography);
    step.ok = h.ok;
    step.reason = h.ok ? "ok" : h.reason;
    step.prev_from_cur = h.H;
    step.inliers = h.inliers;
  }
  previous_ = std::move(current);
  has_previous_ = true;
  step.total_ms = total.ElapsedMs();
  return step;
}

LocalSimilarity SimilarityAt(const cv::Matx33d& h, const cv::Point2d& at) {
  const cv::Point2d p = features::ApplyHomography(h, at);
  const cv::Matx22d j = features::HomographyJacobian(h, at);
  const cv::Vec2d up = j * cv::Vec2d(0, -1);  // the current frame's up, in the previous frame
  LocalSimilarity s;
  s.rotation_rad = std::atan2(up[0], -up[1]);
  s.scale = std::hypot(up[0], up[1]);
  s.translation_px = p - at;
  return s;
}

}  // namespace optinav::nav
