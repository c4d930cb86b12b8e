// The VIO run driver on a short simulated drone flight (optinav sim: urban world, small images,
// fixed seed), sequential and therefore deterministic: pose counts, accuracy against the
// simulator's ground truth, the files written and the statistics JSON, with and without GNSS.
#include "optinav/app/vio_run.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "optinav/eval/metrics.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/html_report.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

namespace fs = std::filesystem;

// One simulated sequence for the whole suite (rendering is the slow part).
class VioRunTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new fs::path(testing::MakeTempDir("app_vio_run"));
    sim::SimulationOptions o;
    o.route = "drone";
    o.duration_s = kDurationS;
    o.speed_m_s = 4.0;
    o.altitude_m = 6.0;
    o.scale = kScale;
    // Seed 9 on the varied road (the default since 2026-12-06). Until 2026-12-07 this suite flew
    // seed 5 on the tiled road: its in-motion start was the fragile part (one 1 s alignment
    // decided it). The start now waits for two alignments to agree (docs/VIO.md, 2026-12-07
    // later); over 60 such flights that halves the worst APE but moves single seeds both ways,
    // seed 5 tiled from 0.14 to 0.30 m here. Seed 9 is one whose start confirms at the first pair
    // of windows (0.4-1.9 s); this suite tests the driver, docs/VIO.md the start's spread.
    o.seed = 9;
    // Rendered without the cameras' noise (as before 2026-12-07): with it the start aligns later
    // (173 poses instead of 193); this suite tests the driver's files, not the start.
    o.camera_noise.enabled = false;
    o.gnss.sigma_m = kGnssSigmaM;  // precise enough to align ENU within the flight
    o.out_dir = (*root_ / "seq").string();
    sim::RunSimulation(o);
  }
  static void TearDownTestSuite() {
    fs::remove_all(*root_);
    delete root_;
  }
  static std::string Dataset() { return (*root_ / "seq").string(); }
  static std::string Out(const std::string& name) { return (*root_ / name).string(); }

  // APE RMSE (SE(3) alignment) of a TUM trajectory against the simulator's ground truth.
  static double ApeRmse(const std::string& tum) {
    const Trajectory gt =
        io::ReadTrajectory(Dataset() + "/mav0/state_groundtruth_estimate0/data.csv");
    eval::SyncedPair p = eval::Synchronize(gt, io::ReadTrajectory(tum));
    eval::AlignTrajectory(p.ref, &p.est, {.mode = eval::AlignMode::kSe3});
    return eval::ComputeApe(p.ref, p.est, eval::PoseRelation::kTranslation).stats.rmse;
  }

  static constexpr double kDurationS = 10.0;
  static constexpr double kGnssSigmaM = 0.3;
  static constexpr double kScale = 0.3;  // image size factor: small images, a short test
  // About 40 m flown; the run gives 0.113 m (VIO alone) and 0.101 m (fused, ENU).
  static constexpr double kApeBoundM = 0.2;
  static fs::path* root_;
};
fs::path* VioRunTest::root_ = nullptr;

size_t PoseLines(const std::string& path) {
  const std::string text = testing::ReadFile(path);
  size_t n = 0;
  for (size_t i = 0; i < text.size(); i = text.find('\n', i) + 1) {
    if (text[i] != '#') ++n;
    if (text.find('\n', i) == std::string::npos) break;
  }
  return n;
}

