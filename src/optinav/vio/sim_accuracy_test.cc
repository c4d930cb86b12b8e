// Accuracy on simulated image sequences (optinav sim: rendered urban world, realistic IMU noise),
// fixed seeds. Half-resolution images (376x240) keep the test short; the full-size figures are
// in docs/VIO.md.
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <optional>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "optinav/eval/metrics.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/sim/renderer.h"
#include "optinav/sim/rig.h"
#include "optinav/sim/simulation.h"
#include "optinav/sim/trajectory.h"
#include "optinav/sim/weather.h"
#include "optinav/sim/world.h"
#include "optinav/util/statistics.h"
#include "optinav/util/testing.h"
#include "optinav/vio/internal/frontend.h"
#include "optinav/vio/pipeline.h"

namespace optinav::vio {
namespace {

struct Accuracy {
  double path_m = 0, ape_rmse_m = 0, ape_mean_m = 0, end_m = 0, yaw_drift_deg = 0;
  size_t poses = 0, lost = 0;
  std::string init;
};

double Yaw(const Eigen::Matrix3d& r) { return std::atan2(r(1, 0), r(0, 0)); }

// `se3`: APE after SE(3) alignment; else after making the first poses coincide (a straight
// start is degenerate for SE(3) alignment, and stereo-only has no gravity direction).
Accuracy Evaluate(const std::string& dir, const VioRunResult& r, bool se3 = true) {
  Accuracy a;
  a.poses = r.estimates.size();
  a.lost = r.lost.size();
  a.init = r.first_init_kind;
  const Trajectory gt = io::ReadTrajectory(dir + "/mav0/state_groundtruth_estimate0/data.csv");
  eval::SyncedPair synced = eval::Synchronize(gt, EstimatesToTrajectory(r.estimates));
  a.path_m = synced.ref.PathLength();
  Trajectory aligned = synced.est;
  if (se3) {
    eval::AlignTrajectory(synced.ref, &aligned, {.mode = eval::AlignMode::kSe3});
  } else {
    eval::AlignTrajectory(synced.ref, &aligned,
                          {.mode = eval::AlignMode::kNone, .align_origin = true});
  }
  std::vector<double> errors;
  for (size_t i = 0; i < aligned.size(); ++i)
    errors.push_back((aligned.positions[i] - synced.ref.positions[i]).norm());
  const eval::Statistics s = eval::ComputeStatistics(errors);
  a.ape_rmse_m = s.rmse;
  a.ape_mean_m = s.mean;
  a.end_m = errors.empty() ? 0.0 : errors.back();
  if (!se3) return a;
  // Gravity-aligned yaw error: the estimate aligned in position + yaw (4-DoF, gravity kept) on
  // the first second, then the yaw of estimate minus the yaw of the ground truth per pose.
  Trajectory start_aligned = synced.est;
  eval::AlignTrajectory(synced.ref, &start_aligned,
                        {.mode = eval::AlignMode::kPosYaw, .n_to_align = 20});
  auto yaw_error = [&](size_t i) {
    double d = Yaw(start_aligned.rotations[i]) - Yaw(synced.ref.rotations[i]);
    return std::remainder(d, 2 * M_PI);
  };
  // Drift = least-squares slope of the yaw error against the distance travelled, from 1 s on
  // (robust to the end points; the yaw error is unwrapped along the way).
  std::vector<double> dist{0.0}, yaw{yaw_error(0)};
  for (size_t i = 1; i < aligned.size(); ++i) {
    dist.push_back(dist.back() + (synced.ref.positions[i] - synced.ref.positions[i - 1]).norm());
    yaw.push_back(yaw.back() + std::remainder(yaw_error(i) - yaw.back(), 2 * M_PI));
  }
  double sd = 0, sy = 0, sdd = 0, sdy = 0, n = 0;
  for (size_t i = 20; i < dist.size(); ++i)
    sd += dist[i], sy += yaw[i], sdd += dist[i] * dist[i], sdy += dist[i] * yaw[i], ++n;
  const double slope = (n * sdy - sd * sy) / (n * sdd - sd * sd);  // rad per m
  a.yaw_drift_deg = std::abs(slope) * a.path_m * 180 / M_PI;
  return a;
}

// `varied_asphalt` false: the urban road as rendered before 2026-12-06, one asphalt texture
// repeating every 8 m (`optinav sim --asphalt tiled`), for the cases found on it whose premise
// the varied road does not reproduce (each says what it measured there). `camera_noise` false
// (`sim --camera-noise off`): rendered without the cameras' noise, as every case found before
// 2026-12-07 was measured; the cases with noise say so.
std::string Simulate(const std::string& name, const std::string& route, double duration_s,
                     double speed, double altitude, uint64_t seed,
                     const std::string& weather = "none", double scale = 0.5,
                     bool varied_asphalt = true, sim::WorldKind world = sim::WorldKind::kUrban,
                     bool camera_noise = false) {
  sim::SimulationOptions o;
  o.camera_noise.enabled = camera_noise;
  o.world.kind = world;
  o.world.varied_asphalt = varied_asphalt;
  o.route = route;
  o.duration_s = duration_s;
  o.speed_m_s = speed;
  o.altitude_m = altitude;
  o.seed = seed;
  o.scale = scale;
  o.weather = sim::ParseWeather(weather);
  o.out_dir = (optinav::testing::MakeTempDir("vio_sim_" + name) / "seq").string();
  sim::RunSimulation(o);
  return o.out_dir;
}

// One stereo frame of the car route as rendered (clear), with its z-buffers.
struct RenderedFrame {
  int64_t t_ns = 0;
  Rigid3d world_from_left, world_from_right;
  cv::Mat left, right, depth, depth_right;
};

RenderedFrame RenderFrame(const sim::Renderer& renderer, const sim::BodyTrajectory& car,
                          const sim::SensorRig& rig, double t_s) {
  RenderedFrame f;
  f.t_ns = static_cast<int64_t>(t_s * 1e9);
  const Rigid3d world_from_body = car.At(f.t_ns).world_from_body;
  f.world_from_left = world_from_body * rig.body_from_left;
  f.world_from_right = world_from_body * rig.body_from_right;
  renderer.Render(rig.left, f.world_from_left, &f.left, &f.depth);
  renderer.Render(rig.right, f.world_from_right, &f.right, &f.depth_right);
  return f;
}

// Frame chains of the urban car route at the benchmark's 400x300, clear, with their z-buffers:
// `frames` consecutive frames (30 Hz) from each start time.
struct RenderedScene {
  sim::SensorRig rig = sim::CarRig().Scaled(0.5);
  std::vector<std::vector<RenderedFrame>> chains;
};

RenderedScene RenderScene(const std::vector<double>& starts_s, int frames) {
  sim::WorldOptions wo;
  wo.seed = 5;
  const sim::World world = sim::MakeWorld(wo);
  const sim::BodyTrajectory car =
      sim::MakeCarTrajectory(sim::CarRouteOptions::Urban(), world.ground_height, 0);
  const sim::Renderer renderer(world);
  RenderedScene scene;
  for (double start : starts_s) {
    std::vector<RenderedFrame> chain;
    for (int k = 0; k < frames; ++k)
      chain.push_back(RenderFrame(renderer, car, scene.rig, start + k / 30.0));
    scene.chains.push_back(std::move(chain));
  }
  return scene;
}

// Five single frames.
RenderedScene RenderDisparityScene() { return RenderScene({8.0, 30.0, 55.0, 70.0, 90.0}, 1); }

// The z-buffer depth at a sub-pixel corner, or nullopt near a depth edge or the border.
std::optional<double> DepthAt(const cv::Mat& depth, const Eigen::Vector2d& px) {
  const int x0 = static_cast<int>(std::floor(px.x()));
  const int y0 = static_cast<int>(std::floor(px.y()));
  if (x0 < 3 || y0 < 3 || x0 >= depth.cols - 4 || y0 >= depth.rows - 4) return std::nullopt;
  double dmin, dmax;
  cv::minMaxLoc(depth(cv::Rect(x0 - 2, y0 - 2, 6, 6)), &dmin, &dmax);
  if (!std::isfinite(dmax) || dmax > 1.05 * dmin) return std::nullopt;
  const double ax = px.x() - x0, ay = px.y() - y0;
  return (1 - ay) * ((1 - ax) * depth.at<float>(y0, x0) + ax * depth.at<float>(y0, x0 + 1)) +
         ay * ((1 - ax) * depth.at<float>(y0 + 1, x0) + ax * depth.at<float>(y0 + 1, x0 + 1));
}

// Each stereo observation's disparity error (measured - true, px) on the scene's frames with the
// image effects of `weather` (haze and particles; the ground's surface stays clear): its
// right-image x against where the z-buffer puts the left observation's point (depth interpolated
// at the sub-pixel corner, corners off depth edges), split at 15 m.
// `right_gain`, `right_offset`: the right image's grey levels scaled and shifted, as a real
// camera pair exposes each camera on its own.
void DisparityErrors(const RenderedScene& scene, const std::string& weather,
                     std::vector<double>* near, std::vector<double>* far,
                     const FrontendOptions& options = FrontendOptions(), double right_gain = 1.0,
                     double right_offset = 0.0) {
  const sim::SensorRig& rig = scene.rig;
  const camera::StereoRig stereo{rig.left, rig.right,
                                 rig.body_from_right.Inverse() * rig.body_from_left};
  const sim::WeatherSpec spec = sim::ParseWeather(weather);
  for (const auto& chain : scene.chains) {
    const RenderedFrame& f = chain.front();
    cv::Mat left = f.left.clone(), right = f.right.clone(), grey_left, grey_right;
    sim::ApplyWeather(left, f.depth, rig.left, f.world_from_left, f.t_ns, spec, 1);
    sim::ApplyWeather(right, f.depth_right, rig.right, f.world_from_right, f.t_ns, spec, 1);
    cv::cvtColor(left, grey_left, cv::COLOR_BGR2GRAY);
    cv::cvtColor(right, grey_right, cv::COLOR_BGR2GRAY);
    if (right_gain != 1.0 || right_offset != 0.0)
      grey_right.convertTo(grey_right, -1, right_gain, right_offset);
    StereoFrontend frontend(stereo, options);
    const FrontendOutput out = frontend.Process(f.t_ns, grey_left, grey_right, std::nullopt, true);
    for (const StereoObservation& obs : out.observations) {
      if (!obs.right) continue;
      const auto left_px = rig.left.Project(obs.left.homogeneous());
      const auto right_px = rig.right.Project(obs.right->homogeneous());
      if (!left_px || !right_px) continue;
      const Eigen::Vector2d px = *left_px;
      const std::optional<double> d = DepthAt(f.depth, px);
      if (!d) continue;
      const Eigen::Vector3d p_world = f.world_from_left * (rig.left.Unproject(px) * *d);
      const auto truth = rig.right.Project(f.world_from_right.Inverse() * p_world);
      if (!truth) continue;
      // Measured minus true disparity.
      const double error = truth->x() - right_px->x();
      (*d < 15 ? near : far)->push_back(error);
    }
  }
}

double MedianAbs(const std::vector<double>& errors) {
  std::vector<double> a;
  for (double e : errors) a.push_back(std::abs(e));
  return Median(a);
}

// The frontend's stereo matches carry no disparity bias, in clear weather and in the haze and
// particles of the weather suite. The stereo odometry's yaw drift on the car route moves by about
// 2 deg per 0.5 px of disparity offset (docs/VIO.md, 2026-12-05), so a frontend bias of that size
// must show here. Measured 2026-12-06 (median near < 15 m / far, px): clear -0.05 / -0.02, fog
// 100 % 0.00 / +0.08, dust 100 % -0.01 / +0.07, leaves 50 % -0.03 / +0.03, against the 0.2 px
// bound: the weather spreads the errors (median |error| near 0.34 px clear, 0.57 px in dust
// 100 %) but does not shift them, so the stereo odometry's drift in dust is not a scale bias.
TEST(SimAccuracy, FrontendStereoDisparityHasNoBias) {
  const RenderedScene scene = RenderDisparityScene();  // rendered once, each weather on a copy
  for (const char* weather : {"none", "fog:100", "dust:100", "leaves:50"}) {
    SCOPED_TRACE(weather);
    std::vector<double> near, far;
    DisparityErrors(scene, weather, &near, &far);
    ASSERT_GT(near.size(), 50u);
    ASSERT_GT(far.size(), 20u);
    std::printf(
        "%s: frontend disparity error (measured - z-buffer), median: near (< 15 m) %.3f px (%zu; "
        "median |error| %.3f px), far %.3f px (%zu); max 0.2 px\n",
        weather, Median(near), near.size(), MedianAbs(near), Median(far), far.size());
    EXPECT_LT(std::abs(Median(near)), 0.2);
    EXPECT_LT(std::abs(Median(far)), 0.2);
  }
}

// The stereo refinement (frontend.stereo_refine_window_px, opt-in) places the near matches
// closer to the truth than the 21 px stereo window alone, whose window spans the slanted road:
// measured 2026-12-07, median |error| near (< 15 m), px, without / with: clear 0.34 / 0.13, fog
// 100 % 0.43 / 0.15, dust 100 % 0.57 / 0.13, leaves 50 % 0.36 / 0.14; with the right image at
// 0.9x contrast and 8 grey levels up, 0.39 / 0.12 (EuRoC's right camera: about 1.1x and +4.5).
// The refinement fits a gain and an offset of the right image: plain KLT over 9 px shifted
// EuRoC's matches by a median 0.9 px.
TEST(SimAccuracy, StereoRefinementPlacesNearMatchesCloser) {
  const RenderedScene scene = RenderDisparityScene();
  FrontendOptions refined;
  refined.stereo_refine_window_px = 9;
  struct Case {
    const char* weather;
    double gain, offset;
  };
  for (const Case& c :
       {Case{"none", 1.0, 0.0}, Case{"fog:100", 1.0, 0.0}, Case{"dust:100", 1.0, 0.0},
        Case{"leaves:50", 1.0, 0.0}, Case{"none", 0.9, 8.0}}) {
    SCOPED_TRACE(std::string(c.weather) + ", right image gain " + std::to_string(c.gain));
    std::vector<double> near0, far0, near1, far1;
    DisparityErrors(scene, c.weather, &near0, &far0, FrontendOptions(), c.gain, c.offset);
    DisparityErrors(scene, c.weather, &near1, &far1, refined, c.gain, c.offset);
    std::printf(
        "%s, right image x%.2f %+.0f: near median |disparity error| %.3f px (21 px window, %zu) "
        "-> %.3f px refined (%zu; < 0.6x), median %.3f px (|.| < 0.1), far %.3f px (%zu)\n",
        c.weather, c.gain, c.offset, MedianAbs(near0), near0.size(), MedianAbs(near1), near1.size(),
        Median(near1), Median(far1), far1.size());
    ASSERT_GT(near1.size(), 50u);
    ASSERT_GT(far1.size(), 20u);
    EXPECT_LT(MedianAbs(near1), 0.6 * MedianAbs(near0));
    EXPECT_LT(std::abs(Median(near1)), 0.1);
    EXPECT_LT(std::abs(Median(far1)), 0.2);
  }
}

// Each temporal track's error at the chain's last frame against where the z-buffer puts the
// point it started on (tracks born in the chain's first frame only): `along` the true image
// motion (negative: the track lags, pulled towards no motion) and `abs` its length, px.
void TrackErrors(const RenderedScene& scene, const std::string& weather,
                 const FrontendOptions& options, std::vector<double>* along,
                 std::vector<double>* abs_error) {
  const sim::SensorRig& rig = scene.rig;
  const camera::StereoRig stereo{rig.left, rig.right,
                                 rig.body_from_right.Inverse() * rig.body_from_left};
  const sim::WeatherSpec spec = sim::ParseWeather(weather);
  for (const auto& chain : scene.chains) {
    StereoFrontend frontend(stereo, options);
    std::map<uint64_t, Eigen::Vector3d> born;  // track id -> world point
    FrontendOutput out;
    for (size_t k = 0; k < chain.size(); ++k) {
      const RenderedFrame& f = chain[k];
      cv::Mat left = f.left.clone(), right = f.right.clone(), grey_left, grey_right;
      sim::ApplyWeather(left, f.depth, rig.left, f.world_from_left, f.t_ns, spec, 1);
      sim::ApplyWeather(right, f.depth_right, rig.right, f.world_from_right, f.t_ns, spec, 1);
      cv::cvtColor(left, grey_left, cv::COLOR_BGR2GRAY);
      cv::cvtColor(right, grey_right, cv::COLOR_BGR2GRAY);
      out = frontend.Process(f.t_ns, grey_left, grey_right, std::nullopt, k == 0);
      if (k != 0) continue;
      for (const StereoObservation& obs : out.observations) {
        const auto px = rig.left.Project(obs.left.homogeneous());
        if (!px) continue;
        if (const auto d = DepthAt(f.depth, *px))
          born[obs.track_id] = f.world_from_left * (rig.left.Unproject(*px) * *d);
      }
    }
    const RenderedFrame& first = chain.front();
    const RenderedFrame& last = chain.back();
    for (const StereoObservation& obs : out.observations) {
      const auto it = born.find(obs.track_id);
      if (it == born.end()) continue;
      const auto measured = rig.left.Project(obs.left.homogeneous());
      const auto truth = rig.left.Project(last.world_from_left.Inverse() * it->second);
      const auto start = rig.left.Project(first.world_from_left.Inverse() * it->second);
      if (!measured || !truth || !start) continue;
      const Eigen::Vector2d motion = *truth - *start;
      if (motion.norm() < 2.0) continue;  // no direction to lag along
      const Eigen::Vector2d error = *measured - *truth;
      along->push_back(error.dot(motion.normalized()));
      abs_error->push_back(error.norm());
    }
  }
}

// Haze is a veil fixed in the image that the texture flows through; plain pyramidal KLT takes
// its gradient for texture and lags behind the true motion (docs/VIO.md, 2026-12-05 last). The
// temporal refinement with a gain and an offset (frontend.klt_gain_offset) absorbs it. Measured
// 2026-12-07 over 5 frames on ten stretches of the urban car route (error along the true motion,
// median, px; plain -> refined): clear +0.007 -> +0.033 (median |error| 0.191 -> 0.214), fog
// 100 % -0.152 -> -0.004 (0.504 -> 0.317), dust 100 % -0.365 -> -0.312 (0.692 -> 0.516). In
// dust the lag stays: CLAHE turns the noise-free haze's 8-bit steps into contours fixed in the
// image (without CLAHE the few tracks left lag -0.27 px plain and -0.04 px refined).
TEST(SimAccuracy, TemporalTracksLagInHazeUnlessGainAndOffsetAreFitted) {
  FrontendOptions refined;
  refined.klt_gain_offset = true;
  const RenderedScene scene = RenderScene({8, 14, 20, 26, 32, 38, 44, 50, 56, 62}, 6);
  struct Result {
    std::vector<double> along0, abs0, along1, abs1;
  };
  std::map<std::string, Result> results;
  for (const char* weather : {"none", "fog:100", "dust:100"}) {
    Result& r = results[weather];
    TrackErrors(scene, weather, FrontendOptions(), &r.along0, &r.abs0);
    TrackErrors(scene, weather, refined, &r.along1, &r.abs1);
    std::printf(
        "urban %s, tracks over 5 frames: error along the true motion, median %.3f px (%zu; median "
        "|error| %.3f px) -> refined %.3f px (%zu; %.3f px)\n",
        weather, Median(r.along0), r.along0.size(), Median(r.abs0), Median(r.along1),
        r.along1.size(), Median(r.abs1));
    ASSERT_GT(r.along1.size(), 25u) << weather;
  }
  const Result& clear = results["none"];
  const Result& fog = results["fog:100"];
  EXPECT_LT(Median(fog.along0), -0.1) << "the case: plain KLT lags in fog";
  EXPECT_LT(std::abs(Median(fog.along1)), 0.05) << "refined, fog";
  EXPECT_LT(Median(fog.abs1), 0.8 * Median(fog.abs0)) << "refined, fog";
  EXPECT_LT(std::abs(Median(clear.along1)), 0.05) << "refined, clear";
  EXPECT_LT(Median(clear.abs1), 1.25 * Median(clear.abs0)) << "refined, clear";
}

TEST(SimAccuracy, DroneStereoInertial) {
  const std::string dir = Simulate("drone", "drone", 15.0, 4.0, 6.0, 5);
  VioRunOptions options;
  const VioRunResult r = RunVioOnEuroc(dir, options);
  const Accuracy a = Evaluate(dir, r);
  const double ate_percent = 100 * a.ape_rmse_m / a.path_m;
  const double yaw_per_100m = a.yaw_drift_deg / a.path_m * 100;
  std::printf(
      "simulated drone, urban, 6 m altitude, 4 m/s, 15 s, 376x240: %zu poses, %s init, %zu "
      "lost; path %.1f m, APE RMSE (SE3) %.3f m = %.2f %% of distance (< 0.5 %%), yaw "
      "drift (slope over distance) %.2f deg = %.2f deg/100 m (< 1); median frame %.1f ms\n",
      a.poses, a.init.c_str(), a.lost, a.path_m, a.ape_rmse_m, ate_percent, a.yaw_drift_deg,
      yaw_per_100m, r.timing.at("total").median_s * 1e3);
  EXPECT_EQ(a.init, "in-motion-aligned");
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(ate_percent, 0.5);
  EXPECT_LT(yaw_per_100m, 1.0);
  // The loose-prior in-motion start on the same flight (the closed form's fallback).
  VioRunOptions priors;
  priors.vio.motion_init_window_s = 0;
  const Accuracy b = Evaluate(dir, RunVioOnEuroc(dir, priors));
  std::printf(
      "same flight, loose-prior in-motion start: %s init, APE RMSE (SE3) %.3f m = %.2f %% "
      "(< 0.5 %%)\n",
      b.init.c_str(), b.ape_rmse_m, 100 * b.ape_rmse_m / b.path_m);
  EXPECT_EQ(b.init, "in-motion-priors");
  EXPECT_LT(100 * b.ape_rmse_m / b.path_m, 0.5);
}

// The in-motion start on a drone that takes off and accelerates (seed 2, 6 m, 4 m/s, 226x144,
// the varied road). Each 1 s alignment of the stereo odometry with the IMU misjudges gravity by
// 0.2-14 deg (measured over 20 seeds, 2026-12-07): the odometry drifts 0.05-0.6 m over the
// window, and the alignment's residual test does not tell a good window from a bad one. Here
// the first window that passed it (1.4-2.4 s, odometry 5 % long over the stretch with 0-8
// stereo points) was 14 deg off, and the flight ended 1.74 m APE. The start now waits for the
// next window (slid by half) to agree on gravity, then aligns both together.
TEST(SimAccuracy, DroneInMotionStartWaitsForTwoAlignmentsToAgree) {
  const std::string dir = Simulate("takeoff", "drone", 10.0, 4.0, 6.0, 2, "none", 0.3);
  const Accuracy a = Evaluate(dir, RunVioOnEuroc(dir, VioRunOptions{}));
  VioRunOptions single;  // the start before 2026-12-07
  single.vio.motion_init_agreement_rad = 0;
  single.vio.motion_init_agreement_sigmas = 0;
  single.vio.motion_init_max_whitened_residual = 8;
  const Accuracy b = Evaluate(dir, RunVioOnEuroc(dir, single));
  std::printf(
      "simulated drone take-off, 6 m, 4 m/s, 226x144, %.1f m: two agreeing alignments: %zu poses, "
      "APE RMSE (SE3) %.3f m (< 0.3); the first alignment that passes: %zu poses, %.3f m\n",
      a.path_m, a.poses, a.ape_rmse_m, b.poses, b.ape_rmse_m);
  EXPECT_GT(b.ape_rmse_m, 1.0) << "the case this test is about: a single window's wrong gravity";
  EXPECT_EQ(a.init, "in-motion-aligned");
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_rmse_m, 0.3);
  EXPECT_GE(a.poses, b.poses);  // the first window that agrees is no later here
}

// A drone cruising at constant velocity is still to the IMU. On `bench gnss`'s outdoor flight
// (seed 7, 10 m, 5 m/s, 226x144) the in-motion alignment fails on the small images until 12 s,
// and at 6.8 s the IMU window was still (gyro 0.018 rad/s, accel 0.12 m/s^2 block spread): the
// start took the drone as parked (velocity 0) and its estimate ran 225 m off over 205 m. The
// camera's tracks moved 22 px over that window (a parked car's: 0.1 px); with the check on
// them the start waits for the alignment (measured 2026-12-05: mean error 4.70 m, 10.2 m at the
// end). The case needs the alignment to fail past the still window, which it does on the tiled
// road; on the varied road (the default since 2026-12-06) the alignment succeeds first and the
// IMU-only start is in-motion too (measured 2026-12-06), so this flight stays on the tiled road.
TEST(SimAccuracy, DroneCruisingAtConstantVelocityIsNotTakenAsParked) {
  const std::string dir =
      Simulate("cruise", "drone", 40.0, 5.0, 10.0, 7, "none", 0.3, /*varied_asphalt=*/false);
  VioRunOptions options;
  const Accuracy a = Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  VioRunOptions imu_only = options;
  imu_only.vio.still_max_image_motion_px = 0;
  const Accuracy b = Evaluate(dir, RunVioOnEuroc(dir, imu_only), /*se3=*/false);
  std::printf(
      "simulated drone, urban, 10 m, 5 m/s, 226x144, %.1f m: %s start, mean error (first poses "
      "aligned) %.2f m (< 10), end %.2f m; with the IMU alone deciding stillness: %s start, "
      "%.2f m\n",
      a.path_m, a.init.c_str(), a.ape_mean_m, a.end_m, b.init.c_str(), b.ape_mean_m);
  EXPECT_EQ(b.init, "static") << "the case this test is about: an IMU-still cruise";
  EXPECT_EQ(a.init, "in-motion-aligned");
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 10.0);
}

