#include "optinav/app/nav_run.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include <gtest/gtest.h>

#include "optinav/geo/geo.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/euroc_writer.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/maploc/map_db.h"
#include "optinav/sim/simulation.h"
#include "optinav/util/error.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

namespace fs = std::filesystem;

std::string Naip(const std::string& date) {
  return (testing::SharedDataDir() / "geo" / "naip" / ("naip_" + date + ".tif")).string();
}

// One short seeded flight over NAIP 2017 (450-520 m, ~20 m/s, a turn and a climb) with the
// NAIP 2009 map of issue 20, shared by the tests of this file.
class NavRunTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(testing::MakeTempDir("nav_run"));
    const std::string waypoints = (*dir_ / "flight.txt").string();
    io::WriteFileAtomically(waypoints,
                            "-400, -300, 450\n-150, -250, 470\n50, -100, 500\n100, 150, 520\n"
                            "-50, 350, 500\n");
    sim::SimulationOptions s;
    s.world.kind = sim::WorldKind::kOrtho;
    s.world.ortho_path = Naip("20170827");
    s.route = "drone:" + waypoints;
    s.speed_m_s = 20;
    s.scale = 0.1;
    s.seed = 7;
    s.out_dir = (*dir_ / "flight").string();
    s.nadir.enabled = true;
    s.baro.enabled = true;
    sim::RunSimulation(s);
    maploc::MapBuildOptions mb;
    mb.frame_width = mb.frame_height = 256;
    mb.hfov_deg = 90;
    mb.altitude_m = 640;
    maploc::BuildMapDatabase(Naip("20090818"), mb, (*dir_ / "map.db").string());
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static NavRunSettings Settings(const std::string& name) {
    NavRunSettings st;
    st.dataset = (*dir_ / "flight").string();
    st.map_path = (*dir_ / "map.db").string();
    st.out = (*dir_ / (name + ".tum")).string();
    st.stats_path = (*dir_ / (name + ".json")).string();
    st.wgs84_out = (*dir_ / (name + ".csv")).string();
    st.geojson_out = (*dir_ / (name + ".geojson")).string();
    return st;
  }
  inline static fs::path* dir_ = nullptr;
};

TEST_F(NavRunTest, MapFixesHoldTheFlight) {
  // From the given start the estimate follows the flight on map fixes + IMU + baro + odometry
  // (the global initialisation is measured by `optinav bench nav`: about a second per try).
  NavRunSettings st = Settings("map");
  st.nav.start = ReadSimTruth(st.dataset).value().Start();
  const NavRunReport r = RunNav(st);
  ASSERT_TRUE(r.error.has_value());
  std::printf(
      "nav, %zu poses over %.1f s: RMSE %.2f m (< 9), max %.2f m (< 20), altitude RMSE "
      "%.2f m (< 4); fixes %zu tried, %zu accepted; %.1fx real time\n",
      r.poses.size(), r.duration_s, r.error->rmse_m, r.error->max_m, r.error->altitude_rmse_m,
      r.stats.fixes_tried, r.stats.fixes_accepted, r.duration_s / r.wall_s);
  EXPECT_LT(r.error->rmse_m, 9.0);
  EXPECT_LT(r.error->max_m, 20.0);
  EXPECT_LT(r.error->altitude_rmse_m, 4.0);
  EXPECT_EQ(r.stats.resets, 0u);
  EXPECT_GE(r.stats.fixes_accepted, 15u);
  // Outputs: TUM with one pose per estimate, the WGS84 csv with sigmas, GeoJSON, statistics.
  EXPECT_EQ(io::ReadTrajectory(st.out).size(), r.poses.size());
  std::ifstream csv(st.wgs84_out);
  std::string line;
  size_t rows = 0;
  while (std::getline(csv, line))
    if (!line.empty() && line[0] != '#') ++rows;
  EXPECT_EQ(rows, r.poses.size());
  EXPECT_TRUE(fs::exists(st.geojson_out));
  std::ifstream stats(st.stats_path);
  const auto j = nlohmann::json::parse(stats);
  EXPECT_NEAR(j["error"]["rmse_m"].get<double>(), r.error->rmse_m, 1e-9);
  // The per-pose sigma is an uncertainty, not a constant: finite, positive, metres to tens.
  for (const nav::NavPose& p : r.poses) {
    const double s = std::sqrt(p.position_covariance(0, 0));
    EXPECT_TRUE(std::isfinite(s) && s > 0.1 && s < 200) << s;
  }
}

