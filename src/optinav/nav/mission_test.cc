#include "optinav/nav/mission.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/test_maps.h"
#include "optinav/util/statistics.h"
#include "optinav/util/testing.h"

namespace optinav::nav {
namespace {

TEST(FrameEffects, AltitudeProfileStaysInItsBand) {
  const AltitudeProfile p(0.1, 5);
  double lo = 2, hi = 0;
  for (double t = 0; t < 2000; t += 0.5) {
    lo = std::min(lo, p.Factor(t));
    hi = std::max(hi, p.Factor(t));
  }
  EXPECT_GE(lo, 0.9 - 1e-12);
  EXPECT_LE(hi, 1.1 + 1e-12);
  EXPECT_GT(hi - lo, 0.05);  // it does vary
  EXPECT_DOUBLE_EQ(AltitudeProfile(0.0, 5).Factor(123.0), 1.0);
}

TEST(FrameEffects, BlurAndExposureChangeTheFrameDeterministically) {
  cv::Mat base(128, 128, CV_8U);
  cv::randu(base, 0, 255);
  cv::GaussianBlur(base, base, cv::Size(0, 0), 1.0);
  auto sharpness = [](const cv::Mat& g) {
    cv::Mat lap;
    cv::Laplacian(g, lap, CV_32F);
    return cv::norm(lap);
  };
  FrameEffectOptions o;
  o.motion_blur_px = 12;
  o.exposure_variation = 0;
  o.noise_sigma = 0;
  cv::Mat a = base.clone(), b = base.clone();
  std::mt19937_64 r1(3), r2(3);
  ApplyPhotometricEffects(a, o, 0.3, r1);
  ApplyPhotometricEffects(b, o, 0.3, r2);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);  // same seed, same frame
  EXPECT_LT(sharpness(a), 0.8 * sharpness(base));
  o.motion_blur_px = 0;
  o.exposure_variation = 0.5;
  cv::Mat c = base.clone();
  std::mt19937_64 r3(4);
  ApplyPhotometricEffects(c, o, 0, r3);
  EXPECT_GT(std::abs(cv::mean(c)[0] - cv::mean(base)[0]), 1.0);
  o.max_tilt_deg = 40;
  EXPECT_NE(o.Check().find("tilt"), std::string::npos);
}

// The NAIP 2009 orthophoto as the map; frames from 2009 or 2017 (real appearance change).
class NaipMission : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(testing::MakeTempDir("mission"));
    maploc::MapBuildOptions o;
    o.frame_width = o.frame_height = 256;
    o.hfov_deg = 90;
    o.altitude_m = 640;  // footprint 1280 m: a fixed-wing altitude over 5 m pixels
    db_ = new maploc::MapDatabase(maploc::BuildMapDatabase(maploc::testmaps::Naip("20090818"), o,
                                                           (*dir_ / "naip2009.db").string()));
  }
  static void TearDownTestSuite() {
    delete db_;
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }
  static std::filesystem::path* dir_;
  static maploc::MapDatabase* db_;
};
std::filesystem::path* NaipMission::dir_ = nullptr;
maploc::MapDatabase* NaipMission::db_ = nullptr;

TEST_F(NaipMission, OdometryRecoversFrameMotion) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(maploc::testmaps::Naip("20090818"));
  maploc::FrameSpec a;
  a.width = a.height = 256;
  a.gsd_m = 5.0;
  a.centre_px = {400, 350};
  a.heading_deg = 30;
  maploc::FrameSpec b = a;
  // Move 12 map px along the frame's up direction and turn 4 degrees.
  const double h = 30 * M_PI / 180;
  b.centre_px += 12.0 * Eigen::Vector2d(std::sin(h), -std::cos(h));
  b.heading_deg = 34;
  FrameOdometry odo;
  EXPECT_FALSE(odo.Track(maploc::SynthesizeFrame(raster, 5.0, a)).ok);
  const OdometryStep s = odo.Track(maploc::SynthesizeFrame(raster, 5.0, b));
  ASSERT_TRUE(s.ok) << s.reason;
  const LocalSimilarity sim = SimilarityAt(s.prev_from_cur, {128, 128});
  std::printf("odometry: translation (%.2f, %.2f) px (truth (0, -12)), rotation %.2f deg (4)\n",
              sim.translation_px.x, sim.translation_px.y, sim.rotation_rad * 180 / M_PI);
  EXPECT_NEAR(sim.translation_px.x, 0.0, 0.5);
  EXPECT_NEAR(sim.translation_px.y, -12.0, 0.5);
  EXPECT_NEAR(sim.rotation_rad * 180 / M_PI, 4.0, 0.3);
  EXPECT_NEAR(sim.scale, 1.0, 0.01);
}

