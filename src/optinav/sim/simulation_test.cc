#include "optinav/sim/simulation.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/io/airsim_recording.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/sim/internal/png_writer.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::sim {
namespace {

SimulationOptions Small(const std::string& out, DatasetFormat format) {
  SimulationOptions o;
  o.out_dir = out;
  o.format = format;
  o.scale = 0.15;
  o.duration_s = 1.5;
  o.seed = 11;
  o.gnss.rate_hz = 10;
  o.gnss.sigma_m = 0.5;
  o.gnss.outlier_fraction = 0.2;
  o.gnss.outlier_magnitude_m = 15;
  return o;
}

TEST(Simulation, EurocOutputRoundTripsThroughTheReader) {
  const fs::path dir = testing::MakeTempDir("sim_euroc");
  SimulationOptions o = Small((dir / "seq").string(), DatasetFormat::kEuroc);
  o.route = "drone";
  o.weather = ParseWeather("fog:50");
  const SimulationSummary s = RunSimulation(o);
  std::printf("euroc: %zu frames, %zu imu, %zu gnss in %.2f s\n", s.frames, s.imu_samples,
              s.gnss_samples, s.wall_s);
  ASSERT_TRUE(fs::is_regular_file(dir / "seq" / "sim_complete.json"));
  const io::EurocDataset ds = io::OpenEurocDataset((dir / "seq").string());
  ASSERT_TRUE(ds.cam0 && ds.cam1 && ds.imu_calibration);
  EXPECT_EQ(ds.cam0->images.size(), s.frames);
  EXPECT_EQ(ds.cam1->images.size(), s.frames);
  const SensorRig rig = DroneRig().Scaled(0.15);
  EXPECT_EQ(ds.cam0->calibration.width, rig.left.width);
  EXPECT_NEAR(ds.cam0->calibration.fx, rig.left.fx, 1e-6);
  EXPECT_NEAR(LogSE3(ds.cam1->calibration.body_from_cam.Inverse() * rig.body_from_right).norm(), 0,
              1e-9);
  EXPECT_NEAR(ds.imu_calibration->gyroscope_noise_density, o.imu.gyroscope_noise_density, 1e-12);

  // IMU, GNSS and ground truth agree with a fresh simulation of the same trajectory.
  const auto imu = io::ReadImuCsv(ds.imu_csv);
  const auto gnss = io::ReadGnssFile(ds.gnss_csv).records;
  ASSERT_EQ(imu.size(), s.imu_samples);
  ASSERT_EQ(gnss.size(), s.gnss_samples);
  const Trajectory gt = io::ReadTrajectory(ds.groundtruth_csv);
  ASSERT_EQ(gt.size(), imu.size());
  // Specific force at rest-ish hover start is about g up; the ground truth starts at rest.
  EXPECT_NEAR(imu.front().accel_m_s2.norm(), kGravity, 0.2);
  EXPECT_EQ(gt.t_ns.front(), imu.front().t_ns);
  // GNSS positions lie near the ground truth (0.5 m sigma, 15 m outliers).
  int near = 0;
  for (const auto& g : gnss) {
    size_t k = 0;
    while (k + 1 < gt.size() && gt.t_ns[k] < g.t_ns) ++k;
    near += (g.value - gt.positions[k]).norm() < 3.0;
  }
  EXPECT_GT(near, static_cast<int>(gnss.size()) / 2);
}

// The nadir camera and the barometer of a drone flight (issue 20's data): cam2 is mounted as the
// attitude convention says (looking down, image top towards the nose), its frames see the ground
// below the vehicle, and the barometer reads the altitude with its bias and noise.
TEST(Simulation, NadirCameraAndBarometerOfADroneFlight) {
  const fs::path dir = testing::MakeTempDir("sim_nadir");
  SimulationOptions o = Small((dir / "seq").string(), DatasetFormat::kEuroc);
  o.route = "drone";
  // Flat ground (z = 0) textured with a real orthophoto: the ground under a ray is exact.
  o.world =
      ParseWorld("ortho:" + (testing::SharedDataDir() / "geo/naip/naip_20170827.tif").string());
  o.altitude_m = 60;
  o.duration_s = 3;
  o.nadir.enabled = true;
  o.nadir.width = 160;
  o.nadir.height = 120;
  o.nadir.rate_hz = 4;
  o.baro.enabled = true;
  const SimulationSummary s = RunSimulation(o);
  const io::EurocDataset ds = io::OpenEurocDataset((dir / "seq").string());
  ASSERT_TRUE(ds.cam2 && ds.baro_calibration);
  EXPECT_EQ(s.nadir_frames, 13u);  // 0, 0.25, ..., 3 s
  ASSERT_EQ(ds.cam2->images.size(), s.nadir_frames);
  EXPECT_EQ(ds.cam2->calibration.width, 160);
  EXPECT_NEAR(ds.cam2->calibration.rate_hz, 4, 1e-9);
  // body_from_cam: the optical axis is body -z, the image's up (-y) is body x (the nose), its
  // right (+x) is body -y (the right wing).
  const Eigen::Matrix3d r = ds.cam2->calibration.body_from_cam.rotation.toRotationMatrix();
  EXPECT_LT((r.col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-9);
  EXPECT_LT((-r.col(1) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-9);
  EXPECT_LT((r.col(0) - Eigen::Vector3d(0, -1, 0)).norm(), 1e-9);
  const cv::Mat img = cv::imread(ds.cam2->images[5].path, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 160);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img, mean, stddev);
  EXPECT_GT(stddev[0], 3.0) << "the nadir frame shows no texture: not looking at the ground?";
  // The ground moves through the image as the mount predicts: the ground point under the image
  // centre of frame 4 lands, in frame 6, where the ground-truth poses and the mount project it;
  // the image shift measured by phase correlation agrees in direction and length.
  {
    const Trajectory gt = io::ReadTrajectory(ds.groundtruth_csv);
    auto pose_at = [&](int64_t t) {
      size_t k = 0;
      while (k + 1 < gt.size() && gt.t_ns[k] < t) ++k;
      return gt.pose(k) * ds.cam2->calibration.body_from_cam;  // world_from_cam
    };
    const Rigid3d w_c1 = pose_at(ds.cam2->images[4].t_ns);
    const Rigid3d w_c2 = pose_at(ds.cam2->images[6].t_ns);
    const Eigen::Vector3d axis = w_c1.rotation * Eigen::Vector3d::UnitZ();
    ASSERT_LT(axis.z(), -0.7);  // looking down (the drone tilts as it accelerates)
    const Eigen::Vector3d ground = w_c1.translation - w_c1.translation.z() / axis.z() * axis;
    const Eigen::Vector3d in2 = w_c2.Inverse() * ground;
    const double f = ds.cam2->calibration.fx;
    const Eigen::Vector2d predicted(f * in2.x() / in2.z(), f * in2.y() / in2.z());
    cv::Mat a, b;
    cv::imread(ds.cam2->images[4].path, cv::IMREAD_GRAYSCALE).convertTo(a, CV_32F);
    cv::imread(ds.cam2->images[6].path, cv::IMREAD_GRAYSCALE).convertTo(b, CV_32F);
    const cv::Point2d shift = cv::phaseCorrelate(a, b);
    const Eigen::Vector2d measured(shift.x, shift.y);
    std::printf("nadir shift: predicted (%.2f, %.2f) px, measured (%.2f, %.2f) px\n", predicted.x(),
                predicted.y(), measured.x(), measured.y());
    ASSERT_GT(predicted.norm(), 1.0);
    EXPECT_GT(predicted.normalized().dot(measured.normalized()), 0.8);
    EXPECT_NEAR(measured.norm(), predicted.norm(), 0.15 * predicted.norm());
  }

  // Barometer: altitude = ground-truth z + bias + noise; the residual's mean is the bias
  // (initial sigma 2 m) and its spread the 0.3 m noise.
  const auto baro = io::ReadBaroCsv(ds.baro_csv);
  ASSERT_EQ(baro.size(), s.baro_samples);
  EXPECT_EQ(baro.size(), 61u);  // 20 Hz over 3 s
  const Trajectory gt = io::ReadTrajectory(ds.groundtruth_csv);
  std::vector<double> residual;
  for (const io::BaroSample& b : baro) {
    size_t k = 0;
    while (k + 1 < gt.size() && gt.t_ns[k] < b.t_ns) ++k;
    ASSERT_EQ(gt.t_ns[k], b.t_ns);  // 20 Hz samples fall on 200 Hz ground-truth stamps
    residual.push_back(b.altitude_m - gt.positions[k].z());
  }
  double mean_r = 0, var_r = 0;
  for (double v : residual) mean_r += v / residual.size();
  for (double v : residual) var_r += (v - mean_r) * (v - mean_r) / (residual.size() - 1);
  std::printf("baro: bias %.3f m, noise %.3f m (model 0.3 m)\n", mean_r, std::sqrt(var_r));
  EXPECT_LT(std::abs(mean_r), 8.0);
  EXPECT_NEAR(std::sqrt(var_r), 0.3, 0.1);
  EXPECT_GT(gt.positions.front().z(), 40.0);  // flying, not on the ground
  EXPECT_NEAR(ds.baro_calibration->noise_sigma_m, 0.3, 1e-12);
}

TEST(Simulation, AirsimOutputRoundTripsThroughTheReader) {
  const fs::path dir = testing::MakeTempDir("sim_airsim");
  SimulationOptions o = Small((dir / "seq").string(), DatasetFormat::kAirsim);
  o.duration_s = 3;
  o.scale = 0.1;
  const SimulationSummary s = RunSimulation(o);
  const io::AirsimRecording rec = io::ReadAirsimRecording((dir / "seq").string());
  ASSERT_EQ(rec.records.size(), s.frames);
  ASSERT_EQ(rec.left_camera.size(), s.frames);
  const Trajectory gt = io::ReadTrajectory((dir / "seq" / "groundtruth.csv").string());
  const SensorRig rig = CarRig();
  double worst_p = 0, worst_r = 0, worst_cam = 0;
  for (size_t i = 0; i < rec.records.size(); ++i) {
    const io::AirsimRecord& r = rec.records[i];
    ASSERT_TRUE(r.world_from_body.has_value());
    ASSERT_EQ(r.image_paths.size(), 2u);
    EXPECT_NE(r.image_paths[0].find("front_left"), std::string::npos);
    EXPECT_NE(r.image_paths[1].find("front_right"), std::string::npos);
    // Ground truth at 200 Hz holds every 30 ms frame time exactly (both are multiples of 5 ms).
    size_t k = 0;
    while (gt.t_ns[k] < r.t_ns) ++k;
    ASSERT_EQ(gt.t_ns[k], r.t_ns);
    worst_p = std::max(worst_p, (r.world_from_body->translation - gt.positions[k]).norm());
    worst_r = std::max(worst_r,
                       RotationAngle(r.world_from_body->rotation.conjugate() * gt.quaternion(k)));
    const Rigid3d cam = gt.pose(k) * rig.body_from_left;
    worst_cam =
        std::max(worst_cam, LogSE3(cam.Inverse() * rec.left_camera[i].world_from_cam).norm());
  }
  std::printf(
      "airsim: %zu rows; NED->ENU round trip: position %.2e m, rotation %.2e rad, left "
      "camera %.2e\n",
      rec.records.size(), worst_p, worst_r, worst_cam);
  EXPECT_LT(worst_p, 2e-6);
  EXPECT_LT(worst_r, 1e-6);
  EXPECT_LT(worst_cam, 1e-5);
  // The car starts at the AirSim origin facing north: identity in NED.
  EXPECT_NEAR(rec.records.front().world_from_body->translation.norm(), 0, 1e-6);
  EXPECT_DOUBLE_EQ(rec.records.back().throttle, 0.7);
}

std::string Slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Every file of a folder, by relative path.
std::map<std::string, std::string> Files(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (e.is_regular_file()) out[fs::relative(e.path(), root).string()] = Slurp(e.path());
  }
  return out;
}

TEST(Simulation, SameSeedGivesByteIdenticalOutput) {
  const fs::path dir = testing::MakeTempDir("sim_det");
  SimulationOptions o = Small((dir / "a").string(), DatasetFormat::kEuroc);
  o.weather = ParseWeather("snow:60");
  o.duration_s = 0.5;
  RunSimulation(o);
  o.out_dir = (dir / "b").string();
  RunSimulation(o);
  o.out_dir = (dir / "c").string();
  o.seed = 12;
  RunSimulation(o);
  const auto a = Files(dir / "a"), b = Files(dir / "b"), c = Files(dir / "c");
  size_t bytes = 0;
  for (const auto& [k, v] : a) bytes += v.size();
  std::printf("determinism: %zu files, %zu bytes compared\n", a.size(), bytes);
  ASSERT_GT(a.size(), 10u);
  EXPECT_TRUE(a == b);
  EXPECT_FALSE(a == c);
}

// The benchmarks' --reuse: a rendering is of the options only when its marker names the same
// parameters; markers written before the asphalt and the requested duration were recorded still
// match by what they do record.
TEST(Simulation, IsRenderingOfComparesTheRecordedParameters) {
  const fs::path dir = testing::MakeTempDir("sim_rendering_of");
  SimulationOptions o = Small((dir / "seq").string(), DatasetFormat::kEuroc);
  o.duration_s = 0.3;
  o.weather = ParseWeather("fog:50");
  RunSimulation(o);
  std::string why;
  EXPECT_TRUE(IsRenderingOf(o.out_dir, o, &why)) << why;
  auto differs = [&](const std::string& key, const std::function<void(SimulationOptions*)>& edit) {
    SimulationOptions other = o;
    edit(&other);
    why.clear();
    EXPECT_FALSE(IsRenderingOf(o.out_dir, other, &why)) << key;
    EXPECT_EQ(why.rfind(key + ":", 0), 0u) << why;
  };
  differs("weather", [](SimulationOptions* x) { x->weather = ParseWeather("fog:75"); });
  differs("particles_still", [](SimulationOptions* x) { x->weather.particles_still = true; });
  differs("asphalt", [](SimulationOptions* x) { x->world.varied_asphalt = false; });
  differs("camera_noise", [](SimulationOptions* x) { x->camera_noise.enabled = false; });
  differs("camera_noise", [](SimulationOptions* x) { x->camera_noise.read_sigma = 2; });
  differs("seed", [](SimulationOptions* x) { x->seed = 12; });
  differs("format", [](SimulationOptions* x) { x->format = DatasetFormat::kAirsim; });
  differs("scale", [](SimulationOptions* x) { x->scale = 0.3; });
  differs("requested_duration_s", [](SimulationOptions* x) { x->duration_s = 0.4; });
  differs("route", [](SimulationOptions* x) { x->route = "drone"; });
  // The sensors' options are not compared.
  SimulationOptions noisier = o;
  noisier.gnss.sigma_m = 3;
  EXPECT_TRUE(IsRenderingOf(o.out_dir, noisier));

  // A marker of before 2026-12-06: no asphalt (tiled) and no requested duration (the rendered
  // one stands for it).
  const fs::path marker = fs::path(o.out_dir) / "sim_complete.json";
  nlohmann::json j = nlohmann::json::parse(testing::ReadFile(marker));
  EXPECT_EQ(j.at("asphalt"), "varied");
  EXPECT_EQ(j.at("requested_duration_s"), 0.3);
  j.erase("asphalt");
  j.erase("requested_duration_s");
  testing::WriteFile(marker, j.dump(2));
  EXPECT_FALSE(IsRenderingOf(o.out_dir, o, &why));
  EXPECT_EQ(why, "asphalt: \"tiled\" (wanted \"varied\")");
  SimulationOptions tiled = o;
  tiled.world.varied_asphalt = false;
  EXPECT_TRUE(IsRenderingOf(o.out_dir, tiled, &why)) << why;
  tiled.duration_s = 0.4;
  EXPECT_FALSE(IsRenderingOf(o.out_dir, tiled));
  tiled.duration_s = 0;  // the whole route: the marker cannot tell, so it is taken
  EXPECT_TRUE(IsRenderingOf(o.out_dir, tiled));

  // A marker of before the camera noise (2026-12-07): rendered without it.
  nlohmann::json quiet = j;
  quiet.erase("camera_noise");
  testing::WriteFile(marker, quiet.dump(2));
  EXPECT_FALSE(IsRenderingOf(o.out_dir, tiled, &why));
  EXPECT_EQ(why, "camera_noise: absent (wanted \"0.8:0.02\")");
  tiled.camera_noise.enabled = false;
  EXPECT_TRUE(IsRenderingOf(o.out_dir, tiled, &why)) << why;
  tiled.camera_noise.enabled = true;
  testing::WriteFile(marker, j.dump(2));

  // Terrain: a marker of before 2026-12-07 has no "ground" (the ground that repeated every 5 m,
  // which this renderer no longer makes).
  nlohmann::json t = j;
  t["world"] = "terrain";
  SimulationOptions terrain = tiled;
  terrain.world.kind = WorldKind::kTerrain;
  testing::WriteFile(marker, t.dump(2));
  EXPECT_FALSE(IsRenderingOf(o.out_dir, terrain, &why));
  EXPECT_EQ(why, "ground: absent (wanted \"varied\")");
  t["ground"] = "varied";
  testing::WriteFile(marker, t.dump(2));
  EXPECT_TRUE(IsRenderingOf(o.out_dir, terrain, &why)) << why;

  // The orthophoto: the same file by another path is the same map; another file is not.
  const fs::path map = dir / "maps" / "map.tif", other_map = dir / "maps" / "other.tif";
  testing::WriteFile(map, "tif");
  testing::WriteFile(other_map, "tif");
  t["ortho"] = fs::absolute(map).string();
  testing::WriteFile(marker, t.dump(2));
  SimulationOptions ortho = terrain;
  ortho.world.ortho_path = (dir / "maps" / "." / "map.tif").string();
  EXPECT_TRUE(IsRenderingOf(o.out_dir, ortho, &why)) << why;
  ortho.world.ortho_path = other_map.string();
  EXPECT_FALSE(IsRenderingOf(o.out_dir, ortho, &why));
  EXPECT_EQ(why.rfind("ortho:", 0), 0u) << why;
  ortho.world.ortho_path = (dir / "maps" / "missing.tif").string();
  EXPECT_FALSE(IsRenderingOf(o.out_dir, ortho, &why));
  t.erase("ortho");
  testing::WriteFile(marker, t.dump(2));

  // Another renderer version, a broken marker, none.
  j["renderer"] = kRendererVersion + 1;
  testing::WriteFile(marker, j.dump(2));
  EXPECT_FALSE(IsRenderingOf(o.out_dir, tiled, &why));
  EXPECT_EQ(why.rfind("renderer ", 0), 0u) << why;
  testing::WriteFile(marker, "{\"renderer\": ");
  EXPECT_FALSE(IsRenderingOf(o.out_dir, tiled, &why));
  EXPECT_NE(why.find("sim_complete.json"), std::string::npos) << why;
  fs::remove(marker);
  EXPECT_FALSE(IsRenderingOf(o.out_dir, tiled, &why));
  EXPECT_NE(why.find("not finished"), std::string::npos) << why;
}

TEST(Simulation, RefusesANonEmptyFolderAndBadInputBeforeWriting) {
  const fs::path dir = testing::MakeTempDir("sim_refuse");
  testing::WriteFile(dir / "seq" / "keep.txt", "keep");
  SimulationOptions o = Small((dir / "seq").string(), DatasetFormat::kEuroc);
  o.duration_s = 0.2;
  try {
    RunSimulation(o);
    ADD_FAILURE() << "wrote into a non-empty folder";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not empty"), std::string::npos) << e.what();
  }
  EXPECT_EQ(Slurp(dir / "seq" / "keep.txt"), "keep");
  // A bad waypoint file fails before the folder is touched, even with force.
  testing::WriteFile(dir / "wp.txt", "0, 0, 10\n5, x, 10\n");
  o.route = "drone:" + (dir / "wp.txt").string();
  o.force = true;
  try {
    RunSimulation(o);
    ADD_FAILURE() << "accepted a bad waypoint file";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("wp.txt:2"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(dir / "seq" / "keep.txt"));
  // With force and a good waypoint file it replaces the contents and completes.
  testing::WriteFile(dir / "wp.txt", "0, 0, 10\n20, 0, 12, 90\n20, 20, 10\n");
  RunSimulation(o);
  EXPECT_FALSE(fs::exists(dir / "seq" / "keep.txt"));
  EXPECT_TRUE(fs::exists(dir / "seq" / "sim_complete.json"));
}

TEST(Simulation, PngEncoderRoundTrips) {
  cv::Mat colour(37, 53, CV_8UC3), grey(20, 31, CV_8UC1);
  cv::randu(colour, 0, 256);
  cv::randu(grey, 0, 256);
  for (int level : {0, 1, 9}) {
    EXPECT_EQ(cv::norm(cv::imdecode(EncodePng(colour, level), cv::IMREAD_UNCHANGED), colour,
                       cv::NORM_INF),
              0);
    EXPECT_EQ(
        cv::norm(cv::imdecode(EncodePng(grey, level), cv::IMREAD_UNCHANGED), grey, cv::NORM_INF),
        0);
  }
  EXPECT_ERROR(EncodePng(cv::Mat(2, 2, CV_32F)), {}, "needs a non-empty 8-bit 1- or 3-channel");
}

TEST(Simulation, SuiteHasTheWeatherDatasetsThirtySixSequences) {
  const auto suite = WeatherSuite();
  int urban = 0, terrain = 0;
  for (const auto& e : suite) (e.world == WorldKind::kUrban ? urban : terrain)++;
  EXPECT_EQ(urban, 24);
  EXPECT_EQ(terrain, 12);
}

}  // namespace
}  // namespace optinav::sim
