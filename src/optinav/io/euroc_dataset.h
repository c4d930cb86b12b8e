// The EuRoC/ASL dataset layout:
//   <seq>/mav0/{cam0,cam1}/{sensor.yaml,data.csv,data/*.png}
//   <seq>/mav0/cam2/{sensor.yaml,data.csv,data/*.png} (optional: a nadir mapping camera)
//   <seq>/mav0/imu0/{sensor.yaml,data.csv}
//   <seq>/mav0/baro0/{sensor.yaml,data.csv} (optional: barometric altitude)
//   <seq>/mav0/gnss0/{sensor.yaml,data.csv,llh.csv} (optional; gnss_io.h reads them)
//   <seq>/mav0/state_groundtruth_estimate0/data.csv (optional)
// sensor.yaml T_BS is body_from_sensor (it maps sensor-frame points into the body/IMU frame).
// The writers of these files are in euroc_writer.h.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"
#include "optinav/util/error.h"

namespace optinav::io {

struct CameraCalibration {
  std::string camera_model = "pinhole";
  int width = 0, height = 0;              // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pinhole intrinsics, pixels
  // "radial-tangential" (k1 k2 p1 p2) or "equidistant" (k1..k4) or "none".
  std::string distortion_model = "none";
  std::vector<double> distortion;
  double rate_hz = 0;
  Rigid3d body_from_cam;
};

struct ImuCalibration {
  double rate_hz = 0;
  double gyroscope_noise_density = 0;      // rad / s / sqrt(Hz)
  double gyroscope_random_walk = 0;        // rad / s^2 / sqrt(Hz)
  double accelerometer_noise_density = 0;  // m / s^2 / sqrt(Hz)
  double accelerometer_random_walk = 0;    // m / s^3 / sqrt(Hz)
  Rigid3d body_from_imu;
};

struct ImageEntry {
  int64_t t_ns = 0;
  std::string path;  // absolute or relative to the working directory
};

struct ImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();
};

// A barometer's altitude: the height of the body above the world frame's origin (its z, metres)
// as a barometer referenced at the origin reports it, with the sensor's noise and bias.
struct BaroSample {
  int64_t t_ns = 0;
  double altitude_m = 0;
};

// baro0/sensor.yaml: the noise model (white noise and a bias that drifts as a random walk).
struct BaroCalibration {
  double rate_hz = 0;
  double noise_sigma_m = 0;     // white noise per sample (m)
  double bias_sigma_m = 0;      // initial bias (m, 1 sigma)
  double bias_random_walk = 0;  // m / sqrt(s)
};

struct CameraStream {
  CameraCalibration calibration;
  std::vector<ImageEntry> images;
};

struct EurocDataset {
  std::string mav0_dir;
  std::optional<CameraStream> cam0, cam1;
  std::optional<CameraStream> cam2;  // the nadir mapping camera, when there is one
  std::optional<ImuCalibration> imu_calibration;
  std::string imu_csv;  // empty when there is no imu0
  std::optional<BaroCalibration> baro_calibration;
  std::string baro_csv;         // empty when there is no baro0; read it with ReadBaroCsv
  std::string gnss_csv;         // empty when there is no gnss0; read it with ReadGnssFile
  std::string groundtruth_csv;  // empty when there is no ground truth
};

struct EurocOpenOptions {
  bool check_images_exist = true;  // stat every listed image
  // false: a listed but missing image is an Error naming the csv line. true: such entries are
  // dropped with a warning (real clips, like V1_01_micro's cam1, list frames they do not ship).
  bool drop_missing_images = false;
};

// Opens `dir` (the sequence folder holding mav0/, or mav0/ itself). Throws Error naming the file
// when the layout, a yaml or a csv is malformed, or a listed image is missing. At least one
// camera or the IMU must be present.
EurocDataset OpenEurocDataset(const std::string& dir, const EurocOpenOptions& options = {});

CameraCalibration ReadCameraCalibration(const std::string& sensor_yaml);
// The camera model of a calibration (intrinsics, distortion); throws Error when it is invalid.
camera::PinholeCamera ToPinholeCamera(const CameraCalibration& calibration);
// The calibration of a camera model (the inverse of ToPinholeCamera); a camera without
// distortion gets distortion_model "none" and no coefficients, as the reader gives them.
CameraCalibration ToCameraCalibration(const camera::PinholeCamera& camera,
                                      const Rigid3d& body_from_cam, double rate_hz);
// The stereo rig of two calibrations: right_from_left = (body_from_right)^-1 * body_from_left.
camera::StereoRig ToStereoRig(const CameraCalibration& left, const CameraCalibration& right);
ImuCalibration ReadImuCalibration(const std::string& sensor_yaml);
// cam data.csv: "timestamp [ns], filename"; paths resolved against <cam>/data/.
std::vector<ImageEntry> ReadImageList(const std::string& data_csv, const std::string& image_dir,
                                      bool check_exist, bool drop_missing = false);
// imu0 data.csv: "timestamp [ns], wx, wy, wz [rad/s], ax, ay, az [m/s^2]".
std::vector<ImuSample> ReadImuCsv(const std::string& data_csv);
// baro0 data.csv: "timestamp [ns], altitude [m]", increasing timestamps, finite values.
std::vector<BaroSample> ReadBaroCsv(const std::string& data_csv);
// baro0 sensor.yaml: rate_hz > 0, noise_sigma_m > 0, bias_sigma_m >= 0, bias_random_walk >= 0.
BaroCalibration ReadBaroCalibration(const std::string& sensor_yaml);

}  // namespace optinav::io