TEST_F(NaipMission, BadMissionsAreRefusedBeforeTheyStart) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(maploc::testmaps::Naip("20090818"));
  Mission mission(*db_, raster);
  const auto [start, target] = RandomStartTarget(*db_, 3000, 300, 1);
  MissionOptions o;
  o.start = start;
  o.target = target;
  EXPECT_EQ(mission.Check(o), "");
  auto expect = [&](MissionOptions bad, const std::string& needle) {
    const std::string e = mission.Check(bad);
    EXPECT_NE(e.find(needle), std::string::npos) << "got: " << e;
    EXPECT_ERROR(mission.Run(bad), {}, needle);  // Run refuses with Check's message
  };
  MissionOptions b = o;
  b.target = {0.0, 0.0};
  expect(b, "target 0.000000,0.000000 is outside the map");
  b = o;
  b.target = b.start;
  expect(b, "within the arrival radius");
  b = o;
  b.speed_m_s = -3;
  expect(b, "speed");
  b = o;
  b.altitude_m = 5000;
  expect(b, "altitude 5000 m is out of range");
  b = o;
  b.speed_m_s = 140;
  b.step_s = 5;
  expect(b, "would not overlap");
  b = o;
  b.attitude_noise_deg = 20;
  expect(b, "attitude noise must be in [0, 10] deg");
  // --estimator nav: its own camera, rate and options.
  b = o;
  b.estimator = "ekf";
  expect(b, "estimator must be 2d or nav, got 'ekf'");
  o.estimator = "nav";
  EXPECT_EQ(mission.Check(o), "");
  b = o;
  b.effects.max_tilt_deg = 20;
  expect(b, "horizon in the nadir frame");
  b = o;
  b.speed_m_s = 140;
  b.nadir.rate_hz = 1;
  b.nadir.hfov_deg = 30;
  expect(b, "raise --nadir-rate");
  b = o;
  b.nav.fix_rate_hz = -1;
  expect(b, "nav: fix_rate_hz");
  EXPECT_ERROR(RandomStartTarget(*db_, 50000, 300, 1), {},
               "no start/target pair 50000 m apart fits inside the map with a 300 m margin");
}

// The frames are taken with the flight's attitude: banked in turns, gusts within --tilt.
TEST_F(NaipMission, FramesCarryTheFlightsAttitude) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(maploc::testmaps::Naip("20090818"));
  Mission mission(*db_, raster);
  const auto [start, target] = RandomStartTarget(*db_, 2000, 300, 3);
  MissionOptions o;
  o.start = start;
  o.target = target;
  o.speed_m_s = 40;
  o.step_s = 2;
  o.seed = 3;
  o.effects.max_tilt_deg = 0;
  const MissionResult level = mission.Run(o);
  double max_roll = 0, max_pitch = 0;
  for (const StepLog& s : level.steps) {
    max_roll = std::max(max_roll, std::abs(s.roll_deg));
    max_pitch = std::max(max_pitch, std::abs(s.pitch_deg));
  }
  std::printf("no gusts: max |roll| %.2f deg (banks in turns), max |pitch| %.2f deg\n", max_roll,
              max_pitch);
  EXPECT_TRUE(level.reached);
  EXPECT_EQ(max_pitch, 0.0);
  EXPECT_GT(max_roll, 0.1);   // the heading corrections are flown as banked turns
  EXPECT_LE(max_roll, 20.0);  // max_bank_deg
  o.effects.max_tilt_deg = 5;
  const MissionResult gusty = mission.Run(o);
  max_pitch = 0;
  for (const StepLog& s : gusty.steps) max_pitch = std::max(max_pitch, std::abs(s.pitch_deg));
  EXPECT_TRUE(gusty.reached);
  EXPECT_GT(max_pitch, 2.5);
  EXPECT_LE(max_pitch, 5.0);
}