TEST_F(NavRunTest, AStartFromMapFixesAlignsBeforeItOutputs) {
  // GNSS-free: a global search, a confirming fix, then the window starts level (the start's
  // guess). No pose is output until its tilt is known (0.5 deg), then it restarts at a fix.
  NavRunSettings st = Settings("aligned");
  NavRunSettings off = Settings("unaligned");
  st.max_frames = off.max_frames = 125;  // the first 25 s
  off.nav.align_tilt_sigma_deg = 0;
  const NavRunReport r = RunNav(st), o = RunNav(off);
  ASSERT_TRUE(r.error && o.error);
  ASSERT_FALSE(r.poses.empty() || o.poses.empty());
  std::optional<int64_t> init;
  for (const nav::FixLog& f : r.fixes)
    if (!init && f.accepted) init = f.t_ns;
  ASSERT_TRUE(init.has_value());
  const double wait_s = (r.poses.front().t_ns - *init) * 1e-9;
  std::printf(
      "start from map fixes: first pose %.1f s after the first accepted fix (>= 1), max error "
      "%.2f m (< 15), first %.2f m, RMSE %.2f m; without the alignment first pose at the fix, "
      "max %.2f m, first %.2f m, RMSE %.2f m\n",
      wait_s, r.error->max_m, r.errors_m.front(), r.error->rmse_m, o.error->max_m,
      o.errors_m.front(), o.error->rmse_m);
  EXPECT_EQ(o.poses.front().t_ns, *init);
  EXPECT_GE(wait_s, 1.0);
  EXPECT_LT(r.error->max_m, 15.0);
  EXPECT_EQ(r.stats.resets, 0u);
}

TEST_F(NavRunTest, WrongFixesAreRejected) {
  // 10 % of the found fixes moved 300-1500 m away: none may enter, and the error stays close to
  // the clean run's. From a given start (the global search is the test above).
  NavRunSettings clean = Settings("clean");
  NavRunSettings bad = Settings("outliers");
  clean.nav.start = bad.nav.start = ReadSimTruth(clean.dataset).value().Start();
  bad.nav.inject_outlier_fraction = 0.1;
  const NavRunReport a = RunNav(clean), b = RunNav(bad);
  ASSERT_TRUE(a.error && b.error);
  std::printf(
      "wrong fixes: %zu injected, %zu accepted (0); RMSE %.2f m vs %.2f m clean "
      "(<= 1.5x + 2 m: fewer fixes cost accuracy on a 50 s flight; one accepted wrong fix "
      "costs hundreds of metres)\n",
      b.stats.outliers_injected, b.stats.outliers_accepted, b.error->rmse_m, a.error->rmse_m);
  EXPECT_GE(b.stats.outliers_injected, 3u);
  EXPECT_EQ(b.stats.outliers_accepted, 0u);
  EXPECT_LE(b.error->rmse_m, 1.5 * a.error->rmse_m + 2.0);
}

TEST_F(NavRunTest, AWrongStartIsRelocalisedAtTheAgreeingFixes) {
  // A start 150 m off that claims 5 m: the gate refuses the first fixes, they agree on one
  // offset, and the window restarts at the fix instead of following a wrong estimate (or
  // restarting at the given start again).
  NavRunSettings st = Settings("wrong_start");
  nav::NavStart start = ReadSimTruth(st.dataset).value().Start();
  start.position = geo::GeodesicDirect(start.position, 45.0, 150.0);
  start.position_sigma_m = 5.0;
  st.nav.start = start;
  const NavRunReport r = RunNav(st);
  ASSERT_TRUE(r.error.has_value());
  double late_max = 0;  // the last half of the flight
  for (size_t k = r.errors_m.size() / 2; k < r.errors_m.size(); ++k)
    late_max = std::max(late_max, r.errors_m[k]);
  std::printf(
      "wrong start (150 m off, sigma 5 m): %zu reset(s) (>= 1), first error %.1f m, last half max "
      "%.1f m (< 20), final %.1f m\n",
      r.stats.resets, r.errors_m.front(), late_max, r.error->final_m);
  EXPECT_GT(r.errors_m.front(), 100.0);
  EXPECT_GE(r.stats.resets, 1u);
  EXPECT_LT(late_max, 20.0);
}

