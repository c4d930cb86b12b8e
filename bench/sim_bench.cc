// Simulator rendering speed (issue 4): stereo pairs per second at the EuRoC-like drone rig's
// 752x480, urban world, along the car route, clear and with moderate weather. Uses every core
// (the renderer parallelises rows; the two cameras of a pair render concurrently). "CPU" is
// the process CPU time per pair over all threads: on N otherwise idle cores the rate is about
// N / CPU; "Time" is wall time, which on a shared machine includes waiting for the cores.
// Run: build/bench/sim_bench  (figures in bench/RESULTS.md)
#include <benchmark/benchmark.h>

#include "optinav/sim/renderer.h"
#include "optinav/sim/simulation.h"

namespace optinav::sim {
namespace {

struct UrbanScene {
  explicit UrbanScene(const WeatherSpec& weather) {
    WorldOptions o;
    o.weather = weather;
    world = MakeWorld(o);
    route.emplace(MakeCarTrajectory(CarRouteOptions::Urban(), world.ground_height, 0));
  }
  World world;
  std::optional<BodyTrajectory> route;
};

void RenderPairs(benchmark::State& state, const std::string& weather, double scale,
                 bool camera_noise = true) {
  const WeatherSpec spec = ParseWeather(weather);
  const UrbanScene scene(spec);
  const Renderer renderer(scene.world);
  // The drone rig's cameras (752x480) on the car, so the view is the urban street scene.
  SensorRig rig = DroneRig().Scaled(scale);
  rig.body_from_left = CarRig().body_from_left;
  rig.body_from_right = CarRig().body_from_right;
  int64_t t = 2'000'000'000;
  CameraNoiseOptions noise;
  noise.enabled = camera_noise;
  cv::Mat left, right;
  for (auto _ : state) {
    RenderStereo(renderer, rig, scene.route->At(t).world_from_body, t, spec, 1, noise, &left,
                 &right);
    benchmark::DoNotOptimize(left.data);
    t += 30'000'000;
    if (t > scene.route->end_ns()) t = 2'000'000'000;
  }
  state.SetItemsProcessed(state.iterations());  // items = stereo pairs
  state.counters["width"] = rig.left.width;
}

void BM_StereoUrbanClear(benchmark::State& s) { RenderPairs(s, "none", 1.0); }
// The same without the camera's noise (rendered before 2026-12-07): the noise model's cost.
void BM_StereoUrbanClearNoNoise(benchmark::State& s) { RenderPairs(s, "none", 1.0, false); }
void BM_StereoUrbanFog50(benchmark::State& s) { RenderPairs(s, "fog:50", 1.0); }
void BM_StereoUrbanRain50(benchmark::State& s) { RenderPairs(s, "rain:50", 1.0); }
void BM_StereoUrbanSnow50(benchmark::State& s) { RenderPairs(s, "snow:50", 1.0); }
void BM_StereoUrbanDust50(benchmark::State& s) { RenderPairs(s, "dust:50", 1.0); }
void BM_StereoUrbanSnow50Half(benchmark::State& s) { RenderPairs(s, "snow:50", 0.5); }
BENCHMARK(BM_StereoUrbanClear)->Unit(benchmark::kMillisecond)->MinTime(3)->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanClearNoNoise)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanFog50)->Unit(benchmark::kMillisecond)->MinTime(3)->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanRain50)->Unit(benchmark::kMillisecond)->MinTime(3)->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanSnow50)->Unit(benchmark::kMillisecond)->MinTime(3)->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanDust50)->Unit(benchmark::kMillisecond)->MinTime(3)->MeasureProcessCPUTime();
BENCHMARK(BM_StereoUrbanSnow50Half)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3)
    ->MeasureProcessCPUTime();

}  // namespace
}  // namespace optinav::sim

BENCHMARK_MAIN();
