// Navigation speed of GNSS-denied missions (issue: mission), on the real NAIP imagery: map built
// from 2009 at a fixed-wing altitude (640 m, 256x256 frames, 90 deg FOV, footprint 1280 m), five
// seeded missions of >= 3 km at 30 m/s with a frame every second. Each benchmark reports the
// document's timing rows per step (feature extraction, matching, position estimation) and the
// whole navigation step (fix + odometry + filter + guidance; frame synthesis is simulation and
// excluded) as mean and std in ms, and the navigation steps per second.
// Target: >= 30 steps/s on one core (run pinned: taskset -c 0 build/bench/mission_bench).
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numeric>

#include <benchmark/benchmark.h>

#include "bench_data.h"
#include "optinav/nav/mission.h"

namespace {

namespace fs = std::filesystem;
using namespace optinav;

std::string Naip(const std::string& year) {
  return (bench::SharedData() / "geo" / "naip" / ("naip_" + year + ".tif")).string();
}

const maploc::MapDatabase& Map() {
  static const maploc::MapDatabase db = [] {
    const fs::path dir = bench::WorkDir();
    maploc::MapBuildOptions o;
    o.frame_width = o.frame_height = 256;
    o.hfov_deg = 90;
    o.altitude_m = 640;
    return maploc::BuildMapDatabase(Naip("20090818"), o, (dir / "naip2009_640.db").string());
  }();
  return db;
}

struct Row {
  std::vector<double> v;
  void Report(benchmark::State& state, const std::string& name) const {
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / v.size();
    double ss = 0;
    for (double x : v) ss += (x - mean) * (x - mean);
    state.counters[name + "_ms"] = mean;
    state.counters[name + "_std"] = std::sqrt(ss / std::max<size_t>(1, v.size() - 1));
  }
};

void RunMissions(benchmark::State& state, const std::string& year, const std::string& weather) {
  const geo::GeoRaster frames = geo::GeoRaster::Open(Naip(year));
  nav::Mission mission(Map(), frames);
  Row extraction, matching, estimation, odometry, navigation;
  int reached = 0, runs = 0;
  for (auto _ : state) {
    for (int i = 0; i < 5; ++i) {
      const auto [start, target] = nav::RandomStartTarget(Map(), 3000, 300, 77 + 1000 * i);
      nav::MissionOptions o;
      o.start = start;
      o.target = target;
      o.seed = 77 + i;
      if (!weather.empty()) {
        sim::WeatherSpec w = sim::ParseWeather(weather);
        w.distance_scale = 0;
        o.weather = nav::MakeWeatherHook(w, o.seed);
      }
      const nav::MissionResult r = mission.Run(o);
      ++runs;
      reached += r.reached;
      for (const nav::StepLog& s : r.steps) {
        extraction.v.push_back(s.times.extraction_ms);
        matching.v.push_back(s.times.matching_ms);
        estimation.v.push_back(s.times.estimation_ms);
        odometry.v.push_back(s.times.odometry_ms);
        navigation.v.push_back(s.times.navigation_ms);
      }
    }
  }
  extraction.Report(state, "extraction");
  matching.Report(state, "matching");
  estimation.Report(state, "estimation");
  odometry.Report(state, "odometry");
  navigation.Report(state, "nav_step");
  state.counters["steps_per_s"] = 1000.0 / state.counters["nav_step_ms"];
  state.counters["steps"] = static_cast<double>(navigation.v.size());
  state.counters["reached"] = reached;
  state.counters["runs"] = runs;
}

void BM_MissionFrames2009(benchmark::State& state) { RunMissions(state, "20090818", ""); }
void BM_MissionFrames2017(benchmark::State& state) { RunMissions(state, "20170827", ""); }
void BM_MissionFrames2017Fog50(benchmark::State& state) {
  RunMissions(state, "20170827", "fog:50");
}
BENCHMARK(BM_MissionFrames2009)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_MissionFrames2017)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_MissionFrames2017Fog50)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