TEST(SimAccuracy, CarStereoOnly) {
  // The urban car route of the AirSim weather dataset (SEEDS.md part 1), first 21 s: 136 m
  // straight, then the start of the first right turn (the straight alone hides the rotation drift
  // that dominated the full route).
  // On the tiled road, where every figure below was measured. Over the varied road (the default
  // since 2026-12-06) this seed measured 0.529 m (tiled 0.450 m, threaded); over seeds 1-4 the
  // varied road is no harder (mean 0.457 m, tiled 0.496 m; 0.58/0.33/0.53/0.39 against
  // 0.49/0.41/0.45/0.64), so the one seed moved within the spread between seeds
  // (docs/VIO.md, 2026-12-06).
  const std::string dir =
      Simulate("car", "car", 21.0, 5.0, 20.0, 3, "none", 0.5, /*varied_asphalt=*/false);
  // The guard is on the odometry without the temporal gain-and-offset refinement
  // (frontend.stereo_only_klt_gain_offset, the stereo-only default since 2026-12-07), as every
  // figure below was measured; the refinement, built for haze, costs clear weather a little: on
  // this segment over seeds 1-4 a mean 0.493 -> 0.545 m (seed 3: 0.446 -> 0.485 m), so its own
  // bound is relative (docs/VIO.md, "2026-12-07 (late)").
  // Both runs without the corner noise floor (frontend.stereo_only_corner_noise_floor, the
  // stereo-only default since 2026-12-07 (last)). These images have no sensor noise, so the
  // floor's noise estimate is the texture's, and it removes real corners: plain KLT 0.446 ->
  // 0.756 m, the default 0.485 -> 0.592 m. With the cameras' noise see
  // CarStereoOnlyWithCameraNoise.
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  options.vio.frontend.stereo_only_klt_gain_offset = false;
  options.vio.frontend.stereo_only_corner_noise_floor = 0;
  const VioRunResult r = RunVioOnEuroc(dir, options);
  const Accuracy a = Evaluate(dir, r, /*se3=*/false);
  VioRunOptions defaults;
  defaults.vio.mode = VioMode::kStereo;
  defaults.vio.frontend.stereo_only_corner_noise_floor = 0;
  const Accuracy d = Evaluate(dir, RunVioOnEuroc(dir, defaults), /*se3=*/false);
  // The weather dataset's ORB-SLAM3 stereo figure, 1.71 m mean error over 745 m, scaled to the
  // route.
  const double limit = 1.71 * a.path_m / 745.0;
  std::printf(
      "simulated car, urban, clear, stereo-only, 400x300: %zu poses, %zu lost; path "
      "%.1f m, mean APE (first poses aligned) %.3f m (ORB-SLAM3 figure scaled: %.3f m = "
      "1.71 m x %.1f / 745; guard 1.5x), RMSE %.3f m; with the temporal gain-and-offset "
      "refinement (the default) %.3f m (< 1.2x)\n",
      a.poses, a.lost, a.path_m, a.ape_mean_m, limit, a.path_m, a.ape_rmse_m, d.ape_mean_m);
  EXPECT_EQ(a.lost, 0u);
  EXPECT_EQ(d.lost, 0u);
  EXPECT_LT(d.ape_mean_m, 1.2 * a.ape_mean_m) << "the refinement's cost in clear weather";
  // A regression guard, not the acceptance (see docs/VIO.md for the full 762 m route).
  // On this segment the mean error was 1.01 m before the stereo-only keyframe thresholds and
  // outlier threshold (every frame a keyframe, 4 px outliers), 0.35 m after. With the window's
  // tracked landmarks split into its prior (backend.stereo_only_marginalize_tracked_landmarks,
  // 2026-12-04) 0.58 m: past this guard, which is why the split is off by default. With one
  // anchored observation per tracked landmark (the default since 2026-12-04 night): 0.454 m with
  // the left camera's (the default), 0.726 m with both cameras' (past the guard).
  EXPECT_LT(a.ape_mean_m, 1.5 * limit) << "regression guard (1.5 x the scaled ORB-SLAM3 figure)";
}