TEST_F(VioRunTest, StereoInertialWritesTrajectoriesAndStats) {
  VioRunSettings st;
  st.dataset = Dataset();
  st.sequential = true;
  st.out = Out("vio.tum");
  st.camera_out = Out("vio_cam.tum");
  st.stats_path = Out("vio.json");
  const VioRunReport r = RunVioDataset(st);
  EXPECT_EQ(r.mode, "stereo-imu");
  EXPECT_EQ(r.frame, "world");
  EXPECT_EQ(r.run.frames_total, 201u);
  // 193 of 201 frames: the poses from the first aligned window's start, 0.4 s in.
  EXPECT_EQ(r.run.estimates.size(), 193u);
  EXPECT_TRUE(r.run.lost.empty());
  EXPECT_EQ(PoseLines(st.out), r.run.estimates.size());
  EXPECT_EQ(PoseLines(st.camera_out), r.run.estimates.size());
  const double ape = ApeRmse(st.out);
  std::printf("APE RMSE (SE3) %.3f m (< %.1f)\n", ape, kApeBoundM);
  EXPECT_LT(ape, kApeBoundM);

  const nlohmann::json j = nlohmann::json::parse(testing::ReadFile(st.stats_path));
  for (const char* key : {"mode", "frame", "frames", "frames_processed", "frames_unpaired", "poses",
                          "initializations", "first_initialization", "timing_per_frame",
                          "lost_intervals", "loop_closure", "loops"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_FALSE(j.contains("gnss"));
  EXPECT_EQ(j["poses"], r.run.estimates.size());
  ASSERT_TRUE(r.run.loop_closure_ran);  // stereo-imu: by default
  EXPECT_EQ(j["loop_keyframes"], r.run.loop_keyframes);
  EXPECT_GT(r.run.loop_keyframes, 0u);
  // At this image size every keyframe has fewer than loop_closure.orb_retry_below_features ORB
  // features, and with the IMU the retry is on by default (orb_retry_stereo_imu, since 2026-12-06
  // evening): every keyframe is described again (68 of 68 measured 2026-12-06).
  EXPECT_EQ(j["loop_faded_keyframes"], r.run.loop_keyframes);
  EXPECT_EQ(r.run.loop_faded_keyframes, r.run.loop_keyframes);
  EXPECT_EQ(j["loops_unsupported"], r.run.loops_unsupported);
  EXPECT_EQ(j["loops_aliased"], r.run.loops_aliased);
  EXPECT_EQ(j["frame"], "world");
  EXPECT_EQ(j["vehicle"], "free");  // auto on a drone route
  EXPECT_TRUE(j["timing_per_frame"].contains("total"));
  const std::string summary = FormatVioSummary(st, r);
  EXPECT_EQ(summary.rfind(fmt::format("vio stereo-imu: {} poses from {} stereo frames, 0 lost",
                                      r.run.estimates.size(), r.run.frames_total),
                          0),
            0u)
      << summary;
}

TEST_F(VioRunTest, GnssFusionWritesEnuAndSideOutputs) {
  VioRunSettings st;
  st.dataset = Dataset();
  st.sequential = true;
  st.out = Out("fused.tum");
  st.stats_path = Out("fused.json");
  st.gnss = true;
  // --gnss-init-yaw-sigma 2: the short flight aligns ENU within its first metres.
  st.gnss_fusion.init_max_yaw_sigma_rad = 2 * M_PI / 180;
  const VioRunReport r = RunVioDataset(st);
  std::printf("%s", FormatVioSummary(st, r).c_str());
  EXPECT_EQ(r.frame, "enu");
  EXPECT_EQ(r.gnss_rejected_out, Out("fused.gnss_rejected.csv"));
  EXPECT_EQ(r.wgs84_out, Out("fused.wgs84.csv"));
  EXPECT_EQ(r.gnss_live_out, Out("fused.live.tum"));  // smoothed output: the live one beside it
  for (const std::string& f :
       {r.gnss_rejected_out, r.wgs84_out, r.gnss_live_out, Out("fused.geojson")})
    EXPECT_TRUE(fs::exists(f)) << f;
  EXPECT_EQ(PoseLines(st.out), r.run.estimates.size());
  EXPECT_EQ(PoseLines(r.wgs84_out), r.run.estimates.size());
  EXPECT_EQ(r.run.gnss_stats.received, 51u);
  const double ape = ApeRmse(st.out);
  std::printf("APE RMSE (SE3) %.3f m (< %.1f)\n", ape, kApeBoundM);
  EXPECT_LT(ape, kApeBoundM);
  const nlohmann::json j = nlohmann::json::parse(testing::ReadFile(st.stats_path));
  EXPECT_EQ(j["frame"], "enu");
  for (const char* key :
       {"received", "factors", "rejected", "alignments", "smoothed_tracks", "aligned_at_s"})
    EXPECT_TRUE(j["gnss"].contains(key)) << key;
  EXPECT_NE(FormatVioSummary(st, r).find("trajectory in ENU (smoothed over the run"),
            std::string::npos);
  // The HTML report's document beside the trajectory: truth, output and live estimate in ENU,
  // every GNSS sample with the rejected ones marked.
  EXPECT_EQ(r.report_document, Out("fused.report.json"));
  const report::ReportDocument doc = report::ReadReportDocument(r.report_document);
  EXPECT_EQ(doc.kind, "vio gnss");
  ASSERT_EQ(doc.views.size(), 1u);
  const report::ReportView& v = doc.views[0];
  ASSERT_EQ(v.paths.size(), 3u);
  EXPECT_EQ(v.paths[0].layer, "ground truth");
  EXPECT_EQ(v.paths[1].layer, "output (smoothed)");
  EXPECT_EQ(v.fixes.size(), 51u);
  size_t rejected = 0;
  for (const report::ReportFix& f : v.fixes) {
    rejected += !f.accepted;
    EXPECT_TRUE(std::isfinite(f.error_m));
  }
  EXPECT_EQ(rejected, r.run.gnss_stats.rejected);
  EXPECT_FALSE(r.html);  // only with --html
}

// --vehicle auto follows the simulator's route; an unreadable marker names the file.
TEST(VioRunSettings, VehicleAutoFollowsTheSimulatorRoute) {
  const fs::path dir = testing::MakeTempDir("app_vio_vehicle");
  EXPECT_EQ(ResolveVehicleModel(VehicleModel::kAuto, dir.string()), VehicleModel::kFree);
  const auto marker = [&](const std::string& text) {
    testing::WriteFile((dir / "sim_complete.json").string(), text);
  };
  marker(R"({"generator": "optinav sim", "route": "car"})");
  EXPECT_EQ(ResolveVehicleModel(VehicleModel::kAuto, dir.string()), VehicleModel::kGround);
  EXPECT_EQ(ResolveVehicleModel(VehicleModel::kFree, dir.string()), VehicleModel::kFree);
  marker(R"({"generator": "optinav sim", "route": "drone"})");
  EXPECT_EQ(ResolveVehicleModel(VehicleModel::kAuto, dir.string()), VehicleModel::kFree);
  EXPECT_EQ(ResolveVehicleModel(VehicleModel::kGround, dir.string()), VehicleModel::kGround);
  marker("{\"route\": ");
  try {
    ResolveVehicleModel(VehicleModel::kAuto, dir.string());
    ADD_FAILURE() << "a truncated marker was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("sim_complete.json"), std::string::npos) << e.what();
  }
  for (const char* name : {"auto", "ground", "free"})
    EXPECT_STREQ(VehicleModelName(*ParseVehicleModel(name)), name);
  EXPECT_FALSE(ParseVehicleModel("car"));
  fs::remove_all(dir);
}

// --vehicle ground puts the vertical-velocity constraint into the window: the run says so and
// its estimate differs from the free run's on the same frames.
TEST_F(VioRunTest, GroundVehicleConstrainsTheRun) {
  VioRunSettings st;
  st.dataset = Dataset();
  st.sequential = true;
  st.max_frames = 90;
  st.out = Out("vio_free.tum");
  st.vehicle = VehicleModel::kFree;
  const VioRunReport free = RunVioDataset(st);
  st.out = Out("vio_ground.tum");
  st.vehicle = VehicleModel::kGround;
  const VioRunReport ground = RunVioDataset(st);
  EXPECT_EQ(free.vehicle, "free");
  EXPECT_EQ(ground.vehicle, "ground");
  // The ground vehicle's default gate on the IMU-predicted pose; none without a vehicle model.
  EXPECT_EQ(free.predicted_gate_px, 0.0);
  EXPECT_EQ(ground.predicted_gate_px, kGroundVehicleGatePixels);
  EXPECT_EQ(ground.predicted_gate_median_factor, kGroundVehicleGateMedianFactor);
  EXPECT_EQ(VioStatsJson(ground)["predicted_gate"]["pixels"], kGroundVehicleGatePixels);
  ASSERT_FALSE(free.run.estimates.empty());
  ASSERT_EQ(free.run.estimates.size(), ground.run.estimates.size());
  const Eigen::Vector3d a = free.run.estimates.back().state.world_from_body.translation;
  const Eigen::Vector3d b = ground.run.estimates.back().state.world_from_body.translation;
  EXPECT_GT((a - b).norm(), 1e-6);
  // The effective options as a config reproduce the run without the vehicle model's defaults.
  EXPECT_EQ(EffectiveVioOptionsYaml(st), ground.vio_options_yaml);
  EXPECT_EQ(VioStatsJson(ground)["vio_options_yaml"], ground.vio_options_yaml);
  EXPECT_NE(free.vio_options_yaml, ground.vio_options_yaml);
  st.config_path = Out("effective.yaml");
  io::WriteFileAtomically(st.config_path, ground.vio_options_yaml);
  st.vehicle = VehicleModel::kFree;
  st.out = Out("vio_reproduced.tum");
  const VioRunReport again = RunVioDataset(st);
  EXPECT_EQ(again.vio_options_yaml, ground.vio_options_yaml);
  ASSERT_EQ(again.run.estimates.size(), ground.run.estimates.size());
  EXPECT_EQ(again.run.estimates.back().state.world_from_body.translation, b);
}

TEST(VioRunSettings, CheckNamesTheFlag) {
  VioRunSettings st;
  EXPECT_EQ(st.Check(), "--dataset must be given");
  st.dataset = "d";
  EXPECT_EQ(st.Check(), "--out must be given");
  st.out = "t.tum";
  EXPECT_EQ(st.Check(), "");
  st.gnss = true;
  st.loop_closure = true;
  EXPECT_EQ(st.Check(), "--loop-closure cannot be on with GNSS fusion");
  st.loop_closure.reset();
  st.mode = vio::VioMode::kStereo;
  EXPECT_EQ(st.Check(), "--gnss fusion needs a EuRoC dataset in stereo-imu mode");
  st.mode.reset();
  st.loop_closure = false;
  st.gnss_input.sigma_m = 0;
  EXPECT_EQ(st.Check(), "--gnss-sigma must be > 0, got 0");
  st.gnss_input.sigma_m.reset();
  st.gnss_fusion.factor_sigma_scale = 0;
  EXPECT_EQ(st.Check().rfind("--gnss fusion options: ", 0), 0u) << st.Check();
  try {
    RunVioDataset(st);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.message().rfind("--gnss fusion options: ", 0), 0u) << e.what();
  }
}

TEST_F(VioRunTest, ErrorsNameTheFieldOrFile) {
  VioRunSettings st;
  st.dataset = Dataset();
  st.out = Out("x.tum");
  st.gnss = true;
  // Stereo mode from a config file: found when the run loads it.
  st.config_path = testing::WriteFile(*root_ / "stereo.yaml", "mode: stereo\n");
  try {
    RunVioDataset(st);
    FAIL() << "GNSS in stereo mode ran";
  } catch (const Error& e) {
    EXPECT_EQ(e.context().field, "--gnss");
  }
  st.config_path.clear();
  st.gnss_input.file = Out("missing_gnss.csv");
  try {
    RunVioDataset(st);
    FAIL() << "a missing GNSS file was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.context().file, st.gnss_input.file) << e.what();
  }
  EXPECT_FALSE(fs::exists(st.out));  // nothing written by a refused run
}

}  // namespace
}  // namespace optinav::app
