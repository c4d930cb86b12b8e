// Round trips: every EuRoC/ASL writer's file read back by the reader for it gives the values
// written (to the written decimals), timestamps exactly and quaternions in w x y z order.
#include "optinav/io/euroc_writer.h"

#include <filesystem>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::io {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000'123;  // needs all 19 digits: no double on the way

class EurocWriterTest : public ::testing::Test {
 protected:
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_ = testing::MakeTempDir("euroc_writer");
};

// A rotation with four distinct, non-zero quaternion components: a w x y z / x y z w mix-up
// cannot go unnoticed.
Eigen::Quaterniond Tilted() { return Eigen::Quaterniond(0.8, 0.1, -0.3, 0.5).normalized(); }

TEST_F(EurocWriterTest, ImageListRoundTrips) {
  const std::string p = Path("cam0/data.csv");
  WriteImageList(p, {{kT0, "a.png"}, {kT0 + 50'000'000, "b.png"}});
  const std::vector<ImageEntry> back = ReadImageList(p, Path("cam0/data"), /*check_exist=*/false);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].t_ns, kT0);
  EXPECT_EQ(back[1].t_ns, kT0 + 50'000'000);
  EXPECT_EQ(back[1].path, (dir_ / "cam0" / "data" / "b.png").string());
  EXPECT_EQ(ReadFileToString(p), "#timestamp [ns],filename\n" + std::to_string(kT0) + ",a.png\n" +
                                     std::to_string(kT0 + 50'000'000) + ",b.png\n");
}

