// Map localization speed (issue: map-based localization), one core:
//  - BM_LocateWithPrior: 640x480 frame, prior -> 9 candidate tiles of up to 1024 ORB features,
//    frames cut from the map's own image (the document's setting); target median < 10 ms.
//  - BM_OrientationCorrelation: NAIP 2009 map, 256x256 frames from 2017 (appearance change),
//    prior within 250 m, heading known within +-10 deg; target median < 20 ms.
//  - BM_Perspective/*: issue 18's acceptance set: NAIP 2009 map (640 m, 90 deg, 256x256), true
//    perspective frames from 2012 and 2017 (maploc::MakePerspectiveFrames: pitch +-15, roll +-10,
//    altitude 0.8-1.25x, exposure, blur, noise, JPEG), given altitude +-10 %, attitude +-1 deg;
//    with prior and heading / prior only / global, and today's call (no altitude or attitude) on
//    the same frames. Targets: median <= 25 ms per 256x256 frame with a prior, <= 1 s global;
//    vehicle position within 25 m for >= 95 / 90 / 80 %. Each prints a summary line with them.
// Each benchmark iteration localizes a fixed, seeded set of frames and reports the median and
// per-stage medians as counters (ms; util/statistics.h: an even count gives the mean of the two
// middle values). Data: ../shared/data (or $OPTINAV_SHARED_DATA).
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bench_data.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/locator.h"
#include "optinav/sim/synthetic_ortho.h"
#include "optinav/util/statistics.h"
#include "optinav/util/timer.h"

namespace {

namespace fs = std::filesystem;
using namespace optinav;

using bench::SharedData;
using bench::WorkDir;

struct Medians {
  std::vector<double> total, extraction, matching, estimation;
  int localized = 0;
  void Add(const maploc::LocateResult& r) {
    total.push_back(r.times.total_ms);
    extraction.push_back(r.times.extraction_ms);
    matching.push_back(r.times.matching_ms);
    estimation.push_back(r.times.estimation_ms);
    localized += r.localized;
  }
  void Report(benchmark::State& state) const {
    state.counters["median_ms"] = Median(total);
    state.counters["extract_ms"] = Median(extraction);
    state.counters["match_ms"] = Median(matching);
    state.counters["estimate_ms"] = Median(estimation);
    state.counters["localized"] = localized;
    state.counters["frames"] = static_cast<double>(total.size());
  }
};

// NAIP 2009 upsampled 2x (2.5 m/px, 1868 x 1448) so that 640x480 frames at 2.5 m/px fill
// tiles with about 1024 ORB features each.
const maploc::MapDatabase& PriorMap(std::string* tif_out) {
  static std::string tif;
  static const maploc::MapDatabase db = [] {
    const geo::GeoRaster src =
        geo::GeoRaster::Open((SharedData() / "geo/naip/naip_20090818.tif").string());
    const cv::Mat gray =
        src.ReadGray(0, 0, src.width(), src.height(), 2 * src.width(), 2 * src.height());
    geo::GeoTransform gt = src.transform();
    gt.c[1] /= 2;
    gt.c[5] /= 2;
    tif = (WorkDir() / "naip2009_2x.tif").string();
    geo::WriteGeoTiff(tif, gray, gt, src.crs_wkt());
    maploc::MapBuildOptions o;
    o.frame_width = 640;
    o.frame_height = 480;
    o.hfov_deg = 60;
    o.altitude_m = 0.5 * 640 * 2.5 / std::tan(30 * M_PI / 180);
    return maploc::BuildMapDatabase(tif, o, (WorkDir() / "naip2009_2x.db").string());
  }();
  *tif_out = tif;
  return db;
}

void BM_LocateWithPrior(benchmark::State& state) {
  std::string tif;
  const maploc::MapDatabase& db = PriorMap(&tif);
  const geo::GeoRaster raster = geo::GeoRaster::Open(tif);
  maploc::LocateOptions lo;
  lo.max_candidate_tiles = 9;
  lo.frame_features = 600;
  lo.allow_orientation_correlation = false;
  maploc::Locator locator(db, lo);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<cv::Mat> frames;
  std::vector<maploc::Prior> priors;
  for (int i = 0; i < 40; ++i) {
    maploc::FrameSpec s;
    s.width = 640;
    s.height = 480;
    s.gsd_m = 2.5;
    s.heading_deg = 360 * u01(rng);
    s.centre_px = {420 + (db.width - 840) * u01(rng), 420 + (db.height - 840) * u01(rng)};
    frames.push_back(maploc::SynthesizeFrame(raster, db.map_gsd_m, s));
    maploc::Prior p;
    p.position = locator.PixelToLatLon(s.centre_px + Eigen::Vector2d(30 * u01(rng), 30 * u01(rng)));
    p.radius_m = 300;
    priors.push_back(p);
  }
  Medians m;
  size_t candidates = 0;
  for (auto _ : state) {
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto r = locator.LocateByFeatures(frames[i], priors[i]);
      m.Add(r);
      candidates += r.candidate_tiles.size();
    }
  }
  m.Report(state);
  state.counters["candidate_tiles"] = static_cast<double>(candidates) / m.total.size();
  state.counters["features_per_tile"] = static_cast<double>(db.FeatureCount()) / db.tiles.size();
}
BENCHMARK(BM_LocateWithPrior)->Unit(benchmark::kMillisecond)->Iterations(2);

