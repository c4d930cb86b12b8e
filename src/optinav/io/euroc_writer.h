// Writers of the EuRoC/ASL dataset files (the layout in euroc_dataset.h), in the layer of the
// readers that read them back: image lists, camera and IMU sensor.yaml and IMU csv
// (euroc_dataset.h), ground truth (trajectory_io.h ReadTrajectory), GNSS csv and sensor.yaml
// (gnss_io.h). euroc_writer_test.cc checks each round trip.
//
// Every file is written atomically (WriteFileAtomically: a temporary file and a rename). Numbers
// are written with fixed decimals, so the same values give byte-identical files: metres with 6
// (µm; ground truth 9), IMU rates with 12, unit quaternions with 9, degrees of latitude and
// longitude with 10 (about 11 µm). Timestamps are integer nanoseconds, quaternions are w x y z.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "optinav/geometry/lie.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/gnss_io.h"

namespace optinav::io {

// <cam>/data.csv: "#timestamp [ns],filename"; each entry's `path` is written as is (a name
// relative to <cam>/data/, as ReadImageList resolves it).
void WriteImageList(const std::string& path, const std::vector<ImageEntry>& images);

// <cam>/sensor.yaml (ReadCameraCalibration). `comment` fills the yaml's comment field. A camera
// without distortion is written as radial-tangential with zero coefficients: EuRoC/Kalibr tools
// know only radial-tangential and equidistant, and zero radial-tangential is no distortion.
void WriteCameraSensorYaml(const std::string& path, const CameraCalibration& calibration,
                           const std::string& comment);

// imu0/sensor.yaml (ReadImuCalibration), with the simulator's noise_free flag for the record.
void WriteImuSensorYaml(const std::string& path, const ImuCalibration& calibration, bool noise_free,
                        const std::string& comment);

// imu0/data.csv (ReadImuCsv): "timestamp [ns], w_RS_S_x..z [rad s^-1], a_RS_S_x..z [m s^-2]".
void WriteImuCsv(const std::string& path, const std::vector<ImuSample>& samples);

// baro0/data.csv (ReadBaroCsv): "timestamp [ns], altitude [m]", and baro0/sensor.yaml
// (ReadBaroCalibration).
void WriteBaroCsv(const std::string& path, const std::vector<BaroSample>& samples);
void WriteBaroSensorYaml(const std::string& path, const BaroCalibration& calibration,
                         const std::string& comment);

// One row of state_groundtruth_estimate0/data.csv.
struct GroundTruthState {
  int64_t t_ns = 0;
  Rigid3d world_from_body;
  Eigen::Vector3d velocity_in_world = Eigen::Vector3d::Zero();  // m/s
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();          // rad/s
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();         // m/s^2
};
// The EuRoC ground-truth csv (17 columns: p, q w x y z, v, b_w, b_a); ReadTrajectory reads its
// pose columns.
void WriteGroundTruthCsv(const std::string& path, const std::vector<GroundTruthState>& states);

// gnss0/data.csv (kEnu: "timestamp [ns], x [m], y [m], z [m]") or llh.csv (kLatLonHeight:
// latitude [deg], longitude [deg], height [m]), as ReadGnssFile reads them. `outliers`, when
// given (one flag per record), adds an "outlier" column of 1/0: the simulation's truth, which
// ReadGnssFile ignores. Records' sigma_m is not written (the simulated sigma is one value, in
// sensor.yaml).
void WriteGnssCsv(const std::string& path, GnssFileKind kind,
                  const std::vector<GnssRecord>& records, const std::vector<bool>* outliers = {});

// gnss0/sensor.yaml: what ReadGnssSensorYaml reads (lever arm, sigma, origin) and, for the
// record, the simulated rate, outliers and outages.
struct GnssSensorDescription {
  Eigen::Vector3d lever_arm_in_body = Eigen::Vector3d::Zero();  // m
  double rate_hz = 0, sigma_m = 0;
  double outlier_fraction = 0, outlier_magnitude_m = 0;
  std::vector<std::pair<double, double>> outages_s;                 // [start, duration], seconds
  Eigen::Vector3d origin_lat_lon_height = Eigen::Vector3d::Zero();  // deg, deg, m
};
void WriteGnssSensorYaml(const std::string& path, const GnssSensorDescription& gnss);

}  // namespace optinav::io
