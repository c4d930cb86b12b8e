#include "optinav/camera/camera.h"

#include <random>

#include <gtest/gtest.h>

#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::camera {
namespace {

PinholeCamera EurocCam0() {
  // V1_01's cam0 intrinsics and radial-tangential coefficients.
  PinholeCamera c;
  c.width = 752;
  c.height = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = DistortionModel::kRadialTangential;
  c.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

TEST(Camera, ProjectUnprojectRoundTripsWithEachDistortion) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (DistortionModel model : {DistortionModel::kNone, DistortionModel::kRadialTangential,
                                DistortionModel::kEquidistant}) {
    PinholeCamera c = EurocCam0();
    c.distortion = model;
    if (model == DistortionModel::kEquidistant) c.coeffs = {-0.01, 0.02, -0.005, 0.001};
    double worst = 0;
    for (int i = 0; i < 1000; ++i) {
      const Eigen::Vector2d px(u(rng) * (c.width - 1), u(rng) * (c.height - 1));
      const Eigen::Vector3d ray = c.Unproject(px);
      const auto back = c.Project(ray * (0.5 + 10 * u(rng)));
      ASSERT_TRUE(back.has_value());
      worst = std::max(worst, (*back - px).norm());
    }
    EXPECT_LT(worst, 1e-6) << DistortionModelName(model);
  }
}

TEST(Camera, RadialTangentialMatchesTheClosedForm) {
  const PinholeCamera c = EurocCam0();
  const Eigen::Vector2d n(0.3, -0.2);
  const double r2 = 0.13, k1 = c.coeffs[0], k2 = c.coeffs[1], p1 = c.coeffs[2], p2 = c.coeffs[3];
  const double radial = 1 + k1 * r2 + k2 * r2 * r2;
  const double xd = 0.3 * radial + 2 * p1 * 0.3 * -0.2 + p2 * (r2 + 2 * 0.09);
  const double yd = -0.2 * radial + p1 * (r2 + 2 * 0.04) + 2 * p2 * 0.3 * -0.2;
  EXPECT_NEAR(c.Distort(n).x(), xd, 1e-15);
  EXPECT_NEAR(c.Distort(n).y(), yd, 1e-15);
}

TEST(Camera, BehindTheCameraDoesNotProject) {
  const PinholeCamera c = PinholeCamera::FromHorizontalFov(800, 600, M_PI / 2);
  EXPECT_DOUBLE_EQ(c.fx, 400.0);  // 90 deg: f = w / 2
  EXPECT_FALSE(c.Project({0, 0, -1}).has_value());
  EXPECT_FALSE(c.Project({1, 0, 0}).has_value());
  EXPECT_TRUE(c.InImage(*c.Project({0, 0, 1})));
  EXPECT_FALSE(c.InImage({-1.0, 10.0}));
}

TEST(Camera, ScaledKeepsRaysThroughPixelCentres) {
  const PinholeCamera c = PinholeCamera::FromHorizontalFov(800, 600, M_PI / 2);
  const PinholeCamera h = c.Scaled(0.5);
  EXPECT_EQ(h.width, 400);
  EXPECT_EQ(h.height, 300);
  // The ray through the corner of the image (continuous -0.5) stays the same.
  const Eigen::Vector3d a = c.Unproject({-0.5, -0.5}), b = h.Unproject({-0.5, -0.5});
  EXPECT_NEAR((a - b).norm(), 0.0, 1e-12);
}

TEST(Camera, BadIntrinsicsAreRejected) {
  PinholeCamera c;
  EXPECT_ERROR(c.Validate(), {.field = "resolution"}, "resolution must be positive, got 0x0");
  c = PinholeCamera::FromHorizontalFov(10, 10, 1.0);
  c.fx = std::nan("");
  EXPECT_ERROR(c.Validate(), {.field = "intrinsics"}, "intrinsics must be finite");
  c = PinholeCamera::FromHorizontalFov(10, 10, 1.0);
  c.coeffs[2] = std::nan("");
  EXPECT_ERROR(c.Validate(), {.field = "distortion_coefficients"}, "must be finite");
  // In-memory values: no file or field to name (ReadCameraCalibration adds them), the message
  // says what is wrong.
  EXPECT_ERROR(PinholeCamera::FromHorizontalFov(10, 10, 4.0), {},
               "field of view must be in (0, 180) deg");
  EXPECT_ERROR(ParseDistortionModel("pinhole-fancy"), {},
               "unknown distortion model 'pinhole-fancy'");
  EXPECT_EQ(ParseDistortionModel("radtan"), DistortionModel::kRadialTangential);
}

TEST(Camera, StereoTriangulationRecoversPoints) {
  StereoRig rig;
  rig.left = rig.right = EurocCam0();
  rig.right_from_left =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(-0.11, 0.001, 0.0));
  EXPECT_NEAR(rig.Baseline(), 0.11, 1e-4);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Rigid3d left_from_world = Rigid3d::Identity();
  const Rigid3d right_from_world = rig.right_from_left * left_from_world;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p(2 * u(rng), 1.5 * u(rng), 4 + 3 * u(rng));
    const auto pl = rig.left.Project(p), pr = rig.right.Project(right_from_world * p);
    ASSERT_TRUE(pl && pr);
    const auto x =
        TriangulateTwoView(left_from_world, right_from_world, rig.left.PixelToNormalized(*pl),
                           rig.right.PixelToNormalized(*pr));
    ASSERT_TRUE(x.has_value());
    EXPECT_LT((*x - p).norm(), 1e-6);
    // A true match lies on its epipolar line; moved 2 px (in normalized units) across the
    // nearly horizontal line it is 2 px off.
    const Eigen::Vector2d nl = rig.left.PixelToNormalized(*pl);
    const Eigen::Vector2d nr = rig.right.PixelToNormalized(*pr);
    EXPECT_LT(EpipolarDistance(rig.Essential(), nl, nr), 1e-9);
    const double off =
        EpipolarDistance(rig.Essential(), nl, nr + Eigen::Vector2d(0, 2 / rig.right.fx));
    EXPECT_NEAR(off * rig.right.fx, 2.0, 0.05);
  }
  // Identical rays (no baseline) cannot be triangulated.
  EXPECT_FALSE(TriangulateTwoView(left_from_world, left_from_world, {0.1, 0.1}, {0.1, 0.1}));
}

}  // namespace
}  // namespace optinav::camera