// NAIP 2009 as the acceptance map: `map build --altitude 640 --hfov 90 --frame-size 256x256`.
const maploc::MapDatabase& Naip2009Map() {
  static const maploc::MapDatabase db = [] {
    maploc::MapBuildOptions o;
    o.frame_width = o.frame_height = 256;
    o.hfov_deg = 90;
    o.altitude_m = 640;
    return maploc::BuildMapDatabase((SharedData() / "geo/naip/naip_20090818.tif").string(), o,
                                    (WorkDir() / "naip2009.db").string());
  }();
  return db;
}

void BM_OrientationCorrelation(benchmark::State& state) {
  const maploc::MapDatabase& db = Naip2009Map();
  const geo::GeoRaster flight =
      geo::GeoRaster::Open((SharedData() / "geo/naip/naip_20170827.tif").string());
  maploc::Locator locator(db);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<cv::Mat> frames;
  std::vector<maploc::Prior> priors;
  std::vector<Eigen::Vector2d> truth;
  const geo::CrsTransform crs(db.crs_wkt);
  for (int i = 0; i < 30; ++i) {
    maploc::FrameSpec s;
    s.width = s.height = 256;
    s.gsd_m = 5;
    s.heading_deg = 360 * u01(rng);
    s.centre_px = {182 + (flight.width() - 364) * u01(rng),
                   182 + (flight.height() - 364) * u01(rng)};
    frames.push_back(maploc::SynthesizeFrame(flight, 5.0, s));
    const Eigen::Vector2d t = flight.transform().PixelToCrs(s.centre_px);
    truth.push_back(t);
    maploc::Prior p;
    p.position = crs.ToLatLon(t + Eigen::Vector2d(150 * (u01(rng) - 0.5), 150 * (u01(rng) - 0.5)));
    p.radius_m = 250;
    p.heading_deg = s.heading_deg + 16 * (u01(rng) - 0.5);
    p.heading_sigma_deg = 10;
    priors.push_back(p);
  }
  locator.LocateByOrientationCorrelation(frames[0], priors[0]);  // warm the map cache
  Medians m;
  std::vector<double> errors;
  for (auto _ : state) {
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto r = locator.LocateByOrientationCorrelation(frames[i], priors[i]);
      m.Add(r);
      if (r.localized) errors.push_back((r.crs_xy - truth[i]).norm());
    }
  }
  m.Report(state);
  state.counters["median_error_m"] = errors.empty() ? -1 : Median(errors);
}
BENCHMARK(BM_OrientationCorrelation)->Unit(benchmark::kMillisecond)->Iterations(2);

