// XFeat through OpenCV's DNN module on real imagery (shared data: models/xfeat_640x640.onnx,
// images/graf*, aero*). A few forward passes per test (0.1-0.25 s each on 2 cores).
#include "optinav/features/xfeat.h"

#include <cstdio>
#include <fstream>

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

std::string ModelPath() {
  return (testing::SharedDataDir() / "models" / "xfeat_640x640.onnx").string();
}

std::unique_ptr<FeatureExtractor> XFeat(int max_features) {
  return CreateFeatureExtractor(
      {.type = FeatureType::kXFeat, .max_features = max_features, .model_path = ModelPath()});
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

HomographyResult Fit(const Features& a, const Features& b, const std::vector<cv::DMatch>& matches,
                     const HomographyOptions& o) {
  std::vector<cv::Point2f> src, dst;
  for (const auto& m : matches) {
    src.push_back(a.keypoints[m.queryIdx].pt);
    dst.push_back(b.keypoints[m.trainIdx].pt);
  }
  return EstimateHomography(src, dst, o);
}

// The extractor's output on a fixed image, against values recorded from this implementation
// (2026-11-26, OpenCV 4.6): a change in resampling, padding, softmax, pixel shuffle, NMS,
// reliability or the mapping back to image pixels moves these positions or scores.
TEST(XFeat, GoldenKeypointsOfGraf1) {
  const auto ex = XFeat(500);
  const cv::Mat img = Gray("graf1.png");  // 800x640: network scale 0.8
  const Features f = ex->Extract(img);
  ASSERT_EQ(f.descriptors.rows, static_cast<int>(f.size()));
  ASSERT_EQ(f.descriptors.cols, 64);
  ASSERT_EQ(f.descriptors.type(), CV_32F);
  ASSERT_GE(f.size(), 10u);
  struct Expected {
    float x, y, score;
  };
  // clang-format off
  const Expected expected[10] = {
      {520.12f, 483.88f, 0.54181f}, {460.12f, 485.12f, 0.48572f}, {621.38f, 333.88f, 0.42014f},
      {340.12f, 183.88f, 0.39547f}, {610.12f, 83.88f, 0.38326f},  {502.62f, 485.12f, 0.37268f},
      {510.12f, 336.38f, 0.36226f}, {522.62f, 205.12f, 0.35987f}, {538.88f, 505.12f, 0.34509f},
      {515.12f, 342.62f, 0.33970f},
  };
  // clang-format on
  for (int i = 0; i < 10; ++i) {
    EXPECT_NEAR(f.keypoints[i].pt.x, expected[i].x, 1.0) << "keypoint " << i;
    EXPECT_NEAR(f.keypoints[i].pt.y, expected[i].y, 1.0) << "keypoint " << i;
    EXPECT_NEAR(f.keypoints[i].response, expected[i].score, 0.01 * expected[i].score + 1e-4)
        << "keypoint " << i;
  }
  // Scores sorted, descriptors of unit length, keypoints inside the image, sizes of one cell.
  for (size_t i = 0; i < f.size(); ++i) {
    if (i > 0) EXPECT_LE(f.keypoints[i].response, f.keypoints[i - 1].response);
    EXPECT_NEAR(cv::norm(f.descriptors.row(static_cast<int>(i))), 1.0, 1e-4);
    EXPECT_GE(f.keypoints[i].pt.x, -0.5f);
    EXPECT_LT(f.keypoints[i].pt.x, img.cols - 0.5f);
    EXPECT_GE(f.keypoints[i].pt.y, -0.5f);
    EXPECT_LT(f.keypoints[i].pt.y, img.rows - 0.5f);
    EXPECT_FLOAT_EQ(f.keypoints[i].size, 10.0f);
  }
}

// The geometry maps back: the same content at another resampling (a 2x crop of graf1) gives
// keypoints at the same image places.
TEST(XFeat, KeypointsFollowTheImageAcrossScales) {
  const auto ex = XFeat(300);
  const cv::Mat img = Gray("graf1.png");
  const cv::Mat crop = img(cv::Rect(200, 160, 320, 320)).clone();  // 320 px: network scale 2
  cv::Mat half;
  cv::resize(crop, half, cv::Size(160, 160), 0, 0, cv::INTER_AREA);  // network scale 4
  const Features a = ex->Extract(crop), b = ex->Extract(half);
  ASSERT_GE(a.size(), 50u);
  ASSERT_GE(b.size(), 20u);
  // Both see the same 640 px network image (up to resampling), so keypoints of `half` x 2 must
  // land on keypoints of `crop`.
  int near = 0;
  for (const auto& kb : b.keypoints) {
    const cv::Point2f p((kb.pt.x + 0.5f) * 2 - 0.5f, (kb.pt.y + 0.5f) * 2 - 0.5f);
    for (const auto& ka : a.keypoints) {
      if (cv::norm(ka.pt - p) <= 1.5) {
        ++near;
        break;
      }
    }
  }
  std::printf("half-size crop: %d of %zu keypoints within 1.5 px of the full-size ones\n", near,
              b.size());
  EXPECT_GE(near, 0.6 * b.size());
}

TEST(XFeat, GraffitiPairBeatsOrbAgainstGroundTruth) {
  const cv::Mat g1 = Gray("graf1.png"), g3 = Gray("graf3.png");
  cv::FileStorage fs((testing::SharedDataDir() / "images" / "H1to3p.xml").string(),
                     cv::FileStorage::READ);
  cv::Mat truth;
  fs.getFirstTopLevelNode() >> truth;
  ASSERT_EQ(truth.size(), cv::Size(3, 3));
  const HomographyOptions ho{.reprojection_threshold_px = 3.0, .max_anisotropy = 4.0};
  // ORB as in features_test (5000 features, ratio 0.8).
  const auto orb = CreateFeatureExtractor({.type = FeatureType::kOrb, .max_features = 5000});
  const Features o1 = orb->Extract(g1), o3 = orb->Extract(g3);
  const HomographyResult ro =
      Fit(o1, o3, MatchWithRatio(o1.descriptors, o3.descriptors, cv::NORM_HAMMING, 0.8f), ho);
  ASSERT_TRUE(ro.ok) << ro.reason;
  const auto ex = XFeat(4000);
  const Features x1 = ex->Extract(g1), x3 = ex->Extract(g3);
  const HomographyResult rx =
      Fit(x1, x3, MatchFeatures(FeatureType::kXFeat, x1.descriptors, x3.descriptors, 0.9f), ho);
  ASSERT_TRUE(rx.ok) << rx.reason;
  const double orb_err = CornerError(ro.H, cv::Matx33d(truth), g1.size());
  const double xfeat_err = CornerError(rx.H, cv::Matx33d(truth), g1.size());
  std::printf(
      "graf1->graf3: ORB %d inliers, worst corner error %.2f px; XFeat %d inliers, %.2f px "
      "(threshold: ORB's, and 5 px)\n",
      ro.inliers, orb_err, rx.inliers, xfeat_err);
  EXPECT_LE(xfeat_err, orb_err);
  EXPECT_LT(xfeat_err, 5.0);
}

TEST(XFeat, AerialPhotoPairUnderSimulatedTiltsIsConsistentWithMoreInliersThanOrb) {
  const cv::Mat a1 = Gray("aero1.jpg"), a3 = Gray("aero3.jpg");
  const HomographyOptions ho{
      .reprojection_threshold_px = 5.0, .min_inliers = 20, .max_scale = 8.0, .max_anisotropy = 8.0};
  const auto orb = CreateFeatureExtractor({.type = FeatureType::kOrb, .max_features = 5000});
  const Features o1 = orb->Extract(a1), o3 = orb->Extract(a3);
  const HomographyResult ro =
      Fit(o1, o3, MatchWithRatio(o1.descriptors, o3.descriptors, cv::NORM_HAMMING, 0.8f), ho);
  const int orb_inliers = ro.ok ? ro.inliers : 0;
  // XFeat is neither rotation nor tilt invariant, and the two photographs differ by a strong
  // oblique view: plain XFeat finds 15 mutual matches (none consistent). Seen under simulated
  // tilts (sqrt 2, 4 rotations: 5 forward passes per image) it finds a consistent homography.
  const auto ex = XFeat(1000);
  const Features x1 = ExtractAffineSimulated(*ex, a1, 1.5),
                 x3 = ExtractAffineSimulated(*ex, a3, 1.5);
  const auto fwd_matches = MatchFeatures(FeatureType::kXFeat, x1.descriptors, x3.descriptors, 0.9f);
  const auto bwd_matches = MatchFeatures(FeatureType::kXFeat, x3.descriptors, x1.descriptors, 0.9f);
  const HomographyResult fwd = Fit(x1, x3, fwd_matches, ho), bwd = Fit(x3, x1, bwd_matches, ho);
  ASSERT_TRUE(fwd.ok) << fwd.reason;
  ASSERT_TRUE(bwd.ok) << bwd.reason;
  // Consistency: the backward estimate inverts the forward one on the forward inliers.
  double worst = 0;
  int checked = 0;
  for (size_t i = 0; i < fwd_matches.size(); ++i) {
    if (!fwd.inlier_mask[i]) continue;
    const cv::Point2d p1 = x1.keypoints[fwd_matches[i].queryIdx].pt;
    worst = std::max(worst, cv::norm(ApplyHomography(bwd.H, ApplyHomography(fwd.H, p1)) - p1));
    ++checked;
  }
  std::printf(
      "aero1<->aero3: plain ORB %d inliers (%s); XFeat %d / %d inliers, round trip over %d: "
      "worst %.2f px (threshold 10)\n",
      orb_inliers, ro.ok ? "ok" : ro.reason.c_str(), fwd.inliers, bwd.inliers, checked, worst);
  EXPECT_GT(fwd.inliers, orb_inliers);
  EXPECT_GE(checked, 20);
  EXPECT_LT(worst, 10.0);
}

TEST(XFeat, FlatImageMaskAndMatchingEdgeCases) {
  const auto ex = XFeat(1000);
  EXPECT_EQ(ex->Extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(90))).size(), 0u);
  EXPECT_EQ(ex->Extract(cv::Mat()).size(), 0u);
  // A mask keeps keypoints out of its zero part.
  const cv::Mat img = Gray("graf1.png");
  cv::Mat mask(img.size(), CV_8U, cv::Scalar(0));
  mask(cv::Rect(0, 0, img.cols / 2, img.rows)).setTo(255);
  const Features f = ex->Extract(img, mask);
  ASSERT_GT(f.size(), 100u);
  for (const auto& k : f.keypoints) EXPECT_LT(k.pt.x, img.cols / 2.0f + 1);
  // Mutual matching: a descriptor set against itself matches one to one.
  const auto self = MatchMutual(f.descriptors, f.descriptors, 0.9f);
  EXPECT_GE(self.size(), 0.95 * f.size());
  for (const auto& m : self) EXPECT_EQ(m.queryIdx, m.trainIdx);
  EXPECT_TRUE(MatchMutual(cv::Mat(), f.descriptors).empty());
  EXPECT_EQ(DescriptorFormatOf(FeatureType::kXFeat).size, 64);
  EXPECT_EQ(ParseFeatureType("xfeat"), FeatureType::kXFeat);
}