// `--estimator nav`: the map-aided navigator (IMU + barometer + 640x480 nadir frames at 5 Hz +
// map fixes) flies the closed loop over the outdated map, with wind and gusts. The issue's
// acceptance (30/30 legs >= 3 km within 20 m) is `optinav mission --estimator nav --runs 30`
// (bench/RESULTS.md); here two legs, for CI time (one in the sanitizer build, about 5x slower:
// the second repeats the first's code).
TEST_F(NaipMission, MapAidedNavigatorFliesTheClosedLoop) {
  const geo::GeoRaster frames = geo::GeoRaster::Open(maploc::testmaps::Naip("20170827"));
  Mission mission(*db_, frames);
#ifdef OPTINAV_SANITIZE
  const std::vector<uint64_t> seeds = {11};
#else
  const std::vector<uint64_t> seeds = {11, 12};
#endif
  for (uint64_t seed : seeds) {
    const auto [start, target] = RandomStartTarget(*db_, 2000, 300, seed);
    MissionOptions o;
    o.start = start;
    o.target = target;
    o.seed = seed;
    o.estimator = "nav";
    o.speed_m_s = 25;
    o.wind_m_s = 5;
    o.effects.max_tilt_deg = 5;
    o.success_radius_m = 20;
    const MissionResult r = mission.Run(o);
    std::vector<double> errors;
    int fixes = 0, accepted = 0;
    double max_roll = 0;
    for (const StepLog& l : r.steps) {
      errors.push_back(l.estimate_error_m);
      fixes += l.fix_found;
      accepted += l.fix_accepted;
      max_roll = std::max(max_roll, std::abs(l.roll_deg));
    }
    std::printf(
        "nav leg %.0f m (seed %llu): %s, final distance %.1f m (threshold 20 m), estimate error "
        "median %.1f m (threshold 8 m) max %.1f m (threshold 30 m), fixes %d found / %d accepted "
        "of %zu steps, "
        "max |roll| %.1f deg, flown %.0f m in %.0f s\n",
        r.straight_distance_m, static_cast<unsigned long long>(seed), r.end_reason.c_str(),
        r.final_distance_m, Median(errors), *std::max_element(errors.begin(), errors.end()), fixes,
        accepted, r.steps.size(), max_roll, r.flown_m, r.duration_s);
    if (std::getenv("OPTINAV_DEBUG_MISSION") != nullptr) {
      for (const StepLog& l : r.steps)
        std::printf("    t %.1f err %.1f sigma %.1f fix %d/%d err %.1f roll %.1f %s %s\n", l.t_s,
                    l.estimate_error_m, l.estimate_sigma_m, l.fix_found, l.fix_accepted,
                    l.fix_error_m, l.roll_deg, l.fix_method.c_str(), l.fix_reason.c_str());
    }
    EXPECT_TRUE(r.reached);
    EXPECT_EQ(r.end_reason, "arrived");
    EXPECT_LT(Median(errors), 8.0);
    // The largest errors come in the first seconds, over fields where only orientation
    // correlation finds fixes, before the window has learnt the tilt and the wind.
    EXPECT_LT(*std::max_element(errors.begin(), errors.end()), 30.0);
    EXPECT_GT(accepted, static_cast<int>(0.8 * r.steps.size()));
    EXPECT_GT(max_roll, 3.0);  // gusts and turns tilt the frames
    EXPECT_LT(r.flown_m, 1.15 * r.straight_distance_m);
  }
}

struct Experiment {
  int runs = 0, reached = 0;
  std::vector<double> fix_errors, final_distances;
  int steps = 0, fixes = 0, rejected = 0;
  int wrong_found = 0, wrong_accepted = 0;  // fixes more than 100 m from the truth
};

