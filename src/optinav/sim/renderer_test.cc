#include "optinav/sim/renderer.h"

#include <algorithm>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "optinav/sim/internal/texture.h"
#include "optinav/sim/rig.h"
#include "optinav/util/statistics.h"

namespace optinav::sim {
namespace {

struct Scene {
  World world;
  BodyTrajectory route;
};

const Scene& Urban() {
  static const Scene* s = [] {
    WorldOptions o;
    o.seed = 5;
    World w = MakeWorld(o);
    BodyTrajectory car = MakeCarTrajectory(CarRouteOptions::Urban(), w.ground_height, 0);
    return new Scene{std::move(w), std::move(car)};
  }();
  return *s;
}

const Scene& Terrain() {
  static const Scene* s = [] {
    WorldOptions o;
    o.kind = WorldKind::kTerrain;
    o.seed = 5;
    World w = MakeWorld(o);
    BodyTrajectory car = MakeCarTrajectory(CarRouteOptions::Terrain(), w.ground_height, 0);
    return new Scene{std::move(w), std::move(car)};
  }();
  return *s;
}

Rigid3d Pose(const Scene& s, double t_s, const Rigid3d& body_from_cam) {
  return s.route.At(static_cast<int64_t>(t_s * 1e9)).world_from_body * body_from_cam;
}

// The rig's grey stereo pair at these camera poses, and the left camera's z-buffer depth.
void RenderGreyPair(const Renderer& r, const SensorRig& rig, const Rigid3d& world_from_left,
                    const Rigid3d& world_from_right, cv::Mat* grey_left, cv::Mat* grey_right,
                    cv::Mat* depth) {
  cv::Mat left, right;
  r.Render(rig.left, world_from_left, &left, depth);
  r.Render(rig.right, world_from_right, &right);
  cv::cvtColor(left, *grey_left, cv::COLOR_BGR2GRAY);
  cv::cvtColor(right, *grey_right, cv::COLOR_BGR2GRAY);
}

TEST(Renderer, WorldsHaveEnoughCornersForFeatureTracking) {
  const SensorRig rig = DroneRig();  // 752x480
  auto fast = cv::FastFeatureDetector::create(20);
  auto orb = cv::ORB::create(1000);
  for (const auto& [name, scene] : {std::pair{"urban", &Urban()}, {"terrain", &Terrain()}}) {
    const Renderer r(scene->world);
    for (double t : {10.0, 40.0, 70.0}) {
      cv::Mat img, gray;
      r.Render(rig.left, Pose(*scene, t, CarRig().body_from_left), &img);
      cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
      std::vector<cv::KeyPoint> kf, ko;
      fast->detect(gray, kf);
      orb->detect(gray, ko);
      std::printf("%s t=%.0f s: %zu FAST corners (threshold 20), %zu ORB keypoints (min 300)\n",
                  name, t, kf.size(), ko.size());
      EXPECT_GT(kf.size(), 300u) << name << " t " << t;
      EXPECT_GT(ko.size(), 300u) << name << " t " << t;
    }
  }
}

// Stereo correspondences found in the rendered images (FAST corners in the left image, 9x9
// SSD block matching along the row of the right image, parabolic sub-pixel refinement),
// triangulated with the rig's geometry (corners off depth edges, within 30 m), recover the world
// points that the z-buffer says are there.
TEST(Renderer, TriangulatedStereoCorrespondencesRecoverWorldPoints) {
  const SensorRig rig = CarRig().Scaled(0.75);
  const Renderer r(Urban().world);
  std::vector<double> rel_errors;
  for (double t : {8.0, 30.0, 55.0}) {
    const Rigid3d wl = Pose(Urban(), t, rig.body_from_left);
    const Rigid3d wr = Pose(Urban(), t, rig.body_from_right);
    cv::Mat depth, gl, gr;
    RenderGreyPair(r, rig, wl, wr, &gl, &gr, &depth);
    std::vector<cv::KeyPoint> kps;
    cv::FastFeatureDetector::create(25)->detect(gl, kps);
    const int half = 4, max_disp = 120;
    for (const cv::KeyPoint& kp : kps) {
      const int x = cvRound(kp.pt.x), y = cvRound(kp.pt.y);
      if (x < half + max_disp || y < half || x >= gl.cols - half || y >= gl.rows - half) continue;
      const float d = depth.at<float>(y, x);
      if (!std::isfinite(d) || d > 30) continue;
      // Skip corners on depth discontinuities: their z-buffer depth may be either side's.
      double dmin, dmax;
      cv::minMaxLoc(depth(cv::Rect(x - 2, y - 2, 5, 5)), &dmin, &dmax);
      if (dmax > 1.05 * dmin) continue;
      const cv::Mat patch = gl(cv::Rect(x - half, y - half, 2 * half + 1, 2 * half + 1));
      std::vector<double> cost(max_disp + 1);
      for (int disp = 0; disp <= max_disp; ++disp) {
        cost[disp] =
            cv::norm(patch, gr(cv::Rect(x - disp - half, y - half, 2 * half + 1, 2 * half + 1)),
                     cv::NORM_L2SQR);
      }
      const int best = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
      if (best == 0 || best == max_disp) continue;
      // Unique minimum only (the second best, away from the minimum, is clearly worse).
      double second = 1e30;
      for (int k = 0; k <= max_disp; ++k) {
        if (std::abs(k - best) > 2) second = std::min(second, cost[k]);
      }
      if (cost[best] > 0.5 * second) continue;
      const double c0 = cost[best - 1], c1 = cost[best], c2 = cost[best + 1];
      const double sub = best + 0.5 * (c0 - c2) / std::max(1e-9, c0 - 2 * c1 + c2);
      const auto p = camera::TriangulateTwoView(wl.Inverse(), wr.Inverse(),
                                                rig.left.PixelToNormalized({double(x), double(y)}),
                                                rig.right.PixelToNormalized({x - sub, double(y)}));
      if (!p) continue;
      const Eigen::Vector3d truth = wl * (rig.left.Unproject({double(x), double(y)}) * d);
      const double range = (truth - wl.translation).norm();
      rel_errors.push_back((*p - truth).norm() / range);
    }
  }
  ASSERT_GT(rel_errors.size(), 100u);
  std::sort(rel_errors.begin(), rel_errors.end());
  const double median = rel_errors[rel_errors.size() / 2];
  const double p90 = rel_errors[rel_errors.size() * 9 / 10];
  std::printf(
      "%zu stereo correspondences: triangulation error / range median %.4f (max 0.01), "
      "90th percentile %.4f (max 0.05)\n",
      rel_errors.size(), median, p90);
  EXPECT_LT(median, 0.01);
  EXPECT_LT(p90, 0.05);
}

// The stereo pair carries no disparity bias: at the benchmark's 400x300, the disparity that
// sub-pixel block matching and KLT (the VIO frontend's left-to-right matcher: 21 px window, 3
// levels) measure at Shi-Tomasi corners agrees, in the median, with the z-buffer's to well under
// a tenth of a pixel. A half-pixel convention slip between the two cameras (a principal point
// off by 0.5 px) would show as a 0.5 px median; on the car route the stereo odometry's yaw drift
// moves by about 2 deg per 0.5 px of such an offset (docs/VIO.md, 2026-12-05), so the renderer
// must be ruled out as its source.
TEST(Renderer, StereoDisparityHasNoBias) {
  const SensorRig rig = CarRig().Scaled(0.5);
  const Renderer r(Urban().world);
  std::vector<double> bm, klt;
  for (double t : {8.0, 30.0, 55.0, 70.0, 90.0}) {
    const Rigid3d wl = Pose(Urban(), t, rig.body_from_left);
    const Rigid3d wr = Pose(Urban(), t, rig.body_from_right);
    cv::Mat depth, gl, gr;
    RenderGreyPair(r, rig, wl, wr, &gl, &gr, &depth);
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(gl, corners, 400, 0.01, 8);
    std::vector<cv::Point2f> pr = corners;
    std::vector<uchar> ok;
    std::vector<float> err;
    cv::calcOpticalFlowPyrLK(
        gl, gr, corners, pr, ok, err, cv::Size(21, 21), 3,
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01),
        cv::OPTFLOW_USE_INITIAL_FLOW);
    const int half = 4, max_disp = 60;
    for (size_t i = 0; i < corners.size(); ++i) {
      const int x = cvRound(corners[i].x), y = cvRound(corners[i].y);
      if (x < half + max_disp || y < half || x >= gl.cols - half || y >= gl.rows - half) continue;
      double dmin, dmax;
      cv::minMaxLoc(depth(cv::Rect(x - 2, y - 2, 5, 5)), &dmin, &dmax);
      if (!std::isfinite(dmax) || dmax > 1.05 * dmin || dmax > 40) continue;
      const Eigen::Vector2d px(corners[i].x, corners[i].y);
      const float d = depth.at<float>(y, x);
      const Eigen::Vector3d p_world = wl * (rig.left.Unproject(px) * d);
      const auto q = rig.right.Project(wr.Inverse() * p_world);
      if (!q) continue;
      const double truth = px.x() - q->x();
      if (ok[i] && std::abs(pr[i].y - q->y()) < 1) klt.push_back((px.x() - pr[i].x) - truth);
      const cv::Mat patch = gl(cv::Rect(x - half, y - half, 2 * half + 1, 2 * half + 1));
      std::vector<double> cost(max_disp + 1);
      for (int disp = 0; disp <= max_disp; ++disp)
        cost[disp] =
            cv::norm(patch, gr(cv::Rect(x - disp - half, y - half, 2 * half + 1, 2 * half + 1)),
                     cv::NORM_L2SQR);
      const int best = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
      if (best == 0 || best == max_disp) continue;
      const double c0 = cost[best - 1], c1 = cost[best], c2 = cost[best + 1];
      const double sub = best + 0.5 * (c0 - c2) / std::max(1e-9, c0 - 2 * c1 + c2);
      // Block matching at the integer pixel x: truth there is the truth at the corner shifted.
      const Eigen::Vector3d p2 =
          wl * (rig.left.Unproject({double(x), double(y)}) * depth.at<float>(y, x));
      const auto q2 = rig.right.Project(wr.Inverse() * p2);
      if (q2) bm.push_back(sub - (x - q2->x()));
    }
  }
  auto median = [](const std::vector<double>& v) { return v.empty() ? 0.0 : Median(v); };
  std::printf(
      "disparity error (measured - z-buffer), median: block matching %.3f px (%zu corners), KLT "
      "%.3f px (%zu); max 0.1 px\n",
      median(bm), bm.size(), median(klt), klt.size());
  ASSERT_GT(bm.size(), 100u);
  ASSERT_GT(klt.size(), 100u);
  EXPECT_LT(std::abs(median(bm)), 0.1);
  EXPECT_LT(std::abs(median(klt)), 0.1);
}

// Sampling is continuous in the mip level: crossing any lod by a hair changes no texel by more
// than a couple of grey levels (a nearest-level sampler jumps by up to 42 on the sidewalk between
// lod 1.499 and 1.501: a seam at a fixed distance from the camera, travelling with it, that makes
// corners no real camera sees). At an integer lod the sample is that level's bilinear sample.
// `--asphalt varied` (the default): nadir views of the road from 2 m, one period of its texture (8
// m of road) apart on a straight, show different asphalt. With `--asphalt tiled` they are the same
// image, and where fog or dust leave only the road visible the loop closer verified loops one or
// two periods off (docs/VIO.md, 2026-12-06 night).
TEST(Renderer, VariedAsphaltDoesNotRepeatEveryPeriod) {
  const Scene& varied = Urban();
  WorldOptions o;
  o.seed = 5;
  o.varied_asphalt = false;
  const World tiled_world = MakeWorld(o);
  const Renderer rt(tiled_world), rv(varied.world);
  const camera::PinholeCamera cam = camera::PinholeCamera::FromHorizontalFov(160, 120, M_PI / 3);
  const Rigid3d body_from_cam = ForwardCamera({0, 0, 2.0}, M_PI / 2);
  // Mean absolute difference (grey levels) of two views of one world.
  auto mad = [&](const Renderer& r, const Rigid3d& a, const Rigid3d& b) {
    cv::Mat ia, ib, ga, gb, d;
    r.Render(cam, a * body_from_cam, &ia);
    r.Render(cam, b * body_from_cam, &ib);
    cv::cvtColor(ia, ga, cv::COLOR_BGR2GRAY);
    cv::cvtColor(ib, gb, cv::COLOR_BGR2GRAY);
    cv::absdiff(ga, gb, d);
    return cv::mean(d)[0];
  };
  int straight = 0, tiled_same = 0, varied_differ = 0;
  for (double t0 = 8; t0 < 95; t0 += 7) {
    const Rigid3d a = varied.route.At(static_cast<int64_t>(t0 * 1e9)).world_from_body;
    // The pose 8 m further along (Euclidean: equal to the arc length on a straight).
    int64_t t1 = static_cast<int64_t>(t0 * 1e9);
    Rigid3d b = a;
    while ((b.translation - a.translation).head<2>().norm() < 8.0 && t1 < varied.route.end_ns()) {
      t1 += 1'000'000;
      b = varied.route.At(t1).world_from_body;
    }
    if (Eigen::AngleAxisd(a.rotation.inverse() * b.rotation).angle() > 0.2 * M_PI / 180) continue;
    ++straight;
    const double m_tiled = mad(rt, a, b), m_varied = mad(rv, a, b);
    std::printf(
        "road at %.0f s and 8 m further: mean absolute difference %.1f grey levels tiled, %.1f "
        "varied\n",
        t0, m_tiled, m_varied);
    tiled_same += m_tiled < 3 ? 1 : 0;
    varied_differ += m_varied > 5 ? 1 : 0;
  }
  ASSERT_GE(straight, 5);
  EXPECT_EQ(tiled_same, straight) << "the premise: one texture repeats every 8 m";
  // 8 variants picked by a hash per period: about 1 in 8 neighbours repeat by chance.
  EXPECT_GE(varied_differ, straight - 2) << "of " << straight << " straight pairs";
}

// The terrain's ground (since 2026-12-07): level views straight down from 2 m, one 5 m cell
// apart, show different grass or soil. Before, each was one texture repeating every 5 m, and
// where dust left only the ground within 15-20 m in view the stereo loop closer verified 36 loops
// between the route's end and its start 50 m away, whole periods apart (docs/VIO.md). Measured
// with one variant per surface (the old repetition): 22 of these 26 pairs correlate at 0.53-0.96,
// the other 4 straddle grass and soil; with 8 variants 24 of 26 are below 0.5.
TEST(Renderer, TerrainGroundDoesNotRepeatEveryCell) {
  const Scene& terrain = Terrain();
  const Renderer r(terrain.world);
  const camera::PinholeCamera cam = camera::PinholeCamera::FromHorizontalFov(160, 120, M_PI / 3);
  const Rigid3d body_from_cam = ForwardCamera({0, 0, 2.0}, M_PI / 2);
  auto grey = [&](const Rigid3d& world_from_body) {
    cv::Mat img, g;
    r.Render(cam, world_from_body * body_from_cam, &img);
    cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
    return g;
  };
  int pairs = 0, differ = 0;
  for (double t0 = 8; t0 < 95; t0 += 7) {
    Rigid3d a = terrain.route.At(static_cast<int64_t>(t0 * 1e9)).world_from_body;
    a.rotation = Eigen::Quaterniond::Identity();  // level, facing +x: the cells' axes
    a.translation.z() = terrain.world.ground_height(a.translation.x(), a.translation.y());
    for (const Eigen::Vector2d& step : {Eigen::Vector2d(5, 0), Eigen::Vector2d(0, 5)}) {
      Rigid3d b = a;
      b.translation.head<2>() += step;
      b.translation.z() = terrain.world.ground_height(b.translation.x(), b.translation.y());
      // Zero-mean normalised cross-correlation: the shading and the slope change the grey
      // levels between two cells of one texture, not the pattern.
      cv::Mat zncc;
      cv::matchTemplate(grey(a), grey(b), zncc, cv::TM_CCOEFF_NORMED);
      const double c = zncc.at<float>(0, 0);
      std::printf("ground at %.0f s and 5 m further along %s: correlation %.2f (< 0.5)\n", t0,
                  step.x() > 0 ? "x" : "y", c);
      ++pairs;
      differ += c < 0.5 ? 1 : 0;
    }
  }
  ASSERT_GE(pairs, 20);
  // 8 variants picked by a hash per cell: about 1 in 8 neighbours repeat by chance.
  EXPECT_GE(differ, pairs - pairs / 4) << "of " << pairs << " pairs";
}

TEST(Texture, SamplingIsContinuousInTheMipLevel) {
  const Texture tex(MakeSurfaceImage(SurfaceKind::kSidewalk, 3));
  ASSERT_GE(tex.levels(), 5);
  int worst = 0;
  for (float lod = 0.25f; lod < tex.levels() - 1.5f; lod += 0.25f) {
    for (int i = 0; i < 400; ++i) {
      const double u = 0.013 + 0.0371 * i, v = 0.29 + 0.0173 * i;
      uint8_t a[3], b[3];
      tex.Sample(u, v, lod - 0.001f, a);
      tex.Sample(u, v, lod + 0.001f, b);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int(a[c]) - int(b[c])));
    }
  }
  std::printf("largest change across lod +- 0.001: %d grey levels; max 2\n", worst);
  EXPECT_LE(worst, 2);
  // At lod 2 exactly: level 2's texel centre (texel (5, 7) is at u = (5 + 0.5) / n).
  const int n = tex.level(2).cols;
  uint8_t s[3];
  tex.Sample((5 + 0.5) / n, (7 + 0.5) / n, 2.0f, s);
  const cv::Vec3b texel = tex.level(2).at<cv::Vec3b>(7, 5);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(s[c], texel[c], 1) << c;
}

