#include "optinav/sim/weather.h"

#include <cstdio>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "optinav/sim/renderer.h"
#include "optinav/sim/rig.h"
#include "optinav/util/testing.h"

namespace optinav::sim {
namespace {

struct Frame {
  cv::Mat bgr, depth;
  camera::PinholeCamera camera;
  Rigid3d world_from_cam;
};

const Frame& ClearUrbanFrame() {
  static const Frame* f = [] {
    static const World w = MakeWorld({});
    const BodyTrajectory car = MakeCarTrajectory(CarRouteOptions::Urban(), w.ground_height, 0);
    const SensorRig rig = CarRig().Scaled(0.4);
    auto* out = new Frame;
    out->camera = rig.left;
    out->world_from_cam = car.At(12'000'000'000).world_from_body * rig.body_from_left;
    Renderer(w).Render(out->camera, out->world_from_cam, &out->bgr, &out->depth);
    return out;
  }();
  return *f;
}

// Local RMS contrast (grey-level standard deviation in 15x15 windows, averaged) and the mean
// gradient magnitude: the contrast feature detectors respond to. (A global standard deviation
// is no measure of haze: fog brightens the distant scene and the sky towards the airlight while
// the near road stays dark, which spreads the global histogram.)
std::pair<double, double> Contrast(const cv::Mat& bgr) {
  cv::Mat gray, gx, gy, mag, mean, mean_sq;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  gray.convertTo(gray, CV_32F);
  cv::boxFilter(gray, mean, CV_32F, {15, 15});
  cv::boxFilter(gray.mul(gray), mean_sq, CV_32F, {15, 15});
  cv::Mat var = cv::max(mean_sq - mean.mul(mean), 0.0f), local_std;
  cv::sqrt(var, local_std);
  const cv::Scalar stddev = cv::mean(local_std);
  cv::Sobel(gray, gx, CV_32F, 1, 0);
  cv::Sobel(gray, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, mag);
  return {stddev[0], cv::mean(mag)[0]};
}

cv::Mat With(const WeatherSpec& spec, int64_t t_ns = 12'000'000'000, uint64_t seed = 9) {
  const Frame& f = ClearUrbanFrame();
  cv::Mat img = f.bgr.clone();
  ApplyWeather(img, f.depth, f.camera, f.world_from_cam, t_ns, spec, seed);
  return img;
}

TEST(Weather, ParsesAndRejectsClearly) {
  EXPECT_EQ(ParseWeather("fog:25").kind, WeatherKind::kFog);
  EXPECT_DOUBLE_EQ(ParseWeather("dust:75").intensity, 0.75);
  EXPECT_DOUBLE_EQ(ParseWeather("rain").intensity, 0.5);
  EXPECT_EQ(ParseWeather("road-snow:100").ToString(), "road-snow:100");
  EXPECT_EQ(ParseWeather("none").kind, WeatherKind::kNone);
  for (const char* bad : {"hail:50", "fog:150", "fog:-1", "fog:abc", "fog:", "none:20"}) {
    try {
      ParseWeather(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.context().field, "weather");
      std::printf("%-10s -> %s\n", bad, e.what());
    }
  }
}

TEST(Weather, ZeroIntensityEqualsTheClearImageExactly) {
  const Frame& f = ClearUrbanFrame();
  for (const char* kind : {"rain", "snow", "leaves", "fog", "dust", "road-wetness"}) {
    const cv::Mat img = With(ParseWeather(std::string(kind) + ":0"));
    EXPECT_EQ(cv::norm(img, f.bgr, cv::NORM_INF), 0) << kind;
  }
}

TEST(Weather, FogAndDustLowerContrastMonotonically) {
  for (const char* kind : {"fog", "dust"}) {
    auto prev = Contrast(ClearUrbanFrame().bgr);
    std::printf("%s contrast (local grey std / mean gradient): 0 %%: %.2f / %.2f", kind, prev.first,
                prev.second);
    for (int level : {25, 50, 75, 100}) {
      const auto c = Contrast(With(ParseWeather(fmt::format("{}:{}", kind, level))));
      std::printf(", %d %%: %.2f / %.2f", level, c.first, c.second);
      EXPECT_LT(c.first, prev.first) << kind << " " << level;
      EXPECT_LT(c.second, prev.second) << kind << " " << level;
      prev = c;
    }
    std::printf(" (must fall at every step)\n");
  }
}

TEST(Weather, ParticlesChangeTheImageAndDependOnTheSeedOnly) {
  const Frame& f = ClearUrbanFrame();
  for (const char* kind : {"rain:75", "snow:75", "leaves:75", "dust:75"}) {
    const WeatherSpec spec = ParseWeather(kind);
    const cv::Mat a = With(spec), b = With(spec), c = With(spec, 12'000'000'000, 10);
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0) << kind;  // stateless, deterministic
    EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0) << kind;   // another seed, other particles
    cv::Mat diff;
    cv::absdiff(a, f.bgr, diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    const int changed = cv::countNonZero(diff > 10);
    std::printf("%s: %d pixels changed by more than 10 grey levels\n", kind, changed);
    EXPECT_GT(changed, 50) << kind;
  }
}

TEST(Weather, StillParticlesDoNotMove) {
  // particles_still: the particles of t = 0 in every frame. A fixed camera sees the same snow
  // 1 s later (moving, the flakes fall 1 m/s and the image changes), and the still image is
  // the moving one at t = 0.
  const Frame& f = ClearUrbanFrame();
  WeatherSpec snow = ParseWeather("snow:75");
  const cv::Mat moving0 = With(snow, 0), moving1 = With(snow, 1'000'000'000);
  snow.particles_still = true;
  const cv::Mat still0 = With(snow, 0), still1 = With(snow, 1'000'000'000);
  EXPECT_GT(cv::norm(moving0, moving1, cv::NORM_L1), 0);
  EXPECT_EQ(cv::norm(still0, still1, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(still0, moving0, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(still1, f.bgr, cv::NORM_L1), 0) << "the particles are drawn";
}

// Rain drops are world objects: a camera that moves with the drops' velocity sees exactly the
// same drops at a later time, and a wall right in front of the camera hides them all.
TEST(Weather, ParticlesAreWorldObjects) {
  camera::PinholeCamera cam = CarRig().Scaled(0.4).left;
  cv::Mat grey(cam.height, cam.width, CV_8UC3, cv::Scalar(80, 80, 80));
  const cv::Mat far(cam.height, cam.width, CV_32F, cv::Scalar(1e6));
  const WeatherSpec rain = ParseWeather("rain:100");
  // Rain's particle velocity is (0.8, 0.3, -7.5) m/s; 0.5 s later the lattice moved by half.
  // The pose translation is a multiple of 0.5 m so the arithmetic is exact.
  const Rigid3d pose0(ExpSO3(Eigen::Vector3d(-1.2, 0, 0)), Eigen::Vector3d(2, 3, 10));
  Rigid3d pose1 = pose0;
  pose1.translation += 0.5 * Eigen::Vector3d(0.8, 0.3, -7.5);
  cv::Mat a = grey.clone(), b = grey.clone();
  DrawWeatherParticles(a, far, cam, pose0, 4'000'000'000, rain, 3);
  DrawWeatherParticles(b, far, cam, pose1, 4'500'000'000, rain, 3);
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const int streak_px = cv::countNonZero(a.reshape(1) != 80);
  std::printf("rain: %d streak pixel channels; moving with the drops changes %d\n", streak_px,
              cv::countNonZero(diff.reshape(1) > 1));
  EXPECT_GT(streak_px, 100);
  EXPECT_LT(cv::countNonZero(diff.reshape(1) > 1), streak_px / 100 + 5);
  const cv::Mat wall(cam.height, cam.width, CV_32F, cv::Scalar(0.1));
  cv::Mat c = grey.clone();
  DrawWeatherParticles(c, wall, cam, pose0, 4'000'000'000, rain, 3);
  EXPECT_EQ(cv::norm(c, grey, cv::NORM_INF), 0);
}

TEST(Weather, SurfaceEffectsFollowTheRoles) {
  const cv::Mat road = MakeSurfaceImage(SurfaceKind::kAsphalt, 1);
  for (const char* kind : {"road-wetness:50", "road-snow:50", "road-leaves:50", "rain:50"}) {
    cv::Mat on_road = road.clone(), on_wall = road.clone();
    ApplySurfaceWeather(on_road, SurfaceRole::kRoad, ParseWeather(kind), 4);
    ApplySurfaceWeather(on_wall, SurfaceRole::kOther, ParseWeather(kind), 4);
    EXPECT_GT(cv::norm(on_road, road, cv::NORM_L1), 0) << kind;
    EXPECT_EQ(cv::norm(on_wall, road, cv::NORM_INF), 0) << kind;
  }
  cv::Mat wet = road.clone();
  ApplySurfaceWeather(wet, SurfaceRole::kRoad, ParseWeather("road-wetness:100"), 4);
  EXPECT_LT(cv::mean(wet)[1], 0.8 * cv::mean(road)[1]);
  cv::Mat snowy = road.clone();
  ApplySurfaceWeather(snowy, SurfaceRole::kRoad, ParseWeather("road-snow:75"), 4);
  EXPECT_GT(cv::mean(snowy)[1], cv::mean(road)[1] + 40);
}

// The mission's use: a nadir camera 500 m up over a warped orthophoto, haze scaled to altitude.
TEST(Weather, NadirCameraHazeFollowsDistanceScale) {
  camera::PinholeCamera cam = camera::PinholeCamera::FromHorizontalFov(64, 48, 0.2);
  cv::Mat ground(cam.height, cam.width, CV_8UC3);
  for (int y = 0; y < ground.rows; ++y) {
    for (int x = 0; x < ground.cols; ++x) {
      ground.at<cv::Vec3b>(y, x) =
          ((x / 8 + y / 8) % 2) ? cv::Vec3b(200, 200, 200) : cv::Vec3b(40, 40, 40);
    }
  }
  const cv::Mat depth(cam.height, cam.width, CV_32F, cv::Scalar(500.0f));
  // Looking straight down from 500 m.
  const Rigid3d world_from_cam(ExpSO3(Eigen::Vector3d(M_PI, 0, 0)), Eigen::Vector3d(0, 0, 500));
  WeatherSpec fog = ParseWeather("fog:100");
  fog.distance_scale = 500.0 / 20;
  cv::Mat img = ground.clone();
  ApplyWeather(img, depth, cam, world_from_cam, 0, fog, 1);
  const double before = 160, after = img.at<cv::Vec3b>(24, 40)[0] - img.at<cv::Vec3b>(24, 32)[0];
  const double kept = std::abs(after) / before;
  std::printf(
      "nadir camera at 500 m, fog 100 %% with distance_scale 25: %.3f of the contrast "
      "kept (expected e^-2 = 0.135)\n",
      kept);
  EXPECT_NEAR(kept, std::exp(-1.956), 0.02);
  WeatherSpec dust = ParseWeather("dust:50");
  dust.distance_scale = 25;
  cv::Mat d = ground.clone();
  ApplyWeather(d, depth, cam, world_from_cam, 3'000'000'000, dust, 1);
  EXPECT_GT(cv::norm(d, ground, cv::NORM_L1), 0);
}

// The camera noise model (sim/camera_noise.h) applies the weather to the unrounded light
// (CV_32FC3): the same weather as on 8 bits, only without its intermediate rounding.
TEST(Weather, UnroundedLightGetsTheSameWeather) {
  const Frame& f = ClearUrbanFrame();
  for (const char* kind : {"fog:100", "dust:100", "rain:75", "snow:75", "leaves:75"}) {
    const WeatherSpec spec = ParseWeather(kind);
    cv::Mat light, rounded;
    f.bgr.convertTo(light, CV_32FC3);
    ApplyWeather(light, f.depth, f.camera, f.world_from_cam, 12'000'000'000, spec, 9);
    light.convertTo(rounded, CV_8UC3);
    cv::Mat diff;
    cv::absdiff(rounded, With(spec), diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    // Differ by a rounding, two where a particle is blended over the hazed (rounded) scene.
    EXPECT_LE(worst, 2) << kind;
    EXPECT_LT(cv::mean(diff)[0], 0.5) << kind;
  }
}

TEST(Weather, RejectsMismatchedInputs) {
  camera::PinholeCamera cam = CarRig().Scaled(0.4).left;
  cv::Mat img(cam.height, cam.width, CV_8UC3, cv::Scalar::all(0));
  cv::Mat depth(cam.height + 1, cam.width, CV_32F, cv::Scalar(5));
  EXPECT_ERROR(ApplyWeather(img, depth, cam, Rigid3d(), 0, ParseWeather("fog:50"), 1),
               {.field = "weather"},
               "depth of the same size (got 320x240 type 16, 320x241 type 5)");
}

}  // namespace
}  // namespace optinav::sim