TEST_F(NavRunTest, TheFixesHeadingCorrectsAWrongStartHeading) {
  // A compass 8 deg off that claims 2 deg: the fixes' heading (the correlation's search, the
  // features' pose) pulls the yaw back within seconds; from position fixes alone the heading is
  // only seen through the track, slowly. Both runs are printed, the fixes' heading is asserted.
  NavRunSettings with = Settings("yaw_fix");
  NavRunSettings without = Settings("yaw_none");
  nav::NavStart start = ReadSimTruth(with.dataset).value().Start();
  start.heading_deg += 8.0;
  start.heading_sigma_deg = 2.0;
  with.nav.start = without.nav.start = start;
  with.max_frames = without.max_frames = 125;  // the first 25 s
  without.nav.fix_yaw_sigma_deg = 0;
  const NavRunReport a = RunNav(with), b = RunNav(without);
  ASSERT_TRUE(a.error && b.error);
  ASSERT_FALSE(a.heading_errors_deg.empty());
  const auto after = [](const NavRunReport& r, double t_s) {
    double m = 0;
    for (size_t k = 0; k < r.error_t_ns.size(); ++k)
      if ((r.error_t_ns[k] - r.poses.front().t_ns) * 1e-9 >= t_s &&
          std::isfinite(r.heading_errors_deg[k]))
        m = std::max(m, std::abs(r.heading_errors_deg[k]));
    return m;
  };
  std::printf(
      "start heading 8 deg off (sigma 2), first 25 s: heading error first %.1f deg; max after 10 s "
      "%.2f deg (< 1.5) with the fixes' heading, %.2f deg without; RMSE %.2f / %.2f m\n",
      a.heading_errors_deg.front(), after(a, 10.0), after(b, 10.0), a.error->rmse_m,
      b.error->rmse_m);
  EXPECT_GT(std::abs(a.heading_errors_deg.front()), 5.0);
  EXPECT_LT(after(a, 10.0), 1.5);
  EXPECT_GT(a.stats.fix_yaws, 10u);
  EXPECT_EQ(b.stats.fix_yaws, 0u);
}

TEST_F(NavRunTest, AGapOfBlankFramesIsBridgedAndLeftWithin10s) {
  // 25 s of blank nadir frames (no map match, no odometry: IMU and barometer only), then the
  // map again. In the gap the accelerometer's x bias jumps by 0.8 m/s^2 (a copy of the flight;
  // the window cannot see it): the estimate drifts about 100 m, much further than its
  // covariance says, as 60 s of IMU only did on `bench nav`'s flight 2. No fix may be found on a
  // blank frame; once fixes return the estimate must be back under 10 m within 10 s (issue
  // 20; asserted: within 3 s of the first fix found, which the restart at the confirming second
  // fix gives) and end there. The same run without the post-gap confirmation is printed beside
  // (8-11 s).
  constexpr double kGapStart = 8, kGapEnd = 33;
  const fs::path src = Settings("x").dataset, dst = *dir_ / "flight_gap";
  const int64_t t0 = ReadSimTruth(src.string()).value().groundtruth.t_ns.front();
  if (!fs::exists(dst)) {
    fs::create_directories(dst / "mav0" / "imu0");
    fs::create_symlink(src / "sim_complete.json", dst / "sim_complete.json");
    for (const auto& e : fs::directory_iterator(src / "mav0"))
      if (e.path().filename() != "imu0")
        fs::create_directory_symlink(e.path(), dst / "mav0" / e.path().filename());
    fs::copy_file(src / "mav0" / "imu0" / "sensor.yaml", dst / "mav0" / "imu0" / "sensor.yaml");
    std::vector<io::ImuSample> imu = io::ReadImuCsv((src / "mav0" / "imu0" / "data.csv").string());
    for (io::ImuSample& m : imu) {
      const double s = (m.t_ns - t0) * 1e-9;
      if (s >= kGapStart && s < kGapEnd) m.accel_m_s2.x() += 0.8;
    }
    io::WriteImuCsv((dst / "mav0" / "imu0" / "data.csv").string(), imu);
  }
  NavRunSettings st = Settings("gap");
  NavRunSettings off = Settings("gap_noconfirm");
  st.dataset = off.dataset = dst.string();
  st.nav.start = off.nav.start = ReadSimTruth(st.dataset).value().Start();
  st.blank.emplace_back(kGapStart, kGapEnd - kGapStart);
  off.blank = st.blank;
  off.nav.confirm_after_gap_s = 0;
  const NavRunReport r = RunNav(st), o = RunNav(off);
  ASSERT_TRUE(r.error && o.error);
  const int64_t f0 = r.first_frame_ns;  // the blanking's reference
  const auto in_gap = [&](int64_t t) {
    const double s = (t - f0) * 1e-9;
    return s >= kGapStart && s < kGapEnd;
  };
  size_t found_in_gap = 0;
  for (const nav::FixLog& f : r.fixes)
    if (in_gap(f.t_ns) && f.found) ++found_in_gap;
  // The error at the gap's end, and how long after the first fix *found* after the gap (each
  // run's own; the confirmation waits for a second one) the error is first under 10 m (the
  // issue's recovery figure; -1: never).
  const auto figures = [&](const NavRunReport& x, double* gap_end, double* recovery_s) {
    std::optional<int64_t> back;
    for (const nav::FixLog& f : x.fixes)
      if (!back && f.found && (f.t_ns - f0) * 1e-9 >= kGapEnd) back = f.t_ns;
    *gap_end = 0;
    *recovery_s = -1;
    for (size_t k = 0; k < x.error_t_ns.size(); ++k) {
      if (in_gap(x.error_t_ns[k])) *gap_end = x.errors_m[k];
      if (back && *recovery_s < 0 && x.error_t_ns[k] >= *back && x.errors_m[k] < 10.0)
        *recovery_s = (x.error_t_ns[k] - *back) * 1e-9;
    }
  };
  double gap_end, recovery, gap_end_off, recovery_off;
  figures(r, &gap_end, &recovery);
  figures(o, &gap_end_off, &recovery_off);
  std::printf(
      "25 s of blank frames, accelerometer bias jump in the gap (flight %.0f s): %zu fixes found "
      "on them (0); error at the gap's end %.1f m (> 50); under 10 m %.1f s after the first fix "
      "found after it (<= 3), final %.1f m (< 10), %zu reset(s); without the post-gap "
      "confirmation: %.1f m at the gap's end, under 10 m after %.1f s, final %.1f m\n",
      r.duration_s, found_in_gap, gap_end, recovery, r.error->final_m, r.stats.resets, gap_end_off,
      recovery_off, o.error->final_m);
  EXPECT_EQ(found_in_gap, 0u);
  EXPECT_GT(gap_end, 50.0);  // the drift the test is about happened
  EXPECT_GE(recovery, 0.0);
  EXPECT_LE(recovery, 3.0);
  EXPECT_LT(r.error->final_m, 10.0);
}

