#include "optinav/maploc/field_correlation.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace optinav::maploc {
namespace {

// The direct correlation against OpenCV's: the block matching's sizes (a 32 px block in a window
// +-3 px wider, taken as a view into a larger field, as the map's level is) and sizes whose rows
// are not a multiple of the SIMD width (the scalar tail).
void ExpectSameAsMatchTemplate(cv::Size image_size, cv::Size tpl_size, cv::Rect roi) {
  cv::RNG rng(static_cast<uint64_t>(image_size.area() * 31 + tpl_size.area()));
  cv::Mat big(image_size.height + 20, image_size.width + 20, CV_32FC2);
  rng.fill(big, cv::RNG::UNIFORM, -1.0, 1.0);
  const cv::Mat image = big(roi);
  cv::Mat tpl(tpl_size, CV_32FC2);
  rng.fill(tpl, cv::RNG::UNIFORM, -1.0, 1.0);
  cv::Mat ours, theirs;
  CorrelateSmall(image, tpl, &ours);
  cv::matchTemplate(image, tpl, theirs, cv::TM_CCORR);
  ASSERT_EQ(ours.size(), theirs.size());
  const double scale = cv::norm(theirs, cv::NORM_INF);
  EXPECT_GT(scale, 1.0);
  EXPECT_LT(cv::norm(ours, theirs, cv::NORM_INF), 1e-4 * scale)
      << image_size << " image, " << tpl_size << " template";
}

// Both implementations: AVX2/FMA where the CPU has it, and the baseline SIMD one. The sizes
// include the locator's whole-patch refinement (a 103 px patch, 5 x 7 placements: the AVX2 path
// takes placements four at a time).
TEST(FieldCorrelation, MatchesMatchTemplate) {
  for (const bool avx2 : {true, false}) {
    if (avx2 && !CorrelateSmallHasAvx2()) continue;
    AllowCorrelateSmallAvx2(avx2);
    SCOPED_TRACE(avx2 ? "AVX2" : "baseline SIMD");
    ExpectSameAsMatchTemplate({38, 38}, {32, 32}, cv::Rect(7, 5, 38, 38));
    ExpectSameAsMatchTemplate({42, 42}, {32, 32}, cv::Rect(0, 0, 42, 42));
    ExpectSameAsMatchTemplate({45, 41}, {29, 31}, cv::Rect(3, 9, 45, 41));  // 58 floats per row
    ExpectSameAsMatchTemplate({9, 9}, {1, 1}, cv::Rect(1, 1, 9, 9));
    ExpectSameAsMatchTemplate({107, 109}, {103, 103}, cv::Rect(2, 4, 107, 109));
  }
  AllowCorrelateSmallAvx2(true);
}

TEST(FieldCorrelation, TemplateLargerThanImageIsAnError) {
  cv::Mat image(10, 10, CV_32FC2, cv::Scalar::all(0)), tpl(12, 8, CV_32FC2, cv::Scalar::all(0));
  cv::Mat result;
  EXPECT_THROW(CorrelateSmall(image, tpl, &result), cv::Exception);
}

// The fused rotation against cv::warpAffine (inverse map, zero border) followed by the turn of
// the doubled angles: rotations about a point inside and near the border, a scale, and a
// destination larger than the source (samples all outside).
TEST(FieldCorrelation, RotateFieldMatchesWarpAffine) {
  cv::RNG rng(7);
  cv::Mat field(57, 63, CV_32FC2);
  rng.fill(field, cv::RNG::UNIFORM, -1.0, 1.0);
  for (const double deg : {0.0, 17.0, 90.0, 213.5}) {
    const double a = deg * CV_PI / 180;
    for (const double k : {1.0, 0.8}) {
      // Destination u -> source q = k R(a) (u - c_dst) + c_src.
      cv::Matx23d m(k * std::cos(a), k * std::sin(a), 0, -k * std::sin(a), k * std::cos(a), 0);
      const cv::Point2d c_src(31.0, 28.5), c_dst(40.0, 40.0);
      m(0, 2) = c_src.x - (m(0, 0) * c_dst.x + m(0, 1) * c_dst.y);
      m(1, 2) = c_src.y - (m(1, 0) * c_dst.x + m(1, 1) * c_dst.y);
      const cv::Size size(81, 81);
      cv::Mat warped;
      cv::warpAffine(field, warped, m, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                     cv::BORDER_CONSTANT);
      cv::Mat expected(size, CV_32FC2);
      const float c2 = static_cast<float>(std::cos(2 * a)),
                  s2 = static_cast<float>(std::sin(2 * a));
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
          const cv::Vec2f q = warped.at<cv::Vec2f>(y, x);
          expected.at<cv::Vec2f>(y, x) = {q[0] * c2 - q[1] * s2, q[0] * s2 + q[1] * c2};
        }
      cv::Mat ours(size, CV_32FC2);
      RotateField(field, m, 2 * a, &ours);
      // OpenCV quantises the sample position to 1/32 px: allow that much of a unit gradient.
      EXPECT_LT(cv::norm(ours, expected, cv::NORM_INF), 0.07) << deg << " deg, scale " << k;
      EXPECT_LT(cv::norm(ours, expected, cv::NORM_L1) / size.area(), 0.02) << deg << " deg";
      // And exactly against bilinear sampling in double precision (zero outside the field).
      auto at = [&](int x, int y, int c) {
        return x < 0 || y < 0 || x >= field.cols || y >= field.rows
                   ? 0.0
                   : static_cast<double>(field.at<cv::Vec2f>(y, x)[c]);
      };
      double worst = 0;
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
          const double qx = m(0, 0) * x + m(0, 1) * y + m(0, 2);
          const double qy = m(1, 0) * x + m(1, 1) * y + m(1, 2);
          const int x0 = static_cast<int>(std::floor(qx)), y0 = static_cast<int>(std::floor(qy));
          const double ax = qx - x0, ay = qy - y0;
          double v[2];
          for (int c = 0; c < 2; ++c) {
            v[c] = (at(x0, y0, c) * (1 - ax) + at(x0 + 1, y0, c) * ax) * (1 - ay) +
                   (at(x0, y0 + 1, c) * (1 - ax) + at(x0 + 1, y0 + 1, c) * ax) * ay;
          }
          const cv::Vec2f o = ours.at<cv::Vec2f>(y, x);
          worst =
              std::max({worst, std::abs(o[0] - (v[0] * std::cos(2 * a) - v[1] * std::sin(2 * a))),
                        std::abs(o[1] - (v[0] * std::sin(2 * a) + v[1] * std::cos(2 * a)))});
        }
      EXPECT_LT(worst, 1e-4) << deg << " deg, scale " << k;
    }
  }
  // Whole-pixel shifts are exact copies, zero where the source ends.
  cv::Mat shifted(30, 30, CV_32FC2);
  RotateField(field, cv::Matx23d(1, 0, 40, 0, 1, 35), 0.0, &shifted);
  EXPECT_EQ(
      cv::norm(shifted(cv::Rect(0, 0, 23, 22)), field(cv::Rect(40, 35, 23, 22)), cv::NORM_INF),
      0.0);
  EXPECT_EQ(cv::norm(shifted(cv::Rect(23, 0, 7, 30)), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(shifted(cv::Rect(0, 22, 30, 8)), cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace optinav::maploc