// Global search without a prior over 1 km^2 at 0.1 m/px (10,000 x 10,000 px, procedural):
// 640x480 frames at 0.18 m/px (100 m altitude, 60 deg FOV). Target median < 200 ms.
void BM_GlobalSearch(benchmark::State& state) {
  static std::string tif;
  static const maploc::MapDatabase db = [] {
    tif = (WorkDir() / "ortho_10k.tif").string();
    if (!fs::exists(tif)) sim::WriteSyntheticOrtho(tif, 10000, 0.1, 5);
    maploc::MapBuildOptions o;
    o.frame_width = 640;
    o.frame_height = 480;
    o.hfov_deg = 60;
    o.altitude_m = 100;
    return maploc::BuildMapDatabase(tif, o, (WorkDir() / "ortho_10k.db").string());
  }();
  const geo::GeoRaster raster = geo::GeoRaster::Open(tif);
  maploc::LocateOptions lo;
  lo.allow_orientation_correlation = false;
  maploc::Locator locator(db, lo);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<cv::Mat> frames;
  std::vector<Eigen::Vector2d> truth;
  const double gsd = 2 * 100 * std::tan(30 * M_PI / 180) / 640;
  for (int i = 0; i < 20; ++i) {
    maploc::FrameSpec s;
    s.width = 640;
    s.height = 480;
    s.gsd_m = gsd;
    s.heading_deg = 360 * u01(rng);
    s.centre_px = {800 + 8400 * u01(rng), 800 + 8400 * u01(rng)};
    frames.push_back(maploc::SynthesizeFrame(raster, db.map_gsd_m, s));
    truth.push_back(s.centre_px);
  }
  locator.LocateByFeatures(frames[0], {});  // builds the global index once
  Medians m;
  std::vector<double> errors;
  for (auto _ : state) {
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto r = locator.LocateByFeatures(frames[i], {});
      m.Add(r);
      if (r.localized) errors.push_back((r.map_px - truth[i]).norm() * db.map_gsd_m);
    }
  }
  m.Report(state);
  state.counters["tiles"] = static_cast<double>(db.tiles.size());
  state.counters["median_error_m"] = errors.empty() ? -1 : Median(errors);
}
BENCHMARK(BM_GlobalSearch)->Unit(benchmark::kMillisecond)->Iterations(1);

// What locate is given in each acceptance mode.
enum PerspectiveMode { kPriorHeading, kPriorOnly, kGlobal, kTodayPriorHeading };

const char* ModeName(int mode) {
  switch (mode) {
    case kPriorHeading:
      return "prior+heading";
    case kPriorOnly:
      return "prior only";
    case kGlobal:
      return "global (no prior, no heading)";
    default:
      return "today's call (prior+heading, no altitude/attitude)";
  }
}

maploc::Prior GivenPrior(const maploc::PerspectiveFrame& f, int mode) {
  maploc::Prior p;
  if (mode != kGlobal) {
    p.position = f.prior;
    p.radius_m = f.prior_radius_m;
  }
  if (mode == kPriorHeading || mode == kTodayPriorHeading) {
    p.heading_deg = f.given_heading_deg;
    p.heading_sigma_deg = f.heading_sigma_deg;
  }
  if (mode != kTodayPriorHeading) {
    p.altitude_m = f.given_altitude_m;
    p.roll_deg = f.given_roll_deg;
    p.pitch_deg = f.given_pitch_deg;
  }
  return p;
}

