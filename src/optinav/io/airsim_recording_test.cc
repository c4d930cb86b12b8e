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

TEST(AirsimRecording, WriterRoundTripsThroughTheReader) {
  const auto dir = testing::MakeTempDir("airsim_write");
  AirsimRecording rec;
  const Rigid3d pose(Eigen::Quaterniond(0.8, 0.1, -0.3, 0.5).normalized(),
                     Eigen::Vector3d(12.5, -3.25, 1.9));
  for (int k = 0; k < 2; ++k) {
    rec.records.push_back({.t_ns = 1'700'000'000'000'000'000 + k * 30'000'000,
                           .vehicle = "PhysXCar",
                           .world_from_body = pose,
                           .throttle = 0.7,
                           .steering = -0.25,
                           .rpm = 1250.5,
                           .speed_m_s = 2.5,
                           .gear = 1,
                           .image_paths = {"l.png", "r.png"}});
    rec.left_camera.push_back({.t_ns = rec.records.back().t_ns, .world_from_cam = pose});
  }
  WriteAirsimRecording(dir.string(), rec);
  const AirsimRecording back = ReadAirsimRecording(dir.string(), {.check_images_exist = false});
  ASSERT_EQ(back.records.size(), 2u);
  ASSERT_EQ(back.left_camera.size(), 2u);
  const AirsimRecord& r = back.records[1];
  EXPECT_EQ(r.t_ns, 1'700'000'000'030'000'000);  // whole milliseconds survive exactly
  EXPECT_EQ(r.vehicle, "PhysXCar");
  ASSERT_TRUE(r.world_from_body.has_value());
  // NED on disk, ENU / FLU in memory: back to the same pose (6 and 9 decimals on disk).
  EXPECT_LT((r.world_from_body->translation - pose.translation).norm(), 1e-6);
  EXPECT_LT(r.world_from_body->rotation.angularDistance(pose.rotation), 1e-8);
  EXPECT_LT(back.left_camera[1].world_from_cam.rotation.angularDistance(pose.rotation), 1e-8);
  EXPECT_DOUBLE_EQ(r.throttle, 0.7);
  EXPECT_DOUBLE_EQ(r.steering, -0.25);
  EXPECT_DOUBLE_EQ(r.rpm, 1250.5);
  EXPECT_EQ(r.gear, 1);
  ASSERT_EQ(r.image_paths.size(), 2u);
  EXPECT_EQ(r.image_paths[1], (dir / "images" / "r.png").string());

  rec.records[0].world_from_body.reset();
  const std::string rec_path = (dir / "airsim_rec.txt").string();
  EXPECT_ERROR(WriteAirsimRecording(dir.string(), rec), {.file = rec_path, .field = "POS_X"},
               "record 0 (t = 1700000000000000000 ns) has no pose to write");
}

}  // namespace
}  // namespace optinav::io