TEST_F(EurocWriterTest, CameraSensorYamlRoundTripsEveryDistortionModel) {
  camera::PinholeCamera cam;
  cam.width = 752;
  cam.height = 480;
  cam.fx = 458.654;
  cam.fy = 457.296;
  cam.cx = 367.215;
  cam.cy = 248.375;
  const Rigid3d body_from_cam(Tilted(), Eigen::Vector3d(-0.0216, -0.0647, 0.0098));
  for (const auto model :
       {camera::DistortionModel::kNone, camera::DistortionModel::kRadialTangential,
        camera::DistortionModel::kEquidistant}) {
    cam.distortion = model;
    cam.coeffs = model == camera::DistortionModel::kNone
                     ? std::array<double, 4>{0, 0, 0, 0}
                     : std::array<double, 4>{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
    const std::string p = Path("cam_" + camera::DistortionModelName(model) + ".yaml");
    WriteCameraSensorYaml(p, ToCameraCalibration(cam, body_from_cam, 20.0), "left camera");
    const CameraCalibration back = ReadCameraCalibration(p);
    SCOPED_TRACE(p);
    EXPECT_EQ(back.width, 752);
    EXPECT_EQ(back.height, 480);
    EXPECT_NEAR(back.fx, 458.654, 1e-9);
    EXPECT_NEAR(back.cy, 248.375, 1e-9);
    EXPECT_DOUBLE_EQ(back.rate_hz, 20.0);
    // No distortion is written as zero radial-tangential coefficients: the same camera.
    const camera::PinholeCamera read = ToPinholeCamera(back);
    EXPECT_EQ(read.distortion, model == camera::DistortionModel::kNone
                                   ? camera::DistortionModel::kRadialTangential
                                   : model);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(read.coeffs[i], cam.coeffs[i], 1e-15) << i;
    EXPECT_LT((back.body_from_cam.translation - body_from_cam.translation).norm(), 1e-12);
    EXPECT_LT(back.body_from_cam.rotation.angularDistance(body_from_cam.rotation), 1e-9);
  }
}

TEST_F(EurocWriterTest, ImuSensorYamlRoundTrips) {
  ImuCalibration c;
  c.rate_hz = 200;
  c.gyroscope_noise_density = 1.6968e-4;
  c.gyroscope_random_walk = 1.9393e-5;
  c.accelerometer_noise_density = 2.0e-3;
  c.accelerometer_random_walk = 3.0e-3;
  const std::string p = Path("imu0/sensor.yaml");
  WriteImuSensorYaml(p, c, /*noise_free=*/true, "simulated IMU");
  const ImuCalibration back = ReadImuCalibration(p);
  EXPECT_DOUBLE_EQ(back.rate_hz, 200);
  EXPECT_DOUBLE_EQ(back.gyroscope_noise_density, 1.6968e-4);
  EXPECT_DOUBLE_EQ(back.gyroscope_random_walk, 1.9393e-5);
  EXPECT_DOUBLE_EQ(back.accelerometer_noise_density, 2.0e-3);
  EXPECT_DOUBLE_EQ(back.accelerometer_random_walk, 3.0e-3);
  EXPECT_TRUE(back.body_from_imu.ToMatrix().isIdentity(0));
  EXPECT_NE(ReadFileToString(p).find("noise_free: true\n"), std::string::npos);
}

TEST_F(EurocWriterTest, ImuCsvRoundTrips) {
  std::vector<ImuSample> samples;
  for (int k = 0; k < 5; ++k) {
    samples.push_back({kT0 + k * 5'000'000, Eigen::Vector3d(0.01 * k, -0.123456789012, 1e-7),
                       Eigen::Vector3d(0.5, -0.25 * k, 9.80665)});
  }
  const std::string p = Path("imu0/data.csv");
  WriteImuCsv(p, samples);
  const std::vector<ImuSample> back = ReadImuCsv(p);
  ASSERT_EQ(back.size(), samples.size());
  for (size_t k = 0; k < samples.size(); ++k) {
    EXPECT_EQ(back[k].t_ns, samples[k].t_ns);
    EXPECT_LT((back[k].gyro_rad_s - samples[k].gyro_rad_s).norm(), 1e-12);
    EXPECT_LT((back[k].accel_m_s2 - samples[k].accel_m_s2).norm(), 1e-12);
  }
}

TEST_F(EurocWriterTest, BarometerRoundTripsAndBadFilesNameTheLine) {
  std::vector<BaroSample> samples;
  for (int k = 0; k < 4; ++k) samples.push_back({kT0 + k * 50'000'000, 412.25 - 0.123456 * k});
  const std::string p = Path("baro0/data.csv");
  WriteBaroCsv(p, samples);
  const std::vector<BaroSample> back = ReadBaroCsv(p);
  ASSERT_EQ(back.size(), samples.size());
  for (size_t k = 0; k < samples.size(); ++k) {
    EXPECT_EQ(back[k].t_ns, samples[k].t_ns);
    EXPECT_NEAR(back[k].altitude_m, samples[k].altitude_m, 1e-6);
  }
  const BaroCalibration c{
      .rate_hz = 20, .noise_sigma_m = 0.3, .bias_sigma_m = 2, .bias_random_walk = 0.02};
  WriteBaroSensorYaml(Path("baro0/sensor.yaml"), c, "test");
  const BaroCalibration cb = ReadBaroCalibration(Path("baro0/sensor.yaml"));
  EXPECT_EQ(cb.rate_hz, 20);
  EXPECT_EQ(cb.noise_sigma_m, 0.3);
  EXPECT_EQ(cb.bias_sigma_m, 2);
  EXPECT_EQ(cb.bias_random_walk, 0.02);

  const auto expect_error = [&](const std::string& text, const std::string& what) {
    WriteFileAtomically(Path("bad.csv"), text);
    try {
      ReadBaroCsv(Path("bad.csv"));
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.csv"), std::string::npos) << e.what();
    }
  };
  expect_error("#t,alt\n100,5.0\n200,nan\n", ":3: field 'altitude'");
  expect_error("100,5.0\n100,6.0\n", ":2: field 'timestamp'");  // not increasing
  expect_error("100,5.0,1\n", "found 3 fields");
  WriteFileAtomically(Path("bad.yaml"),
                      "rate_hz: 20\nnoise_sigma_m: -1\nbias_sigma_m: 0\nbias_random_walk: 0\n");
  EXPECT_THROW(ReadBaroCalibration(Path("bad.yaml")), Error);
}

TEST_F(EurocWriterTest, GroundTruthRoundTripsWithQuaternionWxyz) {
  std::vector<GroundTruthState> states;
  for (int k = 0; k < 3; ++k) {
    GroundTruthState s;
    s.t_ns = kT0 + k * 5'000'000;
    s.world_from_body = Rigid3d(Tilted(), Eigen::Vector3d(1.5 * k, -2.25, 10.125));
    s.velocity_in_world = Eigen::Vector3d(1, 2, 3);
    s.gyro_bias = Eigen::Vector3d(1e-3, -2e-3, 3e-4);
    states.push_back(s);
  }
  const std::string p = Path("state_groundtruth_estimate0/data.csv");
  WriteGroundTruthCsv(p, states);
  const Trajectory back = ReadTrajectory(p);
  ASSERT_EQ(back.size(), 3u);
  const Eigen::Quaterniond q = Tilted();
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(back.t_ns[k], states[k].t_ns);
    EXPECT_LT((back.positions[k] - states[k].world_from_body.translation).norm(), 1e-9);
    const Eigen::Quaterniond r = back.quaternion(k);
    EXPECT_NEAR(r.w(), q.w(), 1e-9);
    EXPECT_NEAR(r.x(), q.x(), 1e-9);
    EXPECT_NEAR(r.y(), q.y(), 1e-9);
    EXPECT_NEAR(r.z(), q.z(), 1e-9);
  }
  // Columns 5-8 are q w x y z, then velocity and the two biases: 17 in all.
  const std::string text = ReadFileToString(p);
  const size_t eol = text.find('\n');
  std::vector<std::string_view> f;
  SplitFields(std::string_view(text).substr(eol + 1, text.find('\n', eol + 1) - eol - 1), ',', &f);
  ASSERT_EQ(f.size(), 17u);
  EXPECT_EQ(f[0], std::to_string(kT0));
  EXPECT_EQ(f[4], fmt::format("{:.9f}", q.w()));
  EXPECT_EQ(f[5], fmt::format("{:.9f}", q.x()));
  EXPECT_EQ(f[7], fmt::format("{:.9f}", q.z()));
  EXPECT_EQ(f[8], "1.000000000");
  EXPECT_EQ(f[11], "0.001");
  EXPECT_EQ(f[16], "0");
}