// Stereo-only runs on `dir`: with the defaults, and with `change` applied to the frontend's
// options (evaluated with the first poses aligned).
std::pair<Accuracy, Accuracy> StereoOnlyDefaultAnd(
    const std::string& dir, const std::function<void(FrontendOptions*)>& change) {
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  const Accuracy a = Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  change(&options.vio.frontend);
  return {a, Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false)};
}

// CarStereoOnly's segment as a camera records it (the cameras' noise, `sim --camera-noise`, the
// default since 2026-12-07), with every default, against the same scaled ORB-SLAM3 guard.
// Measured 2026-12-07: 0.422 m; without the corner noise floor 0.630 m (one seed: the ratio's
// bound is a guard).
TEST(SimAccuracy, CarStereoOnlyWithCameraNoise) {
  const std::string dir =
      Simulate("car_noisy", "car", 21.0, 5.0, 20.0, 3, "none", 0.5, /*varied_asphalt=*/false,
               sim::WorldKind::kUrban, /*camera_noise=*/true);
  const auto [d, u] =
      StereoOnlyDefaultAnd(dir, [](FrontendOptions* f) { f->stereo_only_corner_noise_floor = 0; });
  const double limit = 1.71 * d.path_m / 745.0;
  std::printf(
      "simulated car, urban, clear with camera noise, stereo-only, 400x300, %.1f m: mean error "
      "(first poses aligned) %.3f m with the defaults (guard 1.5 x %.3f m); without the corner "
      "noise floor %.3f m (> 1/0.85 x)\n",
      d.path_m, d.ape_mean_m, limit, u.ape_mean_m);
  EXPECT_EQ(d.lost, 0u);
  EXPECT_LT(d.ape_mean_m, 1.5 * limit) << "regression guard (1.5 x the scaled ORB-SLAM3 figure)";
  EXPECT_LT(d.ape_mean_m, 0.85 * u.ape_mean_m);
}

