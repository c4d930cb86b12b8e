#include "optinav/maploc/aerial_camera.h"

#include <random>

#include <gtest/gtest.h>

namespace optinav::maploc {
namespace {

Eigen::Matrix3d TestK() {
  Eigen::Matrix3d k;
  k << 320, 0, 320, 0, 320, 240, 0, 0, 1;  // 640x480, 90 deg horizontal field of view
  return k;
}

Eigen::Vector2d Apply(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  return (h * p.homogeneous()).hnormalized();
}

TEST(AerialCamera, AttitudeRoundTrip) {
  for (const Attitude a : {Attitude{10, -15, 30}, Attitude{-8, 12, 300}, Attitude{0, 0, 0}}) {
    const Attitude b = AttitudeOf(NedFromBody(a));
    EXPECT_NEAR(b.roll_deg, a.roll_deg, 1e-9);
    EXPECT_NEAR(b.pitch_deg, a.pitch_deg, 1e-9);
    EXPECT_NEAR(b.yaw_deg, a.yaw_deg, 1e-9);
  }
}

// The convention as the docs state it, on a north-up map (map up = north, map right = east).
TEST(AerialCamera, ConventionOfTheDocs) {
  const Eigen::Matrix3d k = TestK();
  const double gsd = 2.0;
  AerialPose pose{.nadir_px = {1000, 1000}, .altitude_m = 400};
  // Level, heading north: the image centre is the nadir point, image up is map up (north),
  // image right is east, and 1 image px = altitude / f metres.
  Eigen::Matrix3d h = MapFromImage(pose, k, gsd);
  EXPECT_NEAR((Apply(h, {320, 240}) - pose.nadir_px).norm(), 0, 1e-9);
  EXPECT_NEAR((Apply(h, {320, 140}) - Eigen::Vector2d(1000, 1000 - 100 * 400 / 320.0 / gsd)).norm(),
              0, 1e-9);
  EXPECT_GT(Apply(h, {420, 240}).x(), 1000);
  // Heading east (yaw 90): image up points east (+x).
  pose.attitude.yaw_deg = 90;
  h = MapFromImage(pose, k, gsd);
  EXPECT_GT(Apply(h, {320, 140}).x(), 1000 + 50);
  EXPECT_NEAR(Apply(h, {320, 140}).y(), 1000, 1e-6);
  // Nose up 15 deg, heading north: the belly faces forward, the camera looks ahead, the centre's
  // ground point lies altitude * tan(15 deg) north of the vehicle.
  pose.attitude = {.roll_deg = 0, .pitch_deg = 15, .yaw_deg = 0};
  h = MapFromImage(pose, k, gsd);
  const Eigen::Vector2d c = Apply(h, {320, 240});
  EXPECT_NEAR(c.x(), 1000, 1e-6);
  EXPECT_NEAR((1000 - c.y()) * gsd, 400 * std::tan(15 * M_PI / 180), 1e-6);
  // Right wing down 10 deg: the belly, and the camera, turn to the left (west).
  pose.attitude = {.roll_deg = 10, .pitch_deg = 0, .yaw_deg = 0};
  h = MapFromImage(pose, k, gsd);
  EXPECT_NEAR((1000 - Apply(h, {320, 240}).x()) * gsd, 400 * std::tan(10 * M_PI / 180), 1e-6);
}

TEST(AerialCamera, PoseFromHomographyRecoversThePose) {
  const Eigen::Matrix3d k = TestK();
  const AerialPose truth{.nadir_px = {2345.6, 1234.5},
                         .altitude_m = 612,
                         .attitude = {.roll_deg = -7, .pitch_deg = 13, .yaw_deg = 221}};
  // Any scale of the homography gives the same pose.
  const auto pose = PoseFromHomography(-3.7 * MapFromImage(truth, k, 1.0), k, 1.0);
  ASSERT_TRUE(pose.has_value());
  EXPECT_NEAR((pose->nadir_px - truth.nadir_px).norm(), 0, 1e-6);
  EXPECT_NEAR(pose->altitude_m, truth.altitude_m, 1e-6);
  EXPECT_NEAR(pose->attitude.roll_deg, -7, 1e-6);
  EXPECT_NEAR(pose->attitude.pitch_deg, 13, 1e-6);
  EXPECT_NEAR(pose->attitude.yaw_deg, 221, 1e-6);
  EXPECT_FALSE(PoseFromHomography(Eigen::Matrix3d::Zero(), k, 1.0).has_value());
}

// Noisy correspondences: the refined pose is close to the truth, its sigma is honest (the error
// within 3 sigma over seeds), and an attitude prior pulls a weak geometry towards the truth.
TEST(AerialCamera, RefinePoseWithNoiseAndPriors) {
  const Eigen::Matrix3d k = TestK();
  const double gsd = 1.0;
  const AerialPose truth{.nadir_px = {3000, 2000},
                         .altitude_m = 640,
                         .attitude = {.roll_deg = 4, .pitch_deg = -9, .yaw_deg = 57}};
  const Eigen::Matrix3d h = MapFromImage(truth, k, gsd);
  int within = 0;
  double worst = 0;
  for (int seed = 0; seed < 20; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> noise(0, 1.5);
    std::vector<Eigen::Vector2d> img, map;
    for (int i = 0; i < 60; ++i) {
      const Eigen::Vector2d p(640 * u(rng), 480 * u(rng));
      map.push_back(Apply(h, p));
      img.push_back(p + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    img[0] += Eigen::Vector2d(80, -60);  // an outlier the Huber loss must absorb
    AerialPose init = truth;
    init.nadir_px += Eigen::Vector2d(40, -30);
    init.altitude_m *= 1.1;
    init.attitude.pitch_deg += 3;
    const PoseEstimate e = RefinePose(img, map, k, gsd, init, {});
    const double err = (e.pose.nadir_px - truth.nadir_px).norm() * gsd;
    worst = std::max(worst, err);
    EXPECT_GT(e.horizontal_sigma_m, 0);
    if (err <= 3 * e.horizontal_sigma_m) ++within;
    EXPECT_NEAR(e.pose.altitude_m, 640, 10);
  }
  EXPECT_LT(worst, 15.0);
  EXPECT_GE(within, 18) << "sigma too optimistic";

  // Six points near the centre: position and tilt are confounded; the roll/pitch prior fixes it.
  std::vector<Eigen::Vector2d> img, map;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 2.0);
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(300, 220), Eigen::Vector2d(345, 225), Eigen::Vector2d(330, 262),
        Eigen::Vector2d(295, 250), Eigen::Vector2d(318, 236), Eigen::Vector2d(340, 245)}) {
    map.push_back(Apply(h, p));
    img.push_back(p + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  AerialPose init = truth;
  init.attitude.pitch_deg = 0;
  init.attitude.roll_deg = 0;
  const PoseEstimate with_prior =
      RefinePose(img, map, k, gsd, init, {.roll_deg = 4.5, .pitch_deg = -8.5, .altitude_m = 620});
  EXPECT_LT((with_prior.pose.nadir_px - truth.nadir_px).norm() * gsd, 20.0);
  EXPECT_NEAR(with_prior.pose.attitude.pitch_deg, -9, 2.0);
}

TEST(AerialCamera, NadirRectificationMapsThePrincipalPointToTheNadir) {
  const Eigen::Matrix3d k = TestK();
  const AerialPose tilted{.nadir_px = {500, 700},
                          .altitude_m = 300,
                          .attitude = {.roll_deg = 8, .pitch_deg = 12, .yaw_deg = 33}};
  AerialPose level = tilted;
  level.attitude.roll_deg = level.attitude.pitch_deg = 0;
  // image (tilted) -> nadir image -> map must equal image -> map.
  const Eigen::Matrix3d via_nadir =
      MapFromImage(level, k, 1.0) *
      NadirFromImage(k, tilted.attitude.roll_deg, tilted.attitude.pitch_deg);
  const Eigen::Matrix3d direct = MapFromImage(tilted, k, 1.0);
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(640, 480), Eigen::Vector2d(100, 400)}) {
    EXPECT_NEAR((Apply(via_nadir, p) - Apply(direct, p)).norm(), 0, 1e-6);
  }
  EXPECT_NEAR((Apply(MapFromImage(level, k, 1.0), {320, 240}) - tilted.nadir_px).norm(), 0, 1e-9);
}

}  // namespace
}  // namespace optinav::maploc
