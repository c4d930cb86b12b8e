#include "optinav/io/euroc_dataset.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "optinav/io/gnss_io.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/testing.h"

namespace fs = std::filesystem;

namespace optinav::io {
namespace {

fs::path Micro() { return testing::SharedDataDir() / "euroc" / "V1_01_micro"; }

TEST(EurocDataset, RealClipListsMissingCam1Images) {
  // The clip's cam1/data.csv lists 99 frames but ships 95: strict opening names the first gap.
  try {
    OpenEurocDataset(Micro().string());
    FAIL() << "missing cam1 images not reported";
  } catch (const Error& e) {
    EXPECT_NE(e.context().file.find("cam1/data.csv"), std::string::npos);
    EXPECT_EQ(e.context().line, 97);
  }
}

TEST(EurocDataset, OpensRealV101Clip) {
  const EurocDataset ds =
      OpenEurocDataset(Micro().string(), {.check_images_exist = true, .drop_missing_images = true});
  ASSERT_TRUE(ds.cam0 && ds.cam1 && ds.imu_calibration);
  EXPECT_EQ(ds.cam0->images.size(), 95u);
  EXPECT_EQ(ds.cam1->images.size(), 95u);
  EXPECT_EQ(ds.cam0->images.front().t_ns, 1403715273262142976);
  const CameraCalibration& c = ds.cam0->calibration;
  EXPECT_EQ(c.width, 752);
  EXPECT_EQ(c.height, 480);
  EXPECT_DOUBLE_EQ(c.fx, 458.654);
  EXPECT_DOUBLE_EQ(c.cy, 248.375);
  EXPECT_EQ(c.distortion_model, "radial-tangential");
  EXPECT_DOUBLE_EQ(c.distortion[0], -0.28340811);
  EXPECT_DOUBLE_EQ(c.rate_hz, 20.0);
  // T_BS first row: 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975
  const Eigen::Matrix4d t = c.body_from_cam.ToMatrix();
  EXPECT_NEAR(t(0, 1), -0.999880929698, 1e-6);
  EXPECT_NEAR(t(0, 3), -0.0216401454975, 1e-12);
  EXPECT_NEAR(ds.imu_calibration->gyroscope_noise_density, 1.6968e-04, 1e-12);
  EXPECT_NEAR(ds.imu_calibration->accelerometer_random_walk, 3.0e-3, 1e-12);
  EXPECT_DOUBLE_EQ(ds.imu_calibration->rate_hz, 200.0);
  EXPECT_TRUE(ds.gnss_csv.empty());
  ASSERT_FALSE(ds.groundtruth_csv.empty());
  const auto gt = ReadTrajectory(ds.groundtruth_csv);
  EXPECT_GE(gt.size(), 95u);
  EXPECT_EQ(gt.t_ns.front(), 1403715273262142976);
  // Opening mav0 directly works too.
  EXPECT_EQ(OpenEurocDataset((Micro() / "mav0").string(), {.drop_missing_images = true}).mav0_dir,
            ds.mav0_dir);
}

TEST(EurocDataset, RealClipStereoRig) {
  const EurocDataset ds = OpenEurocDataset(Micro().string(), {.check_images_exist = false});
  const camera::StereoRig rig = ToStereoRig(ds.cam0->calibration, ds.cam1->calibration);
  // EuRoC's stereo baseline is about 11 cm, the right camera to the +x of the left one.
  EXPECT_NEAR(rig.Baseline(), 0.110, 0.002);
  EXPECT_LT(rig.right_from_left.translation.x(), -0.10);
  EXPECT_LT(RotationAngle(rig.right_from_left.rotation), 0.02);  // 0.82 deg in V1_01
  EXPECT_EQ(rig.left.distortion, camera::DistortionModel::kRadialTangential);
  CameraCalibration bad = ds.cam0->calibration;
  bad.fx = 0;
  // The field names the sensor.yaml key to fix; the calibration no longer knows its file.
  EXPECT_ERROR(ToPinholeCamera(bad), {.field = "intrinsics"}, "positive focal lengths");
}

TEST(EurocDataset, ReadsImuAt200Hz) {
  const auto imu = ReadImuCsv((Micro() / "mav0" / "imu0" / "data.csv").string());
  ASSERT_GT(imu.size(), 1000u);
  EXPECT_EQ(imu[0].t_ns, 1403715273262142976);
  EXPECT_DOUBLE_EQ(imu[0].accel_m_s2.x(), 9.0874956666666655);
  EXPECT_DOUBLE_EQ(imu[0].gyro_rad_s.y(), 0.017453292519943295);
  const double dt = (imu[100].t_ns - imu[0].t_ns) * 1e-9 / 100;
  EXPECT_NEAR(dt, 0.005, 1e-4);
}

// A small synthetic dataset for the failure cases; copies the real yaml files.
fs::path MakeDataset(const std::string& name) {
  const fs::path root = testing::MakeTempDir(name) / "mav0";
  for (const char* d : {"cam0", "imu0"}) fs::create_directories(root / d);
  fs::copy_file(Micro() / "mav0" / "cam0" / "sensor.yaml", root / "cam0" / "sensor.yaml");
  fs::copy_file(Micro() / "mav0" / "imu0" / "sensor.yaml", root / "imu0" / "sensor.yaml");
  testing::WriteFile(root / "cam0" / "data" / "100.png", "not really a png");
  testing::WriteFile(root / "cam0" / "data.csv", "#timestamp [ns],filename\n100,100.png\n");
  testing::WriteFile(root / "imu0" / "data.csv",
                     "#t,wx,wy,wz,ax,ay,az\n100,0,0,0,0,0,9.81\n105,0,0,0,0,0,9.81\n");
  return root;
}

TEST(EurocDataset, MissingImageNamesFileAndLine) {
  const fs::path root = MakeDataset("missingimg");
  testing::WriteFile(root / "cam0" / "data.csv", "#h\n100,100.png\n200,200.png\n");
  try {
    OpenEurocDataset(root.string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.context().line, 3);
    EXPECT_NE(std::string(e.what()).find("200.png"), std::string::npos);
  }
}

TEST(EurocDataset, BadImuAndGnssAndYaml) {
  const fs::path root = MakeDataset("badimu");
  EXPECT_NO_THROW(OpenEurocDataset(root.string()));
  const auto imu_csv =
      testing::WriteFile(root / "imu0" / "data.csv", "100,0,0,0,0,0,9.81\n105,0,nan,0,0,0,9.81\n");
  EXPECT_ERROR(ReadImuCsv(imu_csv), {.file = imu_csv, .line = 2, .field = "w_y"},
               "value is not finite: 'nan'");
  testing::WriteFile(root / "imu0" / "data.csv", "100,0,0,0,0,0,9.81\n90,0,0,0,0,0,9.81\n");
  try {
    ReadImuCsv(imu_csv);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.context().line, 2);
  }
  const auto gnss =
      testing::WriteFile(root / "gnss0" / "data.csv", "#t,x,y,z\n100,1,2,3\n200,1,2\n");
  // gnss0/data.csv is read by ReadGnssFile (gnss_io.h), the one GNSS csv reader.
  EXPECT_ERROR(ReadGnssFile(gnss), {.file = gnss, .line = 3}, "found 3 field(s)");
  testing::WriteFile(root / "gnss0" / "data.csv", "#t,x,y,z\n100,1,2,3\n200,1,2,4\n");
  EXPECT_EQ(ReadGnssFile(gnss).records.size(), 2u);
  EXPECT_FALSE(OpenEurocDataset(root.string()).gnss_csv.empty());
  testing::WriteFile(root / "cam0" / "sensor.yaml", "%YAML:1.0\nresolution: [752]\n");
  try {
    OpenEurocDataset(root.string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.context().field, "resolution");
  }
  EXPECT_ERROR(OpenEurocDataset((root / "nope").string()), {.file = (root / "nope").string()},
               "dataset folder not found");
}

TEST(EurocDataset, EquidistantModel) {
  const fs::path root = MakeDataset("equi");
  testing::WriteFile(root / "cam0" / "sensor.yaml",
                     "%YAML:1.0\nT_BS:\n  data: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n"
                     "rate_hz: 30\nresolution: [640, 480]\ncamera_model: pinhole\n"
                     "intrinsics: [300, 300, 320, 240]\ndistortion_model: equidistant\n"
                     "distortion_coefficients: [0.1, 0.01, -0.001, 0.0001]\n");
  const auto c = ReadCameraCalibration((root / "cam0" / "sensor.yaml").string());
  EXPECT_EQ(c.distortion_model, "equidistant");
  EXPECT_EQ(c.distortion.size(), 4u);
}

}  // namespace
}  // namespace optinav::io