// The terrain car route in 100 % fog, stereo only, first 15 s (92 m): the haze's veil, fixed in
// the image while the ground flows through it, pulls plain KLT towards no motion and pitches the
// odometry (docs/VIO.md, 2026-12-05 last: -16 deg in 12 s before CLAHE's switches were fixed).
// The temporal refinement with a gain and an offset (frontend.stereo_only_klt_gain_offset, the
// stereo-only default since 2026-12-07) absorbs the veil's gradient. Measured 2026-12-07 (mean
// error, first poses aligned / at the end): 2.13 / 10.15 m without, 0.96 / 3.53 m with it (0.69 /
// 2.06 m when the refinement's conditioning check ignored the gain and offset).
TEST(SimAccuracy, CarStereoOnlyInFogOnTerrainFitsGainAndOffset) {
  const std::string dir = Simulate("terrain_fog", "car", 15.0, 5.0, 20.0, 1, "fog:100", 0.5,
                                   /*varied_asphalt=*/true, sim::WorldKind::kTerrain);
  const auto [a, b] =
      StereoOnlyDefaultAnd(dir, [](FrontendOptions* f) { f->stereo_only_klt_gain_offset = false; });
  std::printf(
      "simulated car, terrain, fog 100 %%, stereo-only, 400x300, %.1f m: mean error (first poses "
      "aligned) %.2f m (< 1.2), end %.2f m (< 0.5x plain) with the temporal gain-and-offset "
      "refinement; plain KLT %.2f m, end %.2f m (> 5)\n",
      a.path_m, a.ape_mean_m, a.end_m, b.ape_mean_m, b.end_m);
  EXPECT_GT(b.end_m, 5.0) << "the case this test is about: plain KLT pitches in fog";
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 1.2);
  EXPECT_LT(a.end_m, 0.5 * b.end_m);
}