// Args: mode, frame width, frame height, frames per year (2012 and 2017).
void BM_Perspective(benchmark::State& state) {
  const int mode = static_cast<int>(state.range(0));
  const maploc::MapDatabase& db = Naip2009Map();
  maploc::PerspectiveFrameOptions fo;
  fo.width = static_cast<int>(state.range(1));
  fo.height = static_cast<int>(state.range(2));
  const int per_year = static_cast<int>(state.range(3));
  std::vector<maploc::PerspectiveFrame> frames;
  for (const auto& [year, seed] : {std::pair{"20120731", 1812}, std::pair{"20170827", 1817}}) {
    const geo::GeoRaster flight = geo::GeoRaster::Open(
        (SharedData() / "geo/naip" / ("naip_" + std::string(year) + ".tif")).string());
    for (maploc::PerspectiveFrame& f : maploc::MakePerspectiveFrames(flight, per_year, fo, seed)) {
      frames.push_back(std::move(f));
    }
  }
  maploc::Locator locator(db);
  locator.Locate(frames[0].image, GivenPrior(frames[0], mode));  // warm caches and indexes
  Medians m;
  std::vector<double> errors, alt_errors;
  int within = 0, within_2sigma = 0, with_sigma = 0;
  for (auto _ : state) {
    m = Medians();
    errors.clear();
    alt_errors.clear();
    within = within_2sigma = with_sigma = 0;
    for (const maploc::PerspectiveFrame& f : frames) {
      const maploc::LocateResult r = locator.Locate(f.image, GivenPrior(f, mode));
      m.Add(r);
      if (!r.localized) continue;
      const double e = geo::GeodesicInverse(r.latlon, f.latlon).distance_m;
      errors.push_back(e);
      within += e <= 25.0;
      if (r.altitude_m > 0) alt_errors.push_back(std::abs(r.altitude_m / f.pose.altitude_m - 1));
      if (r.position_sigma_m > 0) {
        ++with_sigma;
        within_2sigma += e <= 2 * r.position_sigma_m;
      }
    }
  }
  m.Report(state);
  const double n = static_cast<double>(frames.size());
  const bool prior = mode != kGlobal;
  const double target_pct = mode == kPriorOnly ? 90 : mode == kGlobal ? 80 : 95;
  state.counters["within_25m_pct"] = 100.0 * within / n;
  state.counters["median_error_m"] = errors.empty() ? -1 : Median(errors);
  state.counters["median_alt_err_pct"] = alt_errors.empty() ? -1 : 100 * Median(alt_errors);
  std::printf(
      "[perspective %dx%d, %s] %d frames (2012 + 2017): vehicle within 25 m %d (%.1f %%, target "
      ">= %.0f %%%s), median error %.1f m, median altitude error %.1f %% (target <= 5 %%), "
      "error <= 2 sigma %d/%d (target >= 90 %%), median %.1f ms per frame (target <= %s)\n",
      fo.width, fo.height, ModeName(mode), static_cast<int>(n), within, 100.0 * within / n,
      target_pct, mode == kTodayPriorHeading ? ", for the new call" : "",
      errors.empty() ? -1.0 : Median(errors), alt_errors.empty() ? -1.0 : 100 * Median(alt_errors),
      within_2sigma, with_sigma, Median(m.total), prior ? "25 ms" : "1000 ms");
}
BENCHMARK(BM_Perspective)
    ->Args({kPriorHeading, 256, 256, 25})
    ->Args({kTodayPriorHeading, 256, 256, 25})
    ->Args({kPriorOnly, 256, 256, 25})
    ->Args({kGlobal, 256, 256, 10})
    ->Args({kPriorHeading, 640, 480, 10})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// Issue 24: the methods side by side on BM_Perspective's 256x256 frames (same seeds, same
// metadata): features alone on an ORB, a SIFT and an XFeat map of NAIP 2009 (same tiling),
// orientation correlation alone, and `auto` (Locator::Locate: features first, then correlation)
// on the ORB map and on the XFeat map. Args: method, mode, frames per year, OpenCV threads (for
// the XFeat forward pass; run under `taskset -c 0` for one core).
enum Method { kOrb, kSift, kXFeat, kCorrelation, kAutoOrb, kAutoXFeat };

const char* MethodName(int method) {
  static const char* const names[] = {"ORB features",   "SIFT features",
                                      "XFeat features", "orientation correlation",
                                      "auto (ORB map)", "auto (XFeat map)"};
  return names[method];
}

const maploc::MapDatabase& NaipMap(features::FeatureType type) {
  static std::map<features::FeatureType, maploc::MapDatabase> maps;
  auto it = maps.find(type);
  if (it == maps.end()) {
    maploc::MapBuildOptions o;
    o.frame_width = o.frame_height = 256;
    o.hfov_deg = 90;
    o.altitude_m = 640;
    o.feature_type = type;
    const std::string name = "naip2009_" + features::FeatureTypeName(type) + ".db";
    it = maps.emplace(type, maploc::BuildMapDatabase(
                                (SharedData() / "geo/naip/naip_20090818.tif").string(), o,
                                (WorkDir() / name).string()))
             .first;
  }
  return it->second;
}

