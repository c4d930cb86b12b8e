#include "optinav/maploc/frame_synth.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "optinav/maploc/test_maps.h"

namespace optinav::maploc {
namespace {

constexpr double kDeg = M_PI / 180.0;

PerspectiveFrameOptions NoEffects() {
  PerspectiveFrameOptions o;
  o.gain_min = o.gain_max = 1;
  o.gamma_min = o.gamma_max = 1;
  o.max_blur_sigma_px = o.max_noise_sigma = 0;
  o.jpeg_quality_min = o.jpeg_quality_max = 0;
  return o;
}

// A black 1 m/px UTM raster with 3x3-pixel white landmarks every 40 px; landmark (i, j) covers
// map pixels [40 i + 20, 40 i + 23): its centre is (40 i + 21.5, 40 j + 21.5) in continuous
// pixel coordinates.
std::string LandmarkRaster(const std::filesystem::path& dir) {
  cv::Mat img(1000, 1000, CV_8UC1, cv::Scalar(0));
  for (int y = 20; y + 3 < img.rows; y += 40)
    for (int x = 20; x + 3 < img.cols; x += 40) img(cv::Rect(x, y, 3, 3)).setTo(255);
  geo::GeoTransform gt;
  gt.c = {500000.0, 1.0, 0.0, 5200000.0, 0.0, -1.0};
  const std::string path = (dir / "landmarks.tif").string();
  geo::WriteGeoTiff(path, img, gt, "EPSG:32614");
  return path;
}

// Every landmark the truth homography puts inside a frame is found there (intensity centroid;
// image pixel centres at integers, as the camera's) within 0.25 frame px, on tilted frames.
TEST(FrameSynth, TruthHomographyMapsRenderedLandmarks) {
  const auto dir = testing::MakeTempDir("framesynth");
  const geo::GeoRaster raster = geo::GeoRaster::Open(LandmarkRaster(dir));
  PerspectiveFrameOptions o = NoEffects();
  o.altitude_m = 100;  // 0.78 m per frame px at nadir: a landmark covers ~4x4 frame px
  const std::vector<PerspectiveFrame> frames = MakePerspectiveFrames(raster, 6, o, 7);
  int checked = 0;
  double worst = 0;
  for (const PerspectiveFrame& f : frames) {
    const Eigen::Matrix3d image_from_map = f.map_from_image.inverse();
    for (int j = 0; j < 24; ++j) {
      for (int i = 0; i < 24; ++i) {
        const Eigen::Vector2d m(40 * i + 21.5, 40 * j + 21.5);
        const Eigen::Vector2d p = (image_from_map * m.homogeneous()).hnormalized();
        if (p.x() < 12 || p.y() < 12 || p.x() > o.width - 12 || p.y() > o.height - 12) continue;
        double sw = 0;
        Eigen::Vector2d c = Eigen::Vector2d::Zero();
        for (int v = static_cast<int>(p.y()) - 8; v <= static_cast<int>(p.y()) + 8; ++v) {
          for (int u = static_cast<int>(p.x()) - 8; u <= static_cast<int>(p.x()) + 8; ++u) {
            const double w = f.image.at<uchar>(v, u);
            sw += w;
            c += w * Eigen::Vector2d(u, v);
          }
        }
        ASSERT_GT(sw, 255.0) << "landmark " << i << "," << j << " missing at " << p.transpose();
        worst = std::max(worst, (c / sw - p).norm());
        ++checked;
      }
    }
    // The truth's other fields agree with the pose.
    const Eigen::Vector2d centre =
        (f.map_from_image * Eigen::Vector3d(f.camera.cx, f.camera.cy, 1)).hnormalized();
    EXPECT_NEAR((centre - f.centre_px).norm(), 0, 1e-9);
    const double tilt = std::acos(std::cos(f.pose.attitude.roll_deg * kDeg) *
                                  std::cos(f.pose.attitude.pitch_deg * kDeg));
    EXPECT_NEAR((f.centre_px - f.pose.nadir_px).norm(), f.pose.altitude_m * std::tan(tilt), 1e-6);
    EXPECT_NEAR(geo::GeodesicInverse(f.latlon, f.centre_latlon).distance_m,
                f.pose.altitude_m * std::tan(tilt), 0.05);
  }
  std::printf("landmarks checked: %d, worst centroid error %.3f frame px (limit 0.25)\n", checked,
              worst);
  EXPECT_GE(checked, 100);
  EXPECT_LT(worst, 0.25);
  std::filesystem::remove_all(dir);
}

TEST(FrameSynth, CameraEffectsAreSeeded) {
  cv::Mat gray(120, 160, CV_8UC1);
  cv::randu(gray, 0, 256);
  cv::GaussianBlur(gray, gray, cv::Size(0, 0), 2.0);
  const CameraEffects e{
      .gain = 1.2, .gamma = 0.9, .blur_sigma_px = 1.0, .noise_sigma = 4, .jpeg_quality = 70};
  const cv::Mat a = ApplyCameraEffects(gray, e, 11), b = ApplyCameraEffects(gray, e, 11);
  const cv::Mat c = ApplyCameraEffects(gray, e, 12);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0);
  EXPECT_EQ(a.type(), CV_8UC1);
  // Neutral effects change nothing; a gain raises the mean; JPEG at quality 90 stays close.
  EXPECT_EQ(cv::norm(ApplyCameraEffects(gray, {}, 1), gray, cv::NORM_INF), 0);
  const double mean = cv::mean(gray)[0];
  EXPECT_NEAR(cv::mean(ApplyCameraEffects(gray, {.gain = 1.2}, 1))[0], 1.2 * mean, 2.0);
  EXPECT_GT(cv::PSNR(ApplyCameraEffects(gray, {.jpeg_quality = 90}, 1), gray), 35);
  EXPECT_ERROR(ApplyCameraEffects(cv::Mat(4, 4, CV_8UC3), e, 1), {.field = ""}, "8-bit grey");
}

TEST(FrameSynth, PerspectiveFramesAreSeeded) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(testmaps::Naip("20120731"));
  const PerspectiveFrameOptions o;
  const auto a = MakePerspectiveFrames(raster, 4, o, 5);
  const auto b = MakePerspectiveFrames(raster, 2, o, 5);
  const auto c = MakePerspectiveFrames(raster, 2, o, 6);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(cv::norm(a[i].image, b[i].image, cv::NORM_INF), 0);
    EXPECT_EQ(a[i].pose.nadir_px, b[i].pose.nadir_px);
    EXPECT_EQ(a[i].given_heading_deg, b[i].given_heading_deg);
    EXPECT_EQ(a[i].prior.lat_deg, b[i].prior.lat_deg);
    EXPECT_NE(a[i].pose.nadir_px, c[i].pose.nadir_px);
  }
  PerspectiveFrameOptions bad;
  bad.width = 8;
  EXPECT_ERROR(MakePerspectiveFrames(raster, 1, bad, 1), {.field = "frames"}, "frame size 8x256");
}