// The urban car route in 100 % fog as a camera records it (with the sensor's noise, `sim
// --camera-noise`, the default since 2026-12-07), stereo only, first 25 s. Far texture fades
// below the noise, and a grid cell's best Shi-Tomasi "corner" is then noise, which KLT follows
// nowhere; the quality level, relative to that best, keeps it. The noise floor
// (frontend.stereo_only_corner_noise_floor, estimated per frame) leaves out most of them. Measured
// 2026-12-07 (mean error, first poses aligned / at the end): 0.93 / 2.61 m with it, 1.28 / 3.42 m
// without; one seed, so the bound on the ratio is a guard. On the whole route (bench/RESULTS.md,
// "Camera noise") fog 100 % went 21.74 -> 1.85 m with it.
TEST(SimAccuracy, CarStereoOnlyInNoisyFogDetectsAboveTheNoise) {
  const std::string dir = Simulate("noisy_fog", "car", 25.0, 5.0, 20.0, 1, "fog:100", 0.5,
                                   /*varied_asphalt=*/true, sim::WorldKind::kUrban,
                                   /*camera_noise=*/true);
  const auto [a, b] =
      StereoOnlyDefaultAnd(dir, [](FrontendOptions* f) { f->stereo_only_corner_noise_floor = 0; });
  std::printf(
      "simulated car, urban, fog 100 %% with camera noise, stereo-only, 400x300, %.1f m: mean "
      "error (first poses aligned) %.2f m (< 1.2, < 0.85x without), end %.2f m with the noise "
      "floor; without it %.2f m, end %.2f m\n",
      a.path_m, a.ape_mean_m, a.end_m, b.ape_mean_m, b.end_m);
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 1.2);
  EXPECT_LT(a.ape_mean_m, 0.85 * b.ape_mean_m);
}

