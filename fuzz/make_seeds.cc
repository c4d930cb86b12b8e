// fuzz_make_seeds OUT_DIR: seed inputs written by the project's own writers (trajectories,
// EuRoC files, GNSS csv and yaml, AirSim recordings, GeoTIFFs, a map database), one folder per
// harness. scripts/fuzz.sh adds heads of the real files in ../shared/data and the committed
// seeds in fuzz/corpus/. Small on purpose: libFuzzer's mutations are cheap on short inputs.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "fuzz/fuzz_map.h"
#include "fuzz/fuzz_target.h"
#include "optinav/geo/raster.h"
#include "optinav/io/airsim_recording.h"
#include "optinav/io/euroc_writer.h"
#include "optinav/io/trajectory_io.h"

using namespace optinav;
namespace fs = std::filesystem;

namespace {

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void Write(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

Rigid3d Pose(int i) {
  const double a = 0.1 * i;
  return Rigid3d(
      Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d(0.2, 0.3, 1).normalized())),
      Eigen::Vector3d(std::cos(a), std::sin(a), 0.05 * i));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_make_seeds OUT_DIR\n");
    return 2;
  }
  fuzz::QuietLibraries();
  const fs::path out = argv[1];
  const fs::path tmp = fs::path(fuzz::ScratchDir()) / "seeds";
  fs::create_directories(tmp);
  const int64_t t0 = 1403636579763555584;

  Trajectory traj;
  for (int i = 0; i < 8; ++i) traj.Add(t0 + i * 50'000'000, Pose(i));
  io::WriteTrajectory((tmp / "t.tum").string(), traj, io::TrajectoryFormat::kTum);
  io::WriteTrajectory((tmp / "t.csv").string(), traj, io::TrajectoryFormat::kEuroc);
  io::WriteTrajectory((tmp / "t.kitti").string(), traj, io::TrajectoryFormat::kKitti);
  io::WriteKittiTimes((tmp / "t.times").string(), traj);
  Write(out / "traj_tum" / "written.tum", Read((tmp / "t.tum").string()));
  Write(out / "traj_euroc" / "written.csv", Read((tmp / "t.csv").string()));
  Write(out / "traj_kitti" / "written.kitti", Read((tmp / "t.kitti").string()));
  Write(out / "traj_kitti" / "written_with_times.kitti",
        Read((tmp / "t.kitti").string()) + "@@times@@\n" + Read((tmp / "t.times").string()));

  std::vector<io::ImuSample> imu;
  std::vector<io::ImageEntry> images;
  for (int i = 0; i < 8; ++i) {
    imu.push_back({t0 + i * 5'000'000, Eigen::Vector3d(0.01 * i, -0.02, 0.003),
                   Eigen::Vector3d(0.1, 9.81, -0.2 * i)});
    images.push_back({t0 + i * 50'000'000, std::to_string(t0 + i * 50'000'000) + ".png"});
  }
  io::WriteImuCsv((tmp / "imu.csv").string(), imu);
  io::WriteImageList((tmp / "cam.csv").string(), images);
  Write(out / "euroc_imu" / "written.csv", Read((tmp / "imu.csv").string()));
  Write(out / "euroc_images" / "written.csv", Read((tmp / "cam.csv").string()));

  std::vector<io::GnssRecord> gnss;
  for (int i = 0; i < 6; ++i) {
    io::GnssRecord r;
    r.t_ns = t0 + i * 200'000'000;
    r.value = Eigen::Vector3d(1.5 * i, -0.5 * i, 0.1);
    gnss.push_back(r);
  }
  const std::vector<bool> outliers = {false, false, true, false, false, false};
  io::WriteGnssCsv((tmp / "enu.csv").string(), io::GnssFileKind::kEnu, gnss, &outliers);
  for (auto& r : gnss) r.value = Eigen::Vector3d(47.37 + 1e-5 * r.value.x(), 8.54, 410);
  io::WriteGnssCsv((tmp / "llh.csv").string(), io::GnssFileKind::kLatLonHeight, gnss);
  Write(out / "gnss_csv" / "written_enu.csv", Read((tmp / "enu.csv").string()));
  Write(out / "gnss_csv" / "written_llh.csv", Read((tmp / "llh.csv").string()));

  io::CameraCalibration cam;
  cam.width = 752;
  cam.height = 480;
  cam.fx = 458.654;
  cam.fy = 457.296;
  cam.cx = 367.215;
  cam.cy = 248.375;
  cam.distortion_model = "radial-tangential";
  cam.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  cam.rate_hz = 20;
  cam.body_from_cam = Pose(3);
  io::WriteCameraSensorYaml((tmp / "cam.yaml").string(), cam, "fuzz seed");
  cam.distortion_model = "equidistant";
  cam.distortion = {0.01, -0.002, 0.0003, -0.00004};
  io::WriteCameraSensorYaml((tmp / "cam_eq.yaml").string(), cam, "fuzz seed");
  io::ImuCalibration ic;
  ic.rate_hz = 200;
  ic.gyroscope_noise_density = 1.6968e-04;
  ic.gyroscope_random_walk = 1.9393e-05;
  ic.accelerometer_noise_density = 2.0e-3;
  ic.accelerometer_random_walk = 3.0e-3;
  io::WriteImuSensorYaml((tmp / "imu.yaml").string(), ic, false, "fuzz seed");
  io::GnssSensorDescription gd;
  gd.lever_arm_in_body = Eigen::Vector3d(0.1, 0, 0.2);
  gd.rate_hz = 5;
  gd.sigma_m = 1.5;
  gd.outages_s = {{3, 2}};
  gd.origin_lat_lon_height = Eigen::Vector3d(47.37, 8.54, 410);
  io::WriteGnssSensorYaml((tmp / "gnss.yaml").string(), gd);
  for (const char* f : {"cam.yaml", "cam_eq.yaml", "imu.yaml", "gnss.yaml"})
    Write(out / "sensor_yaml" / (std::string("written_") + f), Read((tmp / f).string()));

  io::AirsimRecording rec;
  for (int i = 0; i < 4; ++i) {
    io::AirsimRecord r;
    r.t_ns = 1'000'000'000 + i * 50'000'000;
    r.vehicle = "PhysXCar";
    r.world_from_body = Pose(i);
    r.throttle = 0.5;
    r.gear = 1;
    r.speed_m_s = 2;
    r.image_paths = {"img_" + std::to_string(i) + "_0.png", "img_" + std::to_string(i) + "_1.png"};
    rec.records.push_back(r);
    rec.left_camera.push_back({r.t_ns, Pose(i + 1)});
  }
  io::WriteAirsimRecording((tmp / "airsim").string(), rec);
  Write(out / "airsim_rec" / "written.txt", Read((tmp / "airsim" / "airsim_rec.txt").string()));
  Write(out / "airsim_camera_info" / "written.csv",
        Read((tmp / "airsim" / "camera_info.csv").string()));

  // GeoTIFFs: grey and colour, tiled and striped, each compression, nodata, overviews.
  cv::Mat grey(40, 48, CV_8UC1), colour;
  cv::RNG rng(7);
  rng.fill(grey, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(grey, grey, cv::Size(3, 3), 1.0);
  cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
  geo::GeoTransform gt;
  gt.c = {500000.0, 0.5, 0.0, 5560000.0, 0.0, -0.5};
  int k = 0;
  for (const auto& [image, crs, opts] :
       std::vector<std::tuple<cv::Mat, std::string, geo::GeoTiffWriteOptions>>{
           {grey, "EPSG:32633", {.tiled = false, .compress = "NONE"}},
           {grey, "EPSG:4326", {.tiled = true, .compress = "DEFLATE", .nodata = 0.0}},
           {colour, "EPSG:32618", {.tiled = false, .compress = "LZW"}},
           {colour,
            "EPSG:32633",
            {.tiled = false, .compress = "DEFLATE", .build_overviews = true}}}) {
    const std::string p = (tmp / ("r" + std::to_string(k) + ".tif")).string();
    geo::WriteGeoTiff(p, image, gt, crs, opts);
    Write(out / "geotiff" / ("written_" + std::to_string(k++) + ".tif"), Read(p));
  }

  // The map database, and edit scripts for map_db_rows (see its header).
  Write(out / "map_db_file" / "written.db", Read(fuzz::BuildSmallMap((tmp / "map").string())));
  Write(out / "map_db_rows" / "no_edit", std::string(1, '\0'));
  Write(out / "map_db_rows" / "locate", std::string(1, '\2'));
  Write(out / "map_db_rows" / "nan_keypoint", std::string("\2\0\3\25\4", 5) + "\0\0\xc0\x7f");
  Write(out / "map_db_rows" / "empty_descriptors", std::string("\0\0\1\26\0\2\1\24\1\0", 10));
  return 0;
}
