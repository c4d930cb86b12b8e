#include "optinav/sim/camera_noise.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "optinav/util/testing.h"

namespace optinav::sim {
namespace {

cv::Mat Light(int rows, int cols, float grey) {
  return cv::Mat(rows, cols, CV_32FC3, cv::Scalar::all(grey));
}

// Grey mean and standard deviation of an 8-bit BGR image.
std::pair<double, double> GreyMeanStd(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::Scalar mean, stddev;
  cv::meanStdDev(grey, mean, stddev);
  return {mean[0], stddev[0]};
}

TEST(CameraNoise, HasTheModelsSigmaAndNoBias) {
  const CameraNoiseOptions noise;  // on: 0.8 read, 0.02 shot
  for (const float grey : {12.3f, 64.0f, 128.6f, 210.0f}) {
    const auto [mean, stddev] = GreyMeanStd(ExposeToEightBits(Light(300, 400, grey), noise, 7));
    const double want = noise.SigmaAt(grey);
    std::printf("grey %.1f: mean %.3f, sigma %.3f (model %.3f)\n", grey, mean, stddev, want);
    EXPECT_NEAR(mean, grey, 0.05);
    EXPECT_NEAR(stddev, want, 0.05 * want);
  }
  EXPECT_NEAR(noise.SigmaAt(128), 1.79, 0.01);
  // Saturation: near white the noise is clipped, never wrapped.
  const cv::Mat white = ExposeToEightBits(Light(50, 50, 254.5f), noise, 7);
  double lo = 0;
  cv::minMaxLoc(white, &lo);
  EXPECT_GT(lo, 240);
}

TEST(CameraNoise, StreamsAreDeterministicAndIndependent) {
  const CameraNoiseOptions noise;
  const cv::Mat light = Light(120, 160, 100.0f);
  auto centred = [&](uint64_t stream) {
    cv::Mat f;
    ExposeToEightBits(light, noise, stream).convertTo(f, CV_32F);
    return cv::Mat(f - cv::Scalar::all(100));
  };
  const cv::Mat a = centred(CameraNoiseStream(1, 5'000'000, 0));
  EXPECT_EQ(cv::norm(a, centred(CameraNoiseStream(1, 5'000'000, 0)), cv::NORM_INF), 0);
  // Left and right, the next frame, another seed: uncorrelated noise.
  for (const uint64_t other :
       {CameraNoiseStream(1, 5'000'000, 1), CameraNoiseStream(1, 35'000'000, 0),
        CameraNoiseStream(2, 5'000'000, 0)}) {
    const cv::Mat b = centred(other);
    const double corr = a.dot(b) / std::sqrt(a.dot(a) * b.dot(b));
    EXPECT_LT(std::abs(corr), 0.03) << other;
  }
}

// The reason the noise comes before the rounding: a gradient shallower than a grey level per
// pixel (a hazy scene) comes out as 8-bit steps without noise, dithered with it. Averaged over
// many rows, the noisy image follows the light; the noise-free one is off by up to half a level.
TEST(CameraNoise, DithersShallowGradientsInsteadOfSteps) {
  cv::Mat light(400, 200, CV_32FC3);
  for (int x = 0; x < light.cols; ++x) light.col(x).setTo(cv::Scalar::all(90.0 + 0.013 * x));
  CameraNoiseOptions off;
  off.enabled = false;
  auto column_error = [&](const CameraNoiseOptions& n) {
    cv::Mat grey, col_mean;
    cv::cvtColor(ExposeToEightBits(light, n, 3), grey, cv::COLOR_BGR2GRAY);
    cv::reduce(grey, col_mean, 0, cv::REDUCE_AVG, CV_64F);
    double worst = 0;
    for (int x = 0; x < light.cols; ++x)
      worst = std::max(worst, std::abs(col_mean.at<double>(0, x) - (90.0 + 0.013 * x)));
    return worst;
  };
  const double steps = column_error(off), dithered = column_error(CameraNoiseOptions{});
  std::printf("largest column-mean error: rounded %.3f, with noise %.3f grey levels\n", steps,
              dithered);
  EXPECT_GT(steps, 0.4);
  EXPECT_LT(dithered, 0.35);  // 1.8 / sqrt(400) = 0.09 per column, the worst of 200
}

TEST(CameraNoise, OffOnlyRounds) {
  CameraNoiseOptions off;
  off.enabled = false;
  EXPECT_EQ(off.SigmaAt(100), 0);
  const cv::Mat out = ExposeToEightBits(Light(10, 10, 99.6f), off, 1);
  EXPECT_EQ(cv::norm(out, cv::Mat(10, 10, CV_8UC3, cv::Scalar::all(100)), cv::NORM_INF), 0);
  EXPECT_EQ(off.ToString(), "off");
  EXPECT_EQ(CameraNoiseOptions{}.ToString(), "0.8:0.02");
}

TEST(CameraNoise, ParsesAndRejectsClearly) {
  EXPECT_TRUE(ParseCameraNoise("on", "--camera-noise").enabled);
  EXPECT_FALSE(ParseCameraNoise("off", "--camera-noise").enabled);
  const CameraNoiseOptions n = ParseCameraNoise("1.5:0.1", "--camera-noise");
  EXPECT_EQ(n.read_sigma, 1.5);
  EXPECT_EQ(n.shot_variance, 0.1);
  EXPECT_ERROR(ParseCameraNoise("loud", "--camera-noise"), {.field = "--camera-noise"},
               "'loud' is not on, off or READ:SHOT");
  EXPECT_ERROR(ParseCameraNoise("1:x", "--camera-noise"), {.field = "--camera-noise"},
               "not on, off or READ:SHOT");
  EXPECT_ERROR(ParseCameraNoise("-1:0.02", "--camera-noise"), {.field = "--camera-noise"},
               "read sigma -1 not in [0, 20]");
  EXPECT_ERROR(ParseCameraNoise("1:nan", "--camera-noise"), {.field = "--camera-noise"},
               "not on, off or READ:SHOT");
  EXPECT_ERROR(ExposeToEightBits(cv::Mat(4, 4, CV_8UC3), CameraNoiseOptions{}, 1), {},
               "needs a CV_32FC3 image");
}

}  // namespace
}  // namespace optinav::sim