TEST(SimAccuracy, CarStereoOnlyInDust) {
  // 100 % dust on the urban car route (the weather document's worst urban condition): the
  // texture left is a grey level or two deep and, without contrast normalisation, KLT loses most
  // tracks every frame (every frame a keyframe) and the odometry pitches away. First 10 s.
  const std::string dir = Simulate("dust", "car", 10.0, 5.0, 20.0, 3, "dust:100");
  VioRunOptions options;
  options.vio.mode = VioMode::kStereo;
  const Accuracy a = Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  VioRunOptions old = options;
  old.vio.frontend.clahe_clip_limit = 0;  // the frontend before 2026-11-25
  old.vio.frontend.detect_min_eigen = 0;
  // ... and the backend of then: anchored observations (2026-12-04 night) hold the old frontend's
  // odometry too on this short segment (0.142 m), so they are off for the system it replaced.
  old.vio.stereo_only_anchored_observations_per_landmark = 0;
  old.vio.frontend.stereo_only_klt_gain_offset = false;  // and plain KLT (2026-12-07)
  const Accuracy b = Evaluate(dir, RunVioOnEuroc(dir, old), /*se3=*/false);
  std::printf(
      "simulated car, urban, dust 100 %%, stereo-only, 400x300, %.1f m: mean APE (first poses "
      "aligned) %.3f m with low-contrast CLAHE, the trackability check of new corners and "
      "anchored observations (< 1 m), %.3f m without any (> 1 m)\n",
      a.path_m, a.ape_mean_m, b.ape_mean_m);
  EXPECT_EQ(a.lost, 0u);
  // Measured 2026-11-25: 0.348 m with CLAHE, 2.422 m without (52 m of path); 2026-11-29 with the
  // check too: 0.137 m (the check alone, without CLAHE: 0.427 m); 2026-12-04 night with the
  // anchored observations too: 0.273 m; 2026-12-07 with the temporal gain-and-offset refinement
  // too: 0.252 m. The full 762 m route in dust
  // stays far from the clear figure (docs/VIO.md, weather): a guard, not the acceptance.
  EXPECT_LT(a.ape_mean_m, 1.0);
  EXPECT_GT(b.ape_mean_m, 1.0) << "the old system is expected to fail here";
}