TEST_F(EurocWriterTest, GnssCsvRoundTripsEnuAndLatLonHeight) {
  std::vector<GnssRecord> enu = {{.t_ns = kT0, .value = Eigen::Vector3d(1.5, -2.25, 10)},
                                 {.t_ns = kT0 + 200'000'000, .value = Eigen::Vector3d(-3, 4, 5)}};
  const std::string p_enu = Path("gnss0/data.csv");
  WriteGnssCsv(p_enu, GnssFileKind::kEnu, enu);
  GnssFile back = ReadGnssFile(p_enu);
  EXPECT_EQ(back.kind, GnssFileKind::kEnu);
  ASSERT_EQ(back.records.size(), 2u);
  EXPECT_EQ(back.records[1].t_ns, kT0 + 200'000'000);
  EXPECT_LT((back.records[1].value - enu[1].value).norm(), 1e-6);
  EXPECT_FALSE(back.records[0].sigma_m.has_value());

  std::vector<GnssRecord> llh = {
      {.t_ns = kT0, .value = Eigen::Vector3d(47.3769123456, 8.5417654321, 408.5)},
      {.t_ns = kT0 + 200'000'000, .value = Eigen::Vector3d(-33.9, 151.2, -20)}};
  const std::vector<bool> outliers = {false, true};
  const std::string p_llh = Path("gnss0/llh.csv");
  WriteGnssCsv(p_llh, GnssFileKind::kLatLonHeight, llh, &outliers);
  back = ReadGnssFile(p_llh);  // the kind comes from the header
  EXPECT_EQ(back.kind, GnssFileKind::kLatLonHeight);
  ASSERT_EQ(back.records.size(), 2u);
  EXPECT_EQ(back.records[0].t_ns, kT0);
  EXPECT_NEAR(back.records[0].value.x(), 47.3769123456, 1e-10);
  EXPECT_NEAR(back.records[0].value.y(), 8.5417654321, 1e-10);
  EXPECT_NEAR(back.records[0].value.z(), 408.5, 1e-6);
  EXPECT_NE(ReadFileToString(p_llh).find(", outlier\n"), std::string::npos);
  EXPECT_NE(ReadFileToString(p_llh).find(",151.2000000000,-20.000000,1\n"), std::string::npos);
}

TEST_F(EurocWriterTest, GnssSensorYamlRoundTrips) {
  GnssSensorDescription g;
  g.lever_arm_in_body = Eigen::Vector3d(0.1, -0.2, 0.3);
  g.rate_hz = 5;
  g.sigma_m = 1.5;
  g.outages_s = {{10, 5}, {30.25, 2}};
  g.origin_lat_lon_height = Eigen::Vector3d(47.3769, 8.5417, 408);
  const std::string p = Path("gnss0/sensor.yaml");
  WriteGnssSensorYaml(p, g);
  const GnssSensorInfo back = ReadGnssSensorYaml(p);
  ASSERT_TRUE(back.lever_arm_in_body && back.sigma_m && back.origin_lat_lon_height);
  EXPECT_LT((*back.lever_arm_in_body - g.lever_arm_in_body).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(*back.sigma_m, 1.5);
  EXPECT_LT((*back.origin_lat_lon_height - g.origin_lat_lon_height).norm(), 1e-9);
  EXPECT_NE(ReadFileToString(p).find("outages_s: [[10.000, 5.000], [30.250, 2.000]]"),
            std::string::npos);
}

TEST_F(EurocWriterTest, InconsistentInputIsAnErrorNamingFileAndField) {
  const std::string p = Path("gnss0/bad.csv");
  const std::vector<bool> one = {true};
  EXPECT_ERROR(WriteGnssCsv(p, GnssFileKind::kEnu, {}, &one), {.file = p, .field = "outlier"},
               "1 outlier flags for 0 GNSS records");
  EXPECT_FALSE(fs::exists(p));

  CameraCalibration c;
  c.width = c.height = 10;
  c.fx = c.fy = 5;
  c.distortion_model = "equidistant";
  c.distortion = {0.1, 0.2, 0.3};
  const std::string yaml = Path("cam/sensor.yaml");
  EXPECT_ERROR(WriteCameraSensorYaml(yaml, c, ""),
               {.file = yaml, .field = "distortion_coefficients"},
               "distortion model equidistant needs 4 coefficients, got 3");
}

}  // namespace
}  // namespace optinav::io