// The test flight again, flown by a multirotor in wind (drag 0.1/s, wind 3 m/s east and 2 m/s
// south: `sim --drag --wind`), with 25 s of blank frames from 20 s on, from a true start. The IMU
// alone drifts through the gap; with the rotor-drag factor (NavOptions::drag_per_s, the drone's
// calibrated K) the accelerometer's drag gives the air velocity, and the wind learnt from the
// fixes before the gap turns it into the ground velocity: the gap's end must be at most half as
// far off (18.5 -> 7.9 m when written). The wind must be known first: the same gap from 8 s
// ended 11.6 m off with the drag against 7.5 m without.
TEST_F(NavRunTest, RotorDragCarriesAGap) {
  constexpr double kGapStart = 20, kGapEnd = 45;
  const fs::path dir = *dir_ / "flight_wind";
  if (!fs::exists(dir / "sim_complete.json")) {
    sim::SimulationOptions s;
    s.world.kind = sim::WorldKind::kOrtho;
    s.world.ortho_path = Naip("20170827");
    s.route = "drone:" + (*dir_ / "flight.txt").string();
    s.speed_m_s = 20;
    s.drag_per_s = 0.1;
    s.wind_m_s = {3, -2};
    s.scale = 0.1;
    s.seed = 7;
    s.out_dir = dir.string();
    s.nadir.enabled = true;
    s.baro.enabled = true;
    sim::RunSimulation(s);
  }
  const auto gap_end = [&](double drag_per_s) {
    NavRunSettings st = Settings(drag_per_s > 0 ? "wind_drag" : "wind_nodrag");
    st.dataset = dir.string();
    st.nav.start = ReadSimTruth(st.dataset).value().Start();
    st.nav.drag_per_s = drag_per_s;
    st.blank.emplace_back(kGapStart, kGapEnd - kGapStart);
    const NavRunReport r = RunNav(st);
    double end = -1;
    for (size_t k = 0; k < r.error_t_ns.size(); ++k)
      if ((r.error_t_ns[k] - r.first_frame_ns) * 1e-9 < kGapEnd) end = r.errors_m[k];
    return end;
  };
  const double without = gap_end(0.0), with = gap_end(0.1);
  std::printf(
      "25 s of blank frames in wind: gap's end %.1f m with the IMU alone, %.1f m with the "
      "rotor drag (at most half)\n",
      without, with);
  ASSERT_GT(without, 0.0);
  ASSERT_GT(with, 0.0);
  EXPECT_LT(with, 0.5 * without);
}

TEST_F(NavRunTest, BadInputIsNamed) {
  NavRunSettings st = Settings("bad");
  st.no_map = true;
  EXPECT_NE(st.Check().find("--start"), std::string::npos);
  st = Settings("bad");
  st.blank.emplace_back(-1, 10);
  EXPECT_NE(st.Check().find("--blank"), std::string::npos);
  // A dataset without a nadir camera.
  const fs::path empty = *dir_ / "no_cam2";
  fs::create_directories(empty / "mav0" / "imu0");
  fs::copy(fs::path(Settings("x").dataset) / "mav0" / "imu0", empty / "mav0" / "imu0",
           fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  st = Settings("bad");
  st.dataset = empty.string();
  try {
    RunNav(st);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cam2"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(st.out));
}

}  // namespace
}  // namespace optinav::app