TEST(SimAccuracy, CarStereoInertialInFogKeepsTheStaticGyroBias) {
  // 100 % fog on the urban car route (visibility 40 m: near points only), stereo-inertial, first
  // 25 s (163 m). The car starts still, so the static start measures the gyro bias; with the
  // backend's loose 0.01 rad/s prior the window let the near-point vision pull it (the yaw
  // drifting 0.08 deg/s; 9.9 m mean error over the whole route, 2.5 m with the measured prior;
  // docs/VIO.md, weather). The prior is one standard error of the still window's mean rate since
  // 2026-12-01: this segment went 0.456 -> 0.263 m mean, 0.695 -> 0.528 m at the end, from three
  // standard errors (measured 2026-11-27), and the loose prior gave 1.232 m, 3.104 m at the end.
  // Re-measured on the renderer with trilinear texture sampling (2026-12-05): 0.415 m, 0.718 m
  // at the end with the measured prior; 0.739 m, 1.293 m with the loose one. The old renderer's
  // mip seams travelled with the camera, and in fog, where the near field is all there is to
  // track, those false corners made much of the pull on the bias (docs/VIO.md, 2026-12-05).
  // On the tiled road: on the varied one (the default since 2026-12-06) this segment measured
  // 0.78 m with the measured prior and 0.62 m with the loose one, so the prior's gain is not
  // general; this test guards the case where it was found (docs/VIO.md, 2026-12-06).
  const std::string dir =
      Simulate("fog", "car", 25.0, 5.0, 20.0, 1, "fog:100", 0.5, /*varied_asphalt=*/false);
  auto run = [&](double standard_errors) {
    VioRunOptions options;
    options.vio.mode = VioMode::kStereoImu;
    options.vio.static_gyro_bias_standard_errors = standard_errors;
    return Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  };
  const Accuracy a = run(VioOptions{}.static_gyro_bias_standard_errors);
  const Accuracy b = run(0);  // the backend's prior (before 2026-11-27)
  std::printf(
      "simulated car, urban, fog 100 %%, stereo-inertial, 400x300, %.1f m (%s start): mean APE "
      "(first poses aligned) %.3f m, end %.3f m with the measured gyro-bias prior (< 0.5 m, < "
      "0.9 m); %.3f m, end %.3f m with the backend's 0.01 rad/s (end > 1.5x)\n",
      a.path_m, a.init.c_str(), a.ape_mean_m, a.end_m, b.ape_mean_m, b.end_m);
  EXPECT_EQ(a.init, "static");
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 0.5);
  EXPECT_LT(a.end_m, 0.9);
  EXPECT_GT(b.ape_mean_m, 1.5 * a.ape_mean_m) << "the loose prior is expected to drift here";
  EXPECT_GT(b.end_m, 1.5 * a.end_m) << "the loose prior is expected to drift here";
}