void BM_PerspectiveMethods(benchmark::State& state) {
  const int method = static_cast<int>(state.range(0));
  const int mode = static_cast<int>(state.range(1));
  const int per_year = static_cast<int>(state.range(2));
  const int threads = static_cast<int>(state.range(3));
  cv::setNumThreads(threads);
  const features::FeatureType type = method == kSift ? features::FeatureType::kSift
                                     : method == kXFeat || method == kAutoXFeat
                                         ? features::FeatureType::kXFeat
                                         : features::FeatureType::kOrb;
  const maploc::MapDatabase& db = NaipMap(type);
  maploc::PerspectiveFrameOptions fo;
  fo.width = fo.height = 256;
  std::vector<maploc::PerspectiveFrame> frames;
  for (const auto& [year, seed] : {std::pair{"20120731", 1812}, std::pair{"20170827", 1817}}) {
    const geo::GeoRaster flight = geo::GeoRaster::Open(
        (SharedData() / "geo/naip" / ("naip_" + std::string(year) + ".tif")).string());
    for (maploc::PerspectiveFrame& f : maploc::MakePerspectiveFrames(flight, per_year, fo, seed))
      frames.push_back(std::move(f));
  }
  maploc::Locator locator(db);
  auto locate = [&](const maploc::PerspectiveFrame& f) {
    const maploc::Prior p = GivenPrior(f, mode);
    switch (method) {
      case kOrb:
      case kSift:
      case kXFeat:
        return locator.LocateByFeatures(f.image, p);
      case kCorrelation:
        return locator.LocateByOrientationCorrelation(f.image, p);
      default:
        return locator.Locate(f.image, p);
    }
  };
  locate(frames[0]);  // warm caches, indexes and the network
  Medians m;
  std::vector<double> errors;
  int within = 0;
  std::map<std::string, int> by;
  for (auto _ : state) {
    for (const maploc::PerspectiveFrame& f : frames) {
      const maploc::LocateResult r = locate(f);
      m.Add(r);
      if (!r.localized) continue;
      ++by[r.method];
      const double e = geo::GeodesicInverse(r.latlon, f.latlon).distance_m;
      errors.push_back(e);
      within += e <= 25.0;
    }
  }
  m.Report(state);
  const double n = static_cast<double>(frames.size());
  state.counters["within_25m_pct"] = 100.0 * within / n;
  state.counters["median_error_m"] = errors.empty() ? -1 : Median(errors);
  std::printf(
      "[methods, %s, %s, %d thread(s)] %d frames: within 25 m %d (%.1f %%), median error %.1f m, "
      "localized %zu (features %d, correlation %d), median %.1f ms per frame (extraction %.1f)\n",
      MethodName(method), ModeName(mode), threads, static_cast<int>(n), within, 100.0 * within / n,
      errors.empty() ? -1.0 : Median(errors), errors.size(), by["features"],
      by["orientation-correlation"], Median(m.total), Median(m.extraction));
}
BENCHMARK(BM_PerspectiveMethods)
    ->ArgsProduct({{kOrb, kSift, kXFeat, kCorrelation, kAutoOrb, kAutoXFeat},
                   {kPriorHeading, kPriorOnly},
                   {25},
                   {1}})
    ->ArgsProduct({{kOrb, kSift, kXFeat, kCorrelation, kAutoOrb, kAutoXFeat}, {kGlobal}, {10}, {1}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// The XFeat forward pass alone (640x640 input), with 1 and 2 OpenCV threads.
void BM_XFeatForward(benchmark::State& state) {
  cv::setNumThreads(static_cast<int>(state.range(0)));
  const auto ex = features::CreateFeatureExtractor({.type = features::FeatureType::kXFeat});
  const cv::Mat img =
      cv::imread((SharedData() / "images/graf1.png").string(), cv::IMREAD_GRAYSCALE);
  ex->Extract(img);  // first pass allocates
  std::vector<double> ms;
  for (auto _ : state) {
    Timer t;
    benchmark::DoNotOptimize(ex->Extract(img));
    ms.push_back(t.ElapsedSeconds() * 1e3);
  }
  state.counters["median_ms"] = Median(ms);
}
BENCHMARK(BM_XFeatForward)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(10);

}  // namespace

BENCHMARK_MAIN();