// The acceptance set's distributions: every drawn value within its range, the ranges used, the
// footprint inside the raster, and the given values within their errors of the truth.
TEST(FrameSynth, PerspectiveFrameRangesOnNaip) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(testmaps::Naip("20170827"));
  PerspectiveFrameOptions o;
  o.width = 640;
  o.height = 480;
  const int kFrames = 40;
  const auto frames = MakePerspectiveFrames(raster, kFrames, o, 2024);
  ASSERT_EQ(frames.size(), kFrames);
  double max_pitch = 0, max_roll = 0, max_blur = 0, max_noise = 0, min_alt = 1e9, max_alt = 0;
  int min_q = 100, max_q = 0;
  for (const PerspectiveFrame& f : frames) {
    ASSERT_EQ(f.image.size(), cv::Size(640, 480));
    const Attitude& a = f.pose.attitude;
    EXPECT_LE(std::abs(a.pitch_deg), 15);
    EXPECT_LE(std::abs(a.roll_deg), 10);
    EXPECT_GE(a.yaw_deg, 0);
    EXPECT_LT(a.yaw_deg, 360);
    EXPECT_GE(f.pose.altitude_m, 0.8 * 640);
    EXPECT_LE(f.pose.altitude_m, 1.25 * 640);
    EXPECT_GE(f.effects.gain, 0.7);
    EXPECT_LE(f.effects.gain, 1.3);
    EXPECT_GE(f.effects.gamma, 0.8);
    EXPECT_LE(f.effects.gamma, 1.25);
    EXPECT_LE(f.effects.blur_sigma_px, 1.2);
    EXPECT_LE(f.effects.noise_sigma, 5);
    EXPECT_GE(f.effects.jpeg_quality, 55);
    EXPECT_LE(f.effects.jpeg_quality, 90);
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(639.5, -0.5),
                                     Eigen::Vector2d(639.5, 479.5), Eigen::Vector2d(-0.5, 479.5)}) {
      const Eigen::Vector2d m = (f.map_from_image * c.homogeneous()).hnormalized();
      EXPECT_TRUE(m.x() >= 0 && m.y() >= 0 && m.x() <= 934 && m.y() <= 724) << m.transpose();
    }
    // Given values.
    EXPECT_LE(std::abs(f.given_altitude_m / f.pose.altitude_m - 1), 0.1 + 1e-12);
    EXPECT_LE(std::abs(f.given_roll_deg - a.roll_deg), 1 + 1e-12);
    EXPECT_LE(std::abs(f.given_pitch_deg - a.pitch_deg), 1 + 1e-12);
    EXPECT_LE(std::abs(std::remainder(f.given_heading_deg - f.heading_deg, 360.0)), 10 + 1e-9);
    EXPECT_EQ(f.heading_sigma_deg, 10);
    EXPECT_LE(geo::GeodesicInverse(f.prior, f.latlon).distance_m, 250 + 1e-6);
    EXPECT_EQ(f.prior_radius_m, 300);
    // UTM 14N near its central meridian: true north is within 2 deg of the raster's up.
    EXPECT_LE(std::abs(std::remainder(f.heading_deg - a.yaw_deg, 360.0)), 2);
    max_pitch = std::max(max_pitch, std::abs(a.pitch_deg));
    max_roll = std::max(max_roll, std::abs(a.roll_deg));
    max_blur = std::max(max_blur, f.effects.blur_sigma_px);
    max_noise = std::max(max_noise, f.effects.noise_sigma);
    min_alt = std::min(min_alt, f.pose.altitude_m);
    max_alt = std::max(max_alt, f.pose.altitude_m);
    min_q = std::min(min_q, f.effects.jpeg_quality);
    max_q = std::max(max_q, f.effects.jpeg_quality);
  }
  // The ranges are used, not just respected.
  EXPECT_GT(max_pitch, 12);
  EXPECT_GT(max_roll, 8);
  EXPECT_GT(max_blur, 0.9);
  EXPECT_GT(max_noise, 4);
  EXPECT_LT(min_alt, 560);
  EXPECT_GT(max_alt, 740);
  EXPECT_LT(min_q, 62);
  EXPECT_GT(max_q, 83);
}

}  // namespace
}  // namespace optinav::maploc