TEST(SimAccuracy, CarStereoInertialInDustHoldsTheGyroBias) {
  // 100 % dust on the urban car route, stereo-inertial, first 40 s (275 m), the defaults: the
  // texture left is a grey level or two deep; on such frames the gyro bias random walk is held at
  // 0.3 of the IMU's (backend.lowcontrast_gyro_walk_scale), since the vision of faint texture
  // pulls the vertical gyro bias and the yaw with it. That pull takes the whole route to show
  // (seed 1, 762 m: 2.41 -> 1.51 m mean error, docs/VIO.md, weather, 2026-12-02); on this
  // segment the hold is not better (measured 0.942 m mean, 1.162 m at the end; 0.818 m and
  // 1.218 m as modelled), so this is a guard on stereo-inertial dust, not the acceptance.
  const std::string dir = Simulate("dust_imu", "car", 40.0, 5.0, 20.0, 1, "dust:100");
  VioRunOptions options;
  options.vio.mode = VioMode::kStereoImu;
  const Accuracy a = Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  std::printf(
      "simulated car, urban, dust 100 %%, stereo-inertial, 400x300, %.1f m (%s start): mean APE "
      "(first poses aligned) %.3f m (< 1.2 m), end %.3f m (< 1.6 m)\n",
      a.path_m, a.init.c_str(), a.ape_mean_m, a.end_m);
  EXPECT_EQ(a.init, "static");
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 1.2);
  EXPECT_LT(a.end_m, 1.6);
}

TEST(SimAccuracy, CarStereoInertialInFallingLeavesGatesTheParticles) {
  // Falling leaves (50 %) on the urban car route, stereo-inertial, first 25 s (163 m). The
  // leaves drift through the scene with the wind and KLT tracks them like the scene: with the
  // post-solve outlier check alone they bent the yaw (3.8 deg at 25 s; 15.0 m mean error over
  // the whole route), the gate on the IMU-predicted pose keeps them out of the solve
  // (docs/VIO.md, weather). On the tiled road: on the varied one (the default since 2026-12-06)
  // the gate gains less here (1.49 m without it, under the 1.5x this test asks for).
  const std::string dir =
      Simulate("leaves", "car", 25.0, 5.0, 20.0, 1, "leaves:50", 0.5, /*varied_asphalt=*/false);
  auto run = [&](double gate_px) {
    VioRunOptions options;
    options.vio.mode = VioMode::kStereoImu;
    options.vio.backend.predicted_gate_pixels = gate_px;
    return Evaluate(dir, RunVioOnEuroc(dir, options), /*se3=*/false);
  };
  const Accuracy a = run(2.0);
  const Accuracy b = run(0);  // no gate
  std::printf(
      "simulated car, urban, leaves 50 %%, stereo-inertial, 400x300, %.1f m: mean APE (first "
      "poses aligned) %.3f m, end %.3f m with the 2 px predicted gate (< 1.6 m, < 3.0 m); "
      "%.3f m, end %.3f m without\n",
      a.path_m, a.ape_mean_m, a.end_m, b.ape_mean_m, b.end_m);
  EXPECT_EQ(a.lost, 0u);
  EXPECT_LT(a.ape_mean_m, 1.6);
  EXPECT_LT(a.end_m, 3.0);
  EXPECT_GT(b.ape_mean_m, 1.5 * a.ape_mean_m) << "without the gate the leaves are expected to pull";
}

}  // namespace
}  // namespace optinav::vio
