#include "optinav/io/airsim_recording.h"

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav::io {
namespace {

TEST(AirsimRecording, ReadsTheCarRecorderFormatAndConvertsNedToEnu) {
  const auto dir = testing::MakeTempDir("airsim");
  testing::WriteFile(dir / "images" / "l1.png", "x");
  testing::WriteFile(dir / "images" / "r1.png", "x");
  testing::WriteFile(dir / "images" / "l2.png", "x");
  testing::WriteFile(dir / "images" / "r2.png", "x");
  testing::WriteFile(
      dir / "airsim_rec.txt",
      "VehicleName\tTimeStamp\tPOS_X\tPOS_Y\tPOS_Z\tQ_W\tQ_X\tQ_Y\tQ_Z\tThrottle\tSteering\t"
      "Brake\tGear\tHandbrake\tRPM\tSpeed\tImageFile\n"
      "PhysXCar\t1000\t0\t0\t0\t1\t0\t0\t0\t0.7\t0\t0\t1\t0\t900\t0.5\tl1.png;r1.png\n"
      // 90 deg right turn (yaw +90 in NED), 10 m north, 2 m east, 1 m down.
      "PhysXCar\t1030\t10\t2\t1\t0.70710678\t0\t0\t0.70710678\t0.5\t0.5\t0\t1\t0\t950\t6\t"
      "l2.png;r2.png\n");
  const AirsimRecording rec = ReadAirsimRecording(dir.string());
  ASSERT_EQ(rec.records.size(), 2u);
  EXPECT_EQ(rec.records[1].t_ns, 1'030'000'000);
  const Rigid3d& p = *rec.records[1].world_from_body;
  EXPECT_NEAR((p.translation - Eigen::Vector3d(2, 10, -1)).norm(), 0, 1e-12);
  // Facing east after the right turn: body x along ENU x, body z up.
  EXPECT_NEAR((p.rotation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm(), 0, 1e-6);
  EXPECT_NEAR((p.rotation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ()).norm(), 0, 1e-6);
  // At identity the car faces north.
  EXPECT_NEAR((rec.records[0].world_from_body->rotation * Eigen::Vector3d::UnitX() -
               Eigen::Vector3d::UnitY())
                  .norm(),
              0, 1e-9);
  EXPECT_DOUBLE_EQ(rec.records[1].steering, 0.5);
  EXPECT_EQ(rec.records[1].image_paths.size(), 2u);
  // Conversions are inverse of each other.
  const Rigid3d x(ExpSO3(Eigen::Vector3d(0.3, -0.2, 1.1)), Eigen::Vector3d(1, 2, 3));
  EXPECT_NEAR(LogSE3(EnuFluFromNedFrd(NedFrdFromEnuFlu(x)).Inverse() * x).norm(), 0, 1e-12);
  EXPECT_NEAR(
      LogSE3(EnuOpticalFromNedAirsimCamera(NedAirsimCameraFromEnuOptical(x)).Inverse() * x).norm(),
      0, 1e-12);
}

TEST(AirsimRecording, AcceptsTheTwoColumnVariant) {
  const auto dir = testing::MakeTempDir("airsim2");
  testing::WriteFile(dir / "images" / "a.png", "x");
  testing::WriteFile(dir / "airsim_rec.txt", "TimeStamp ImageFile\n5 a.png\n");
  const AirsimRecording rec = ReadAirsimRecording((dir / "airsim_rec.txt").string());
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_FALSE(rec.records[0].world_from_body.has_value());
  EXPECT_EQ(rec.records[0].t_ns, 5'000'000);
}

TEST(AirsimRecording, BadInputNamesFileLineAndField) {
  const auto dir = testing::MakeTempDir("airsim3");
  testing::WriteFile(dir / "images" / "a.png", "x");
  auto expect = [&](const std::string& text, const std::string& needle) {
    testing::WriteFile(dir / "airsim_rec.txt", text);
    try {
      ReadAirsimRecording(dir.string());
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect("TimeStamp\tImageFile\n5\tmissing.png\n", "airsim_rec.txt:2");
  expect("TimeStamp\tImageFile\n5\ta.png\n4\ta.png\n", "does not increase");
  expect("TimeStamp\tImageFile\nx\ta.png\n", "field 'TimeStamp'");
  expect("Time\tImageFile\n5\ta.png\n", "TimeStamp");
  expect("TimeStamp\tPOS_X\tImageFile\n5\t1\ta.png\n", "not all of POS_X");
}

}  // namespace
}  // namespace optinav::io
