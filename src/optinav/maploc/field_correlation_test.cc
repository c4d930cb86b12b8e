#include "optinav/maploc/field_correlation.h"

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

TEST(FieldCorrelation, MatchesMatchTemplate) {
  ExpectSameAsMatchTemplate({38, 38}, {32, 32}, cv::Rect(7, 5, 38, 38));
  ExpectSameAsMatchTemplate({42, 42}, {32, 32}, cv::Rect(0, 0, 42, 42));
  ExpectSameAsMatchTemplate({45, 41}, {29, 31}, cv::Rect(3, 9, 45, 41));  // 58 floats per row
  ExpectSameAsMatchTemplate({9, 9}, {1, 1}, cv::Rect(1, 1, 9, 9));
}

TEST(FieldCorrelation, TemplateLargerThanImageIsAnError) {
  cv::Mat image(10, 10, CV_32FC2, cv::Scalar::all(0)), tpl(12, 8, CV_32FC2, cv::Scalar::all(0));
  cv::Mat result;
  EXPECT_THROW(CorrelateSmall(image, tpl, &result), cv::Exception);
}

}  // namespace
}  // namespace optinav::maploc
