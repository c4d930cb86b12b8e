#include "optinav/features/features.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/util/testing.h"

namespace optinav::features {
namespace {

cv::Mat Gray(const std::string& name) {
  const cv::Mat img =
      cv::imread((testing::SharedDataDir() / "images" / name).string(), cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(img.empty()) << name;
  return img;
}

HomographyResult MatchPair(const cv::Mat& a, const cv::Mat& b, FeatureType type, int n) {
  const auto ex = CreateFeatureExtractor({.type = type, .max_features = n});
  const Features fa = ex->Extract(a), fb = ex->Extract(b);
  const auto matches = MatchWithRatio(fa.descriptors, fb.descriptors, ex->norm(), 0.8f);
  std::vector<cv::Point2f> src, dst;
  for (const auto& m : matches) {
    src.push_back(fa.keypoints[m.queryIdx].pt);
    dst.push_back(fb.keypoints[m.trainIdx].pt);
  }
  return EstimateHomography(src, dst, {.reprojection_threshold_px = 3.0, .max_anisotropy = 4.0});
}

// Worst corner distance between two homographies over an image.
double CornerError(const cv::Matx33d& a, const cv::Matx33d& b, cv::Size size) {
  double worst = 0;
  for (const cv::Point2d c : {cv::Point2d(0, 0), cv::Point2d(size.width, 0),
                              cv::Point2d(0, size.height), cv::Point2d(size.width, size.height)}) {
    worst = std::max(worst, cv::norm(ApplyHomography(a, c) - ApplyHomography(b, c)));
  }
  return worst;
}

TEST(Homography, GraffitiPairMatchesGroundTruth) {
  const cv::Mat g1 = Gray("graf1.png"), g3 = Gray("graf3.png");
  cv::FileStorage fs((testing::SharedDataDir() / "images" / "H1to3p.xml").string(),
                     cv::FileStorage::READ);
  cv::Mat truth;
  fs.getFirstTopLevelNode() >> truth;
  ASSERT_EQ(truth.size(), cv::Size(3, 3));
  for (FeatureType type : {FeatureType::kSift, FeatureType::kOrb}) {
    const HomographyResult r = MatchPair(g1, g3, type, type == FeatureType::kOrb ? 5000 : 4000);
    ASSERT_TRUE(r.ok) << FeatureTypeName(type) << ": " << r.reason;
    const double err = CornerError(r.H, cv::Matx33d(truth), g1.size());
    // The reference homography itself fits the matched points only to ~1-2 px (median), and
    // the corners are extrapolated; ORB (the default) stays within 5 px, SIFT within 10.
    const double threshold = type == FeatureType::kOrb ? 5.0 : 10.0;
    std::printf("graf1->graf3 %s: %d inliers, worst corner error %.2f px (threshold %.0f)\n",
                FeatureTypeName(type).c_str(), r.inliers, err, threshold);
    EXPECT_LT(err, threshold) << FeatureTypeName(type);
  }
}

TEST(Homography, AerialPhotoPairIsConsistent) {
  // Two oblique photographs of the same town from different directions: plain ORB or SIFT find
  // only a handful of correct matches, so both are seen under simulated tilts (ASIFT idea).
  const cv::Mat a1 = Gray("aero1.jpg"), a3 = Gray("aero3.jpg");
  const auto ex = CreateFeatureExtractor({.type = FeatureType::kBrisk, .max_features = 5000});
  const Features f1 = ExtractAffineSimulated(*ex, a1, 5.7);
  const Features f3 = ExtractAffineSimulated(*ex, a3, 5.7);
  const auto fwd_matches = MatchWithRatio(f1.descriptors, f3.descriptors, ex->norm(), 0.75f);
  auto estimate = [&](const Features& a, const Features& b) {
    std::vector<cv::Point2f> src, dst;
    const auto matches =
        &a == &f1 ? fwd_matches : MatchWithRatio(a.descriptors, b.descriptors, ex->norm(), 0.75f);
    for (const auto& m : matches) {
      src.push_back(a.keypoints[m.queryIdx].pt);
      dst.push_back(b.keypoints[m.trainIdx].pt);
    }
    return EstimateHomography(src, dst,
                              {.reprojection_threshold_px = 5.0,
                               .min_inliers = 20,
                               .max_scale = 8.0,
                               .max_anisotropy = 8.0});
  };
  const HomographyResult fwd = estimate(f1, f3), bwd = estimate(f3, f1);
  ASSERT_TRUE(fwd.ok) << fwd.reason;
  ASSERT_TRUE(bwd.ok) << bwd.reason;
  // Consistency: the backward estimate inverts the forward one on the forward inliers.
  double worst = 0;
  int checked = 0;
  for (const auto& m : fwd_matches) {
    const cv::Point2d p1 = f1.keypoints[m.queryIdx].pt;
    const cv::Point2d p3 = ApplyHomography(fwd.H, p1);
    if (cv::norm(p3 - cv::Point2d(f3.keypoints[m.trainIdx].pt)) > 5.0) continue;  // outlier
    worst = std::max(worst, cv::norm(ApplyHomography(bwd.H, p3) - p1));
    ++checked;
  }
  std::printf(
      "aero1<->aero3 (affine-simulated BRISK): %d / %d inliers, round trip over %d "
      "inliers: worst %.2f px (threshold 10)\n",
      fwd.inliers, bwd.inliers, checked, worst);
  EXPECT_GE(checked, 20);
  EXPECT_LT(worst, 10.0);
}

TEST(Homography, RejectsMirrorsTooFewAndNoise) {
  std::vector<cv::Point2f> src, mirrored;
  cv::RNG rng(5);
  for (int i = 0; i < 100; ++i) {
    const cv::Point2f p(rng.uniform(0.f, 400.f), rng.uniform(0.f, 300.f));
    src.push_back(p);
    mirrored.emplace_back(400.f - p.x, p.y);
  }
  const HomographyResult m = EstimateHomography(src, mirrored);
  EXPECT_FALSE(m.ok) << "a mirror image must not give a homography";
  const HomographyResult few =
      EstimateHomography({src.begin(), src.begin() + 3}, {src.begin(), src.begin() + 3});
  EXPECT_FALSE(few.ok);
  std::vector<cv::Point2f> noise;
  for (int i = 0; i < 100; ++i)
    noise.emplace_back(rng.uniform(0.f, 400.f), rng.uniform(0.f, 300.f));
  EXPECT_FALSE(EstimateHomography(src, noise).ok);
  // A clean similarity is accepted with all inliers.
  std::vector<cv::Point2f> sim;
  for (const auto& p : src)
    sim.emplace_back(0.8f * p.x - 0.6f * p.y + 50, 0.6f * p.x + 0.8f * p.y + 20);
  const HomographyResult ok = EstimateHomography(src, sim);
  ASSERT_TRUE(ok.ok) << ok.reason;
  EXPECT_EQ(ok.inliers, 100);
}

TEST(Features, FastHammingMatcherAgreesWithOpenCv) {
  cv::Mat q(300, 32, CV_8U), t(500, 32, CV_8U);
  cv::randu(q, 0, 256);
  cv::randu(t, 0, 256);
  t.row(7).copyTo(q.row(3));  // an exact match
  const auto fast = MatchWithRatio(q, t, cv::NORM_HAMMING, 0.8f);
  // Reference: OpenCV's brute force (through a non-continuous view to bypass the fast path).
  cv::Mat qq(300, 40, CV_8U), tt(500, 40, CV_8U);
  q.copyTo(qq.colRange(0, 32));
  t.copyTo(tt.colRange(0, 32));
  const auto ref = MatchWithRatio(qq.colRange(0, 32), tt.colRange(0, 32), cv::NORM_HAMMING, 0.8f);
  ASSERT_EQ(fast.size(), ref.size());
  for (size_t i = 0; i < fast.size(); ++i) {
    EXPECT_EQ(fast[i].distance, ref[i].distance);
  }
  ASSERT_FALSE(fast.empty());
  EXPECT_EQ(fast[0].queryIdx, 3);
  EXPECT_EQ(fast[0].trainIdx, 7);
  EXPECT_EQ(fast[0].distance, 0.0f);
}

TEST(Features, BlackImageHasNoFeaturesAndMatchingEmptyIsEmpty) {
  for (FeatureType type : {FeatureType::kOrb, FeatureType::kSift}) {
    const auto ex = CreateFeatureExtractor({.type = type});
    EXPECT_EQ(ex->Extract(cv::Mat::zeros(480, 640, CV_8UC1)).size(), 0u);
  }
  EXPECT_TRUE(MatchWithRatio(cv::Mat(), cv::Mat(), cv::NORM_HAMMING).empty());
  EXPECT_FALSE(ExtractorOptions{.max_features = 1}.Check().empty());
  EXPECT_EQ(ParseFeatureType("sift"), FeatureType::kSift);
  EXPECT_FALSE(ParseFeatureType("superpoint").has_value());
}

}  // namespace
}  // namespace optinav::features