// Seeded missions between random points >= 3 km apart (300 m from the map edge), 40 m/s with a
// frame every 2 s (80 m), the map's fixed-wing altitude (footprint 1280 m).
Experiment RunMany(const maploc::MapDatabase& db, const std::string& frames_path, int runs,
                   uint64_t seed, const std::function<void(MissionOptions&)>& tweak = {}) {
  const geo::GeoRaster frames = geo::GeoRaster::Open(frames_path);
  Mission mission(db, frames);
  Experiment e;
  for (int i = 0; i < runs; ++i) {
    const auto [start, target] = RandomStartTarget(db, 3000, 300, seed + 1000 * i);
    MissionOptions o;
    o.start = start;
    o.target = target;
    o.speed_m_s = 40;
    o.step_s = 2;
    o.seed = seed + i;
    if (tweak) tweak(o);
    const MissionResult r = mission.Run(o);
    ++e.runs;
    e.reached += r.reached;
    e.final_distances.push_back(r.final_distance_m);
    for (const StepLog& s : r.steps) {
      ++e.steps;
      e.rejected += s.fix_found && !s.fix_accepted;
      e.wrong_found += s.fix_found && s.fix_error_m > 100;
      e.wrong_accepted += s.fix_accepted && s.fix_error_m > 100;
      if (s.fix_accepted && s.fix_error_m > 100) {
        std::printf("  run %d step %d: accepted a fix %.0f m off (%s; estimate sigma %.1f m)\n", i,
                    s.step, s.fix_error_m, s.fix_reason.c_str(), s.estimate_sigma_m);
      }
      if (s.fix_found) {
        ++e.fixes;
        e.fix_errors.push_back(s.fix_error_m);
      }
    }
    // OPTINAV_DEBUG_MISSION=1 prints every step of every run (for diagnosing a threshold miss).
    const bool debug = std::getenv("OPTINAV_DEBUG_MISSION") != nullptr;
    if (!r.reached || debug) {
      std::printf("  run %d %s: %s, final distance %.1f m, %zu steps\n", i,
                  r.reached ? "reached" : "missed", r.end_reason.c_str(), r.final_distance_m,
                  r.steps.size());
    }
    if (debug) {
      for (const StepLog& s : r.steps) {
        std::printf("    step %d fix %d/%d %s err %.1f est err %.1f sigma %.1f odo %d glob %d %s\n",
                    s.step, s.fix_found, s.fix_accepted, s.fix_method.c_str(), s.fix_error_m,
                    s.estimate_error_m, s.estimate_sigma_m, s.odometry_ok, s.global_search,
                    s.fix_reason.c_str());
      }
    }
  }
  return e;
}

void Print(const char* what, const Experiment& e, const char* threshold) {
  std::printf(
      "%s: %d/%d reached within 50 m (threshold %s); median fix error %.2f m (threshold 10 m = 2 "
      "map px); fixes found in %d/%d steps, %d rejected; median final distance %.1f m\n",
      what, e.reached, e.runs, threshold, Median(e.fix_errors), e.fixes, e.steps, e.rejected,
      Median(e.final_distances));
}

// The sanitizer build (about 5x slower) flies the first 10 of the 30 seeded runs: the same code,
// and a subset of runs that all must reach as in the whole set (at most one miss of the 2017 set).
#ifdef OPTINAV_SANITIZE
constexpr int kRuns = 10;
#else
constexpr int kRuns = 30;
#endif

TEST_F(NaipMission, ThirtyRunsWithFramesFromTheMapImage) {
  const Experiment e = RunMany(*db_, maploc::testmaps::Naip("20090818"), kRuns, 100,
                               [](MissionOptions& o) { o.wind_m_s = 3; });
  Print("frames 2009 (map 2009), 3 m/s wind", e, "all");
  EXPECT_EQ(e.reached, kRuns);
  EXPECT_LT(Median(e.fix_errors), 10.0);
}

TEST_F(NaipMission, ThirtyRunsOverAnOutdatedMap) {
  const Experiment e = RunMany(*db_, maploc::testmaps::Naip("20170827"), kRuns, 200);
  Print("frames 2017 (map 2009)", e, "all but one");
  EXPECT_GE(e.reached, kRuns - 1);
  EXPECT_LT(Median(e.fix_errors), 10.0);
}

// The outdated map under the simulator's weather at 50 %: haze by depth (scaled to the altitude)
// and particles, seeded per run.
void ExpectThirtyRunsInWeather(const maploc::MapDatabase& db, const std::string& weather,
                               uint64_t seed) {
  const Experiment e =
      RunMany(db, maploc::testmaps::Naip("20170827"), 30, seed, [&](MissionOptions& o) {
        sim::WeatherSpec w = sim::ParseWeather(weather);
        w.distance_scale = 0;  // altitude / 50
        o.weather = MakeWeatherHook(w, o.seed);
      });
  Print(("frames 2017 (map 2009), " + weather).c_str(), e, ">= 28/30");
  EXPECT_GE(e.reached, 28);
  EXPECT_LT(Median(e.fix_errors), 10.0);
}

