#include "optinav/vio/internal/frontend.h"

#include <cstdio>
#include <map>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/io/euroc_dataset.h"
#include "optinav/util/testing.h"

namespace optinav::vio {
namespace {

io::EurocDataset OpenMicro() {
  io::EurocOpenOptions open;
  open.drop_missing_images = true;
  return io::OpenEurocDataset(
      (optinav::testing::SharedDataDir() / "euroc" / "V1_01_micro").string(), open);
}

TEST(Frontend, TracksAndMatchesOnEuroc) {
  const io::EurocDataset ds = OpenMicro();
  const camera::StereoRig rig = io::ToStereoRig(ds.cam0->calibration, ds.cam1->calibration);
  StereoFrontend frontend(rig, FrontendOptions{});
  int frames = 0, stereo = 0, tracked = 0, previous = 0, keyframes = 0;
  double max_epipolar_px = 0;
  const Eigen::Matrix3d E =
      Hat(rig.right_from_left.translation) * rig.right_from_left.rotation.toRotationMatrix();
  std::map<int64_t, std::string> rights;
  for (const auto& r : ds.cam1->images) rights[r.t_ns] = r.path;
  for (size_t i = 0; i < 20; ++i) {
    const auto& l = ds.cam0->images[i];
    const cv::Mat left = cv::imread(l.path, cv::IMREAD_GRAYSCALE);
    const auto r = rights.find(l.t_ns);
    if (r == rights.end()) continue;
    const std::string right_path = r->second;
    const cv::Mat right = cv::imread(right_path, cv::IMREAD_GRAYSCALE);
    if (right.empty()) continue;
    const FrontendOutput out = frontend.Process(l.t_ns, left, right, std::nullopt, true);
    ++frames;
    keyframes += out.keyframe ? 1 : 0;
    if (frames > 1) tracked += out.stats.tracked, previous += 150;
    stereo += out.stats.stereo;
    EXPECT_LE(out.observations.size(), 150u);
    for (const StereoObservation& o : out.observations) {
      if (!o.right) continue;
      const Eigen::Vector3d xl(o.left.x(), o.left.y(), 1), xr(o.right->x(), o.right->y(), 1);
      const Eigen::Vector3d line = E * xl;
      max_epipolar_px =
          std::max(max_epipolar_px, std::abs(xr.dot(line)) / line.head<2>().norm() * rig.left.fx);
    }
  }
  ASSERT_GE(frames, 15);
  const double stereo_per_frame = static_cast<double>(stereo) / frames;
  const double track_ratio = static_cast<double>(tracked) / previous;
  std::printf(
      "EuRoC V1_01_micro, %d frames: %.0f stereo matches per frame (> 40), %.2f of "
      "features tracked frame to frame (> 0.8), max epipolar distance %.2f px (<= 2), "
      "%d keyframes\n",
      frames, stereo_per_frame, track_ratio, max_epipolar_px, keyframes);
  EXPECT_GT(stereo_per_frame, 40);
  EXPECT_GT(track_ratio, 0.8);
  EXPECT_LE(max_epipolar_px, 2.0 + 1e-9);
  EXPECT_GE(keyframes, 1);
}

TEST(Frontend, BlackFramesGiveNoFeaturesAndNoCrash) {
  const io::EurocDataset ds = OpenMicro();
  const camera::StereoRig rig = io::ToStereoRig(ds.cam0->calibration, ds.cam1->calibration);
  StereoFrontend frontend(rig, FrontendOptions{});
  const cv::Mat black(rig.left.height, rig.left.width, CV_8UC1, cv::Scalar(0));
  const cv::Mat real = cv::imread(ds.cam0->images[0].path, cv::IMREAD_GRAYSCALE);
  EXPECT_GT(frontend.Process(1, real, real, std::nullopt).observations.size(), 50u);
  const FrontendOutput out = frontend.Process(2, black, black, std::nullopt);
  EXPECT_EQ(out.stats.stereo, 0);
  EXPECT_LT(out.observations.size(), 5u);
  EXPECT_GT(frontend.Process(3, real, real, std::nullopt).observations.size(), 50u);
}

TEST(Frontend, OptionsAreChecked) {
  FrontendOptions o;
  EXPECT_EQ(o.Check(), "");
  o.max_features = 2;
  EXPECT_NE(o.Check().find("max_features"), std::string::npos);
}

}  // namespace
}  // namespace optinav::vio