// A minimal ONNX model (protobuf written by hand): one Identity node from a 1x1x640x640 float
// input "x" to an output named `output`.
std::string IdentityOnnx(const std::string& output) {
  auto varint = [](uint64_t v) {
    std::string s;
    do {
      s += static_cast<char>((v & 0x7F) | (v > 0x7F ? 0x80 : 0));
      v >>= 7;
    } while (v);
    return s;
  };
  auto field = [&](int number, const std::string& bytes) {  // length-delimited
    return varint(static_cast<uint64_t>(number) << 3 | 2) + varint(bytes.size()) + bytes;
  };
  auto number = [&](int n, uint64_t v) {
    return varint(static_cast<uint64_t>(n) << 3) + varint(v);
  };
  std::string shape;
  for (int d : {1, 1, 640, 640}) shape += field(1, number(1, d));
  auto value_info = [&](const std::string& name) {
    return field(1, name) + field(2, field(1, number(1, 1) + field(2, shape)));
  };
  const std::string node = field(1, "x") + field(2, output) + field(4, "Identity");
  const std::string graph =
      field(1, node) + field(2, "g") + field(11, value_info("x")) + field(12, value_info(output));
  return number(1, 7) + field(7, graph) + field(8, number(2, 11));
}

TEST(XFeat, MissingOrWrongModelIsAClearError) {
  const auto dir = testing::MakeTempDir("xfeat");
  const std::string missing = (dir / "none.onnx").string();
  EXPECT_ERROR(CheckXFeatModel(missing), {.file = "none.onnx"}, "XFeat model not found");
  EXPECT_ERROR(CreateFeatureExtractor({.type = FeatureType::kXFeat, .model_path = missing}),
               {.file = "none.onnx"}, "XFeat model not found");
  const std::string garbage = testing::WriteFile(dir / "garbage.onnx", "not a network\n");
  EXPECT_ERROR(CheckXFeatModel(garbage), {.file = "garbage.onnx"}, "not an ONNX network");
  // Valid ONNX networks that are not XFeat: a missing output, an output of the wrong shape.
  const std::string other = testing::WriteFile(dir / "other.onnx", IdentityOnnx("y"));
  EXPECT_ERROR(CheckXFeatModel(other), {.file = "other.onnx"},
               "not the XFeat network: it has no output 'output_feats'");
  const std::string shaped = testing::WriteFile(dir / "shaped.onnx", IdentityOnnx("output_feats"));
  EXPECT_ERROR(CheckXFeatModel(shaped), {.file = "shaped.onnx"},
               "output 'output_feats' is 1x1x640x640 for a 1x1x640x640 input, expected 1x80x80x64");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace optinav::features