TEST_F(NaipMission, WeatherThirtyRunsOverAnOutdatedMapInFog) {
  ExpectThirtyRunsInWeather(*db_, "fog:50", 500);
}

TEST_F(NaipMission, WeatherThirtyRunsOverAnOutdatedMapInDust) {
  ExpectThirtyRunsInWeather(*db_, "dust:50", 600);
}

// The hook darkens contrast with the intensity and leaves a clear frame alone.
TEST_F(NaipMission, WeatherHookLowersContrastMonotonically) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(maploc::testmaps::Naip("20090818"));
  maploc::FrameSpec s;
  s.width = s.height = 256;
  s.gsd_m = 5.0;
  s.centre_px = {450, 360};
  const cv::Mat clear = maploc::SynthesizeFrame(raster, 5.0, s);
  FrameView v;
  v.position_enu = {0, 0, 640};
  v.focal_px = 128;
  v.width = v.height = 256;
  EXPECT_FALSE(MakeWeatherHook(sim::ParseWeather("fog:0"), 1));
  double last = 1e9;
  for (const char* w : {"fog:25", "fog:50", "fog:75", "fog:100"}) {
    sim::WeatherSpec spec = sim::ParseWeather(w);
    spec.distance_scale = 0;
    cv::Mat g = clear.clone();
    MakeWeatherHook(spec, 3)(g, v);
    cv::Scalar mean, sd;
    cv::meanStdDev(g, mean, sd);
    std::printf("%s: contrast (std of grey) %.1f\n", w, sd[0]);
    EXPECT_LT(sd[0], last) << w;
    last = sd[0];
  }
}

TEST_F(NaipMission, TheThesisLoopWithoutOdometryStillWorksOnTheMapImage) {
  const Experiment e = RunMany(*db_, maploc::testmaps::Naip("20090818"), 5, 300,
                               [](MissionOptions& o) { o.use_odometry = false; });
  Print("frames 2009, no odometry (the thesis loop)", e, "5/5");
  EXPECT_EQ(e.reached, 5);
}

// Every 7th frame shows a place 1.5 km away (a wrong-but-confident fix, as a repeated pattern or
// a spoofed camera feed would give): the filter must reject those fixes and still arrive.
TEST_F(NaipMission, WrongFixesAreRejected) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(maploc::testmaps::Naip("20090818"));
  int injected = 0;
  const Experiment e =
      RunMany(*db_, maploc::testmaps::Naip("20090818"), 5, 400, [&](MissionOptions& o) {
        o.weather = [&](cv::Mat& gray, const FrameView& v) {
          if (v.t_ns == 0 || (v.t_ns / 2'000'000'000) % 7 != 3) return;
          maploc::FrameSpec s;
          s.width = gray.cols;
          s.height = gray.rows;
          s.gsd_m = 5.0;
          s.heading_deg = v.heading_deg;
          // The truth's pixel, shifted 300 px (1.5 km) towards the map centre.
          const Eigen::Vector2d here(raster.width() / 2.0 + v.position_enu.x() / 5.0,
                                     raster.height() / 2.0);
          s.centre_px = {raster.width() / 2.0 + (here.x() > raster.width() / 2.0 ? -150 : 150),
                         raster.height() / 2.0 + 120};
          gray = maploc::SynthesizeFrame(raster, 5.0, s);
          ++injected;
        };
      });
  Print("frames 2009 with every 7th frame from elsewhere", e, "5/5, all injected rejected");
  std::printf(
      "injected %d frames from elsewhere: %d fixes more than 100 m off, %d of them accepted "
      "(threshold 0); %d fixes rejected in all\n",
      injected, e.wrong_found, e.wrong_accepted, e.rejected);
  EXPECT_EQ(e.reached, 5);
  EXPECT_GT(e.wrong_found, 10);
  EXPECT_EQ(e.wrong_accepted, 0);
  EXPECT_LT(Median(e.fix_errors), 10.0);
}

}  // namespace
}  // namespace optinav::nav
