// Local features behind one interface, ratio-test matching, and robust homography estimation.
// A learned detector/descriptor plugs in by implementing FeatureExtractor: matchers only see
// descriptors and their norm (Hamming for binary, L2 for float).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace optinav::features {

// kXFeat: the learned XFeat detector/descriptor (features/xfeat.h), run by OpenCV's DNN module.
enum class FeatureType { kOrb, kSift, kBrisk, kXFeat };
std::optional<FeatureType> ParseFeatureType(const std::string& name);  // orb|sift|brisk|xfeat
std::string FeatureTypeName(FeatureType type);

// What a feature type's descriptors look like, known without building an extractor (an XFeat
// extractor loads its network).
struct DescriptorFormat {
  int type = CV_8U;             // CV_8U (binary) or CV_32F
  int size = 32;                // columns per descriptor
  int norm = cv::NORM_HAMMING;  // or cv::NORM_L2 (float)
};
DescriptorFormat DescriptorFormatOf(FeatureType type);

struct Features {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  // one row per keypoint: CV_8U (binary) or CV_32F
  int norm = cv::NORM_HAMMING;
  size_t size() const { return keypoints.size(); }
};

class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;
  // `gray`: 8-bit single channel. `mask` (optional): non-zero where features may be detected.
  virtual Features Extract(const cv::Mat& gray, const cv::Mat& mask = cv::Mat()) const = 0;
  virtual std::string name() const = 0;
  virtual int norm() const = 0;
  virtual int descriptor_type() const = 0;  // CV_8U or CV_32F
  virtual int descriptor_size() const = 0;  // columns per descriptor
};

struct ExtractorOptions {
  FeatureType type = FeatureType::kOrb;
  int max_features = 1024;      // strongest N kept
  int orb_fast_threshold = 12;  // lower than OpenCV's 20: aerial imagery is low in contrast
  int orb_levels = 8;           // pyramid levels (scale factor 1.2 each)
  // XFeat only: the network file ("" = DefaultXFeatModelPath()), the image-to-network resampling
  // (network px per image px; 0 = fit the image into the network's input) and OpenCV's thread
  // count for the forward pass (0 = OpenCV's default, every core the process may use).
  std::string model_path;
  double xfeat_scale = 0;
  int threads = 0;
  std::string Check() const;  // "" when valid
};

// Throws Error (naming the file) when an XFeat network cannot be loaded or is not XFeat.
std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const ExtractorOptions& options);

// Affine-simulated extraction (the idea of ASIFT, Morel and Yu 2009): the image is also seen
// under simulated camera tilts t = sqrt2, 2, ... up to `max_tilt`, rotated in steps of
// 72 deg / t; features of every view are mapped back into the original image. Makes an
// extractor tolerant of strongly oblique views (about 2 t^2 times the work).
Features ExtractAffineSimulated(const FeatureExtractor& extractor, const cv::Mat& gray,
                                double max_tilt);

// Extraction from rotated copies of the image, for a detector/descriptor that is not rotation
// invariant (XFeat): the image (and mask) is turned by each angle (radians, counter-clockwise as
// seen on screen: image x right, y down, so the rotation [cos -sin; sin cos]) about its centre
// onto a canvas that holds it whole, and the features of every copy are mapped back into the
// original image. Known heading: one angle that brings the image to the map's orientation;
// unknown: a few spread over the circle.
Features ExtractRotated(const FeatureExtractor& extractor, const cv::Mat& gray, const cv::Mat& mask,
                        const std::vector<double>& angles_rad);

// k = 2 nearest neighbours and Lowe's ratio test; returns query -> train matches sorted by
// distance. Empty when either side is empty.
std::vector<cv::DMatch> MatchWithRatio(const cv::Mat& query, const cv::Mat& train, int norm,
                                       float ratio = 0.8f);

// Mutual nearest neighbours for L2-normalised float descriptors (XFeat): a pair is kept when each
// is the other's nearest, the nearest is `ratio` times closer than the second nearest, and the
// distance is at most `max_distance` (for unit vectors d = sqrt(2 - 2 cos)). Returns query ->
// train matches sorted by distance.
std::vector<cv::DMatch> MatchMutual(const cv::Mat& query, const cv::Mat& train, float ratio = 0.9f,
                                    float max_distance = 0.8f);

// The matcher a feature type is meant for: MatchMutual (with `ratio`) for XFeat, else
// MatchWithRatio.
std::vector<cv::DMatch> MatchFeatures(FeatureType type, const cv::Mat& query, const cv::Mat& train,
                                      float ratio);

struct HomographyOptions {
  double reprojection_threshold_px = 4.0;
  int min_inliers = 12;                     // at least 4 by definition; higher rejects chance fits
  double min_inlier_ratio = 0.0;            // inliers / matches
  double min_scale = 0.2, max_scale = 5.0;  // singular values of the linear part
  double max_anisotropy = 3.0;              // ratio of those singular values (shear, squash)
  int max_iterations = 5000;
  double confidence = 0.999;
  std::string Check() const;
};

struct HomographyResult {
  bool ok = false;
  std::string reason;  // why not, when !ok
  cv::Matx33d H;       // dst ~ H * src
  int inliers = 0;
  double inlier_ratio = 0;
  std::vector<uint8_t> inlier_mask;
};

// Robust homography (OpenCV USAC MAGSAC++) with checks that reject degenerate results: mirror or
// fold-over (non-positive local determinant), extreme scale, shear or perspective.
HomographyResult EstimateHomography(const std::vector<cv::Point2f>& src,
                                    const std::vector<cv::Point2f>& dst,
                                    const HomographyOptions& options = {});

// Applies a homography to a point.
cv::Point2d ApplyHomography(const cv::Matx33d& H, const cv::Point2d& p);
// The 2x2 Jacobian of the homography's point map at p.
cv::Matx22d HomographyJacobian(const cv::Matx33d& H, const cv::Point2d& p);
// The homography's local scale at p: sqrt |det J| (e.g. map pixels per frame pixel).
double HomographyScale(const cv::Matx33d& H, const cv::Point2d& p);

}  // namespace optinav::features