TEST(Renderer, OutputDoesNotDependOnTheThreadCount) {
  const SensorRig rig = CarRig().Scaled(0.4);
  const Renderer r(Urban().world);
  const Rigid3d pose = Pose(Urban(), 20, rig.body_from_left);
  cv::Mat a, b, da, db;
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  r.Render(rig.left, pose, &a, &da);
  cv::setNumThreads(std::max(2, threads));
  r.Render(rig.left, pose, &b, &db);
  cv::setNumThreads(threads);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_EQ(cv::countNonZero(da != db), 0);
}

// A distorted camera sees each world point where its own projection model puts it: the depth
// it renders at a pixel, unprojected through the distortion model, lands on the surface the
// undistorted camera renders at that point's pinhole projection.
TEST(Renderer, DistortedCamerasFollowTheirModel) {
  camera::PinholeCamera dist = CarRig().Scaled(0.4).left;
  dist.distortion = camera::DistortionModel::kRadialTangential;
  dist.coeffs = {-0.28, 0.07, 0.0002, 0.00002};
  camera::PinholeCamera pin = dist;
  pin.distortion = camera::DistortionModel::kNone;
  pin.width *= 2;
  pin.height *= 2;
  pin.cx = pin.cx * 2 + 0.5;
  pin.cy = pin.cy * 2 + 0.5;
  const Renderer r(Urban().world);
  const Rigid3d pose = Pose(Urban(), 25, CarRig().body_from_left);
  cv::Mat img_d, depth_d, img_p, depth_p;
  r.Render(dist, pose, &img_d, &depth_d);
  r.Render(pin, pose, &img_p, &depth_p);
  int checked = 0, agree = 0;
  for (int y = 5; y < dist.height - 5; y += 7) {
    for (int x = 5; x < dist.width - 5; x += 7) {
      const float d = depth_d.at<float>(y, x);
      if (!std::isfinite(d) || d > 60) continue;
      const Eigen::Vector3d p = dist.Unproject({double(x), double(y)}) * d;
      const auto q = pin.Project(p);
      if (!q || !pin.InImage(*q, 2)) continue;
      ++checked;
      const float dp = depth_p.at<float>(cvRound(q->y()), cvRound(q->x()));
      agree += std::abs(dp - d) < 0.03 * d;
    }
  }
  const double ratio = static_cast<double>(agree) / checked;
  std::printf(
      "distorted camera: %d of %d sampled pixels agree with the pinhole render (%.3f, "
      "min 0.95)\n",
      agree, checked, ratio);
  EXPECT_GT(checked, 300);
  EXPECT_GT(ratio, 0.95);
}

}  // namespace
}  // namespace optinav::sim
