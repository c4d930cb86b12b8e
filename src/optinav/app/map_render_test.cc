#include "optinav/app/map_render.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/geo/raster.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

std::string Naip2017() {
  return (testing::SharedDataDir() / "geo" / "naip" / "naip_20170827.tif").string();
}

// A perspective frame pitched 10 deg nose up, heading north, at 640 m: the image centre's ground
// point lies 640 tan(10 deg) = 112.9 m north of the vehicle.
TEST(MapRender, PerspectiveFrameWithAttitude) {
  const auto dir = testing::MakeTempDir("maprender");
  FrameRenderOptions o;
  o.ortho_path = Naip2017();
  o.out_path = (dir / "f.png").string();
  o.at = {47.0186, -99.1526};
  o.width = 320;
  o.height = 240;
  o.altitude_m = 640;
  o.pitch_deg = 10;
  o.roll_deg = 0;
  const RenderedFrame r = RenderFrame(o);
  EXPECT_NEAR(r.gsd_m, 640 / 160.0, 1e-9);  // 90 deg field of view: f = width / 2
  const geo::GeodesicResult d = geo::GeodesicInverse(o.at, r.centre);
  EXPECT_NEAR(d.distance_m, 640 * std::tan(10 * M_PI / 180), 0.5);
  EXPECT_LT(std::abs(std::remainder(d.azimuth1_deg, 360.0)), 2.0);
  const cv::Mat img = cv::imread(o.out_path, cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.size(), cv::Size(320, 240));
  EXPECT_GT(cv::mean(img)[0], 20);  // ground, not the black outside of the map
  // Right wing down 8 deg: the camera looks left (west) of the vehicle.
  o.pitch_deg = 0;
  o.roll_deg = 8;
  const RenderedFrame rolled = RenderFrame(o);
  const geo::GeodesicResult dr = geo::GeodesicInverse(o.at, rolled.centre);
  EXPECT_NEAR(dr.distance_m, 640 * std::tan(8 * M_PI / 180), 0.5);
  EXPECT_NEAR(std::remainder(dr.azimuth1_deg - 270, 360.0), 0, 2.0);
  // The legacy tilt model still renders, centred on --at.
  FrameRenderOptions legacy;
  legacy.ortho_path = Naip2017();
  legacy.out_path = (dir / "legacy.png").string();
  legacy.at = o.at;
  legacy.tilt_deg = 10;
  legacy.tilt_azimuth_deg = 30;
  const RenderedFrame lr = RenderFrame(legacy);
  EXPECT_NEAR(lr.gsd_m, 5.0, 0.05);
  EXPECT_FALSE(cv::imread(legacy.out_path).empty());
  std::filesystem::remove_all(dir);
}

TEST(MapRender, OptionErrors) {
  FrameRenderOptions o;
  o.ortho_path = Naip2017();
  o.out_path = "/nonexistent/x.png";
  o.tilt_deg = 5;
  o.roll_deg = 3;
  EXPECT_NE(o.Check().find("--tilt"), std::string::npos);
  o.tilt_deg.reset();
  o.altitude_m = 600;
  o.gsd_m = 2;
  EXPECT_EQ(o.Check().rfind("--altitude and --gsd", 0), 0u);
  o.gsd_m = 0;
  o.pitch_deg = 85;
  EXPECT_EQ(o.Check().rfind("--pitch", 0), 0u);
  o.pitch_deg = 0;
  o.at = {10, 10};
  EXPECT_ERROR(RenderFrame(o), {.field = "--at"}, "outside the orthophoto");
  // Looking at the horizon: a frame corner sees the sky.
  o.at = {47.0186, -99.1526};
  o.pitch_deg = 60;
  EXPECT_ERROR(RenderFrame(o), {.field = "attitude"}, "horizon");
}

// The acceptance set on disk: the files locate reads are exactly the generator's frames, the
// CSVs have the headers and one row per frame.
TEST(MapRender, FrameSetFiles) {
  const auto dir = testing::MakeTempDir("mapset");
  FrameSetOptions o;
  o.ortho_path = Naip2017();
  o.out_dir = (dir / "set").string();
  o.count = 3;
  o.seed = 9;
  const FrameSetSummary s = RenderFrameSet(o);
  EXPECT_EQ(s.count, 3);
  const auto frames =
      maploc::MakePerspectiveFrames(geo::GeoRaster::Open(o.ortho_path), 3, o.frames, o.seed);
  for (int i = 0; i < 3; ++i) {
    const cv::Mat img = cv::imread(
        (dir / "set" / ("frame_00" + std::to_string(i) + ".jpg")).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(img.empty());
    EXPECT_EQ(cv::norm(img, frames[i].image, cv::NORM_INF), 0) << "frame " << i;
  }
  const std::string given = testing::ReadFile(s.frames_csv);
  EXPECT_EQ(given.rfind("image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg,"
                        "altitude_m,roll_deg,pitch_deg\n",
                        0),
            0u);
  EXPECT_EQ(std::count(given.begin(), given.end(), '\n'), 4);
  EXPECT_NE(given.find((dir / "set" / "frame_002.jpg").string() + ","), std::string::npos);
  const std::string truth = testing::ReadFile(s.truth_csv);
  EXPECT_EQ(truth.rfind("image,lat,lon,center_lat,center_lon,altitude_m,roll_deg,pitch_deg,"
                        "heading_deg\n",
                        0),
            0u);
  EXPECT_EQ(std::count(truth.begin(), truth.end(), '\n'), 4);
  o.count = 0;
  EXPECT_ERROR(RenderFrameSet(o), {.field = ""}, "--set must be");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace optinav::app
