#include "optinav/app/sim_suite.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

sim::SimulationOptions Tiny(const std::filesystem::path& out) {
  sim::SimulationOptions o;
  o.out_dir = out.string();
  o.duration_s = 0.5;
  o.scale = 0.1;
  o.seed = 3;
  return o;
}

TEST(SimulateWithProgress, HalfASecondOfTheCarRoute) {
  const std::filesystem::path dir = testing::MakeTempDir("sim_one");
  const sim::SimulationSummary s = SimulateWithProgress(Tiny(dir / "seq"), "sim");
  // The car rig: 800x600, a frame every 30 ms; IMU 200 Hz, GNSS 5 Hz; samples at both ends.
  EXPECT_EQ(s.frames, 17u);
  EXPECT_EQ(s.imu_samples, 101u);
  EXPECT_EQ(s.gnss_samples, 3u);
  EXPECT_EQ(s.width, 80);
  EXPECT_EQ(s.height, 60);
  EXPECT_TRUE(std::filesystem::exists(dir / "seq" / "sim_complete.json"));
  std::filesystem::remove_all(dir);
}

TEST(RunWeatherSuite, RefusesANonEmptyFolderAndLeavesIt) {
  const std::filesystem::path dir = testing::MakeTempDir("sim_suite");
  testing::WriteFile(dir / "note.txt", "keep me");
  int calls = 0;
  const auto count = [&](size_t, const sim::SuiteEntry&, const sim::SimulationSummary&) {
    ++calls;
  };
  EXPECT_ERROR(RunWeatherSuite(Tiny(dir), count),
               {.file = dir.string(), .line = 0, .field = "--out"},
               "output folder exists and is not empty (use --force to replace its contents)");
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(testing::ReadFile(dir / "note.txt"), "keep me");
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 1);

  // Invalid options fail before the folder is touched.
  sim::SimulationOptions bad = Tiny(dir / "new");
  bad.scale = 0;
  EXPECT_ERROR(RunWeatherSuite(bad, count), {.file = "", .line = 0, .field = ""},
               "--scale 0 not in [0.05, 4]");
  EXPECT_FALSE(std::filesystem::exists(dir / "new"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace optinav::app
