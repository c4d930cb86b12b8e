// VIO speed (issue 5), one core, 752x480 stereo at 20 Hz + 200 Hz IMU (EuRoC V1_01_micro, real):
//  - BM_VioEurocMicro: the whole estimator (frontend + backend, sequential) over the clip's
//    95 stereo frames per iteration, images decoded beforehand. Counters: per-module median and
//    p95 per frame (ms). Target: total median < 15 ms, p95 < 40 ms per frame (backend amortised
//    over frames: it solves every frame, marginalises at keyframes).
//  - BM_FrontendOnly: the frontend alone over the same frames.
//  - BM_GnssSmoother/N: SmoothGnssAlignment over N frames at 20 Hz (a 5 m/s circle) with a GNSS
//    sample (3 m noise) every 4th frame: the one-off cost after a run with GNSS (N = 4000: the
//    1 km flight of `optinav bench gnss`).
//  - BM_VioCar800/<weather>/<mode>/<frontend> (issue 19): the whole estimator, sequential, one
//    OpenCV thread, on the first 15 s (501 stereo frames, 800x600: the weather document's camera)
//    of the simulated urban car route (seed 1, as `bench weather`), rendered once into a temporary
//    folder before timing. Weather none / fog:100 / dust:100; mode stereo (the document's) or
//    stereo-imu; frontend "now" (the defaults) or "filed" (as when issue 19 was filed: no
//    low-contrast CLAHE, no trackability check of new corners, no ground-vehicle defaults),
//    side by side in the same run. "now" in stereo-imu applies the ground vehicle's defaults
//    (app::ApplyGroundVehicleDefaults: what `optinav vio` and `bench weather` run on car routes).
//    Rendered with the cameras' noise since 2026-12-07 (the simulator's default). Since then
//    "filed" also has plain KLT and no corner noise floor (stereo-only defaults added later);
//    "<weather>_stereo_nofloor" is "now" without the floor (its cost).
//    Target: total per frame median <= 20 ms, p95 <= 50 ms on one core (run under `taskset -c 0`).
// Data: ../shared/data (or $OPTINAV_SHARED_DATA); the car frames are generated.
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "optinav/app/vio_run.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/sim/simulation.h"
#include "optinav/sim/weather.h"
#include "optinav/vio/estimator.h"
#include "optinav/vio/gnss_smoother.h"
#include "optinav/vio/internal/frontend.h"
#include "optinav/vio/pipeline.h"

namespace {

namespace fs = std::filesystem;
using namespace optinav;

struct Clip {
  io::EurocDataset ds;
  camera::StereoRig rig;
  vio::ImuNoise noise;  // from imu0/sensor.yaml
  std::vector<vio::TimedImuSample> imu;
  std::vector<int64_t> t_ns;
  std::vector<cv::Mat> left, right;
};

// Every stereo pair of a EuRoC-layout folder, decoded, with the IMU samples.
Clip ReadClip(const fs::path& dir) {
  Clip c;
  io::EurocOpenOptions open;
  open.drop_missing_images = true;
  c.ds = io::OpenEurocDataset(dir.string(), open);
  c.rig = io::ToStereoRig(c.ds.cam0->calibration, c.ds.cam1->calibration);
  if (c.ds.imu_calibration) {
    vio::BodyImu imu = vio::ReadBodyImu(c.ds);
    c.noise = imu.noise;
    c.imu = std::move(imu.samples);
  }
  std::map<int64_t, std::string> rights;
  for (const auto& r : c.ds.cam1->images) rights[r.t_ns] = r.path;
  for (const auto& l : c.ds.cam0->images) {
    if (!rights.count(l.t_ns)) continue;
    c.t_ns.push_back(l.t_ns);
    c.left.push_back(cv::imread(l.path, cv::IMREAD_GRAYSCALE));
    c.right.push_back(cv::imread(rights[l.t_ns], cv::IMREAD_GRAYSCALE));
  }
  return c;
}

const Clip& LoadClip() {
  static const Clip clip = [] {
    const char* env = std::getenv("OPTINAV_SHARED_DATA");
    return ReadClip((env ? fs::path(env) : fs::path(OPTINAV_SHARED_DATA_DEFAULT)) / "euroc" /
                    "V1_01_micro");
  }();
  return clip;
}

// The first 15 s of the urban car route at 800x600 in `weather`, rendered once per process.
const Clip& CarClip(const std::string& weather) {
  static std::map<std::string, Clip> clips;
  auto it = clips.find(weather);
  if (it != clips.end()) return it->second;
  sim::SimulationOptions o;
  o.route = "car";
  o.duration_s = 15.0;
  o.seed = 1;
  o.scale = 1.0;
  o.weather = sim::ParseWeather(weather);
  const fs::path dir =
      fs::temp_directory_path() / ("optinav_vio_bench_car_" + std::to_string(::getpid()));
  o.out_dir = dir.string();
  o.force = true;
  sim::RunSimulation(o);
  Clip c = ReadClip(dir);
  fs::remove_all(dir);
  return clips.emplace(weather, std::move(c)).first->second;
}

// The whole estimator over `c`'s frames (sequential), per-stage median and p95 per frame as
// counters (of the last iteration).
void RunEstimator(benchmark::State& state, const Clip& c, const vio::VioOptions& options) {
  for (auto _ : state) {
    vio::VioEstimator e(c.rig, c.ds.cam0->calibration.body_from_cam, c.noise, options);
    size_t k = 0;
    for (size_t i = 0; i < c.t_ns.size(); ++i) {
      for (; k < c.imu.size() && c.imu[k].t_ns <= c.t_ns[i] + 20'000'000; ++k) e.AddImu(c.imu[k]);
      benchmark::DoNotOptimize(e.ProcessFrame(c.t_ns[i], c.left[i], c.right[i]));
    }
    for (const std::string& stage : e.timing().Stages()) {
      const TimingSummary s = e.timing().Summary(stage);
      state.counters[stage + "_median_ms"] = s.median_s * 1e3;
      state.counters[stage + "_p95_ms"] = s.p95_s * 1e3;
    }
  }
  state.counters["frames"] = static_cast<double>(c.t_ns.size());
}

void BM_VioEurocMicro(benchmark::State& state) {
  RunEstimator(state, LoadClip(), vio::VioOptions{});
}
BENCHMARK(BM_VioEurocMicro)->Unit(benchmark::kMillisecond)->Iterations(3);

enum class CarFrontend { kNow, kFiled, kNoFloor };

void BM_VioCar800(benchmark::State& state, const std::string& weather, vio::VioMode mode,
                  CarFrontend frontend) {
  const Clip& c = CarClip(weather);  // rendered on every core
  cv::setNumThreads(1);
  vio::VioOptions options;
  options.mode = mode;
  if (frontend == CarFrontend::kFiled) {  // the frontend before 2026-11-25
    options.frontend.clahe_clip_limit = 0;
    options.frontend.detect_min_eigen = 0;
    options.frontend.stereo_only_corner_noise_floor = 0;
    options.frontend.stereo_only_klt_gain_offset = false;
  } else if (mode == vio::VioMode::kStereoImu) {  // --vehicle auto on a car route
    app::ApplyGroundVehicleDefaults(&options.backend);
  }
  if (frontend == CarFrontend::kNoFloor) options.frontend.stereo_only_corner_noise_floor = 0;
  RunEstimator(state, c, options);
}
#define OPTINAV_CAR_BENCH(name, weather, mode)                                      \
  BENCHMARK_CAPTURE(BM_VioCar800, name##_now, weather, mode, CarFrontend::kNow)     \
      ->Unit(benchmark::kMillisecond)                                               \
      ->Iterations(1);                                                              \
  BENCHMARK_CAPTURE(BM_VioCar800, name##_filed, weather, mode, CarFrontend::kFiled) \
      ->Unit(benchmark::kMillisecond)                                               \
      ->Iterations(1)
OPTINAV_CAR_BENCH(clear_stereo, "none", vio::VioMode::kStereo);
OPTINAV_CAR_BENCH(fog100_stereo, "fog:100", vio::VioMode::kStereo);
OPTINAV_CAR_BENCH(dust100_stereo, "dust:100", vio::VioMode::kStereo);
OPTINAV_CAR_BENCH(clear_stereo_imu, "none", vio::VioMode::kStereoImu);
OPTINAV_CAR_BENCH(fog100_stereo_imu, "fog:100", vio::VioMode::kStereoImu);
OPTINAV_CAR_BENCH(dust100_stereo_imu, "dust:100", vio::VioMode::kStereoImu);
#undef OPTINAV_CAR_BENCH
// The stereo-only corner floor's cost (frontend.stereo_only_corner_noise_floor 0, otherwise
// the defaults), beside "now" in the same run.
BENCHMARK_CAPTURE(BM_VioCar800, clear_stereo_nofloor, "none", vio::VioMode::kStereo,
                  CarFrontend::kNoFloor)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_VioCar800, fog100_stereo_nofloor, "fog:100", vio::VioMode::kStereo,
                  CarFrontend::kNoFloor)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

void BM_FrontendOnly(benchmark::State& state) {
  const Clip& c = LoadClip();
  for (auto _ : state) {
    vio::StereoFrontend f(c.rig, vio::FrontendOptions{});
    for (size_t i = 0; i < c.t_ns.size(); ++i)
      benchmark::DoNotOptimize(f.Process(c.t_ns[i], c.left[i], c.right[i], std::nullopt));
  }
  state.counters["ms_per_frame"] = benchmark::Counter(
      static_cast<double>(c.t_ns.size()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_FrontendOnly)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_GnssSmoother(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::vector<vio::FrameEstimate> estimates;
  std::vector<vio::GnssSample> samples;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 3.0);
  vio::WorldAlignment live;
  live.yaw_rad = 0.5;
  for (int i = 0; i < n; ++i) {
    const double t = 0.05 * i, w = 5.0 / 150.0;
    const Eigen::Vector3d p(150 * std::cos(w * t), 150 * std::sin(w * t), 10.0);
    vio::FrameEstimate e;
    e.state.t_ns = static_cast<int64_t>(i) * 50'000'000;
    e.state.world_from_body = Rigid3d(Eigen::Quaterniond::Identity(), p);
    live.translation = Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 0.1;
    e.enu_from_world = live;
    estimates.push_back(e);
    if (i % 4 == 0) {
      vio::GnssSample g;
      g.t_ns = e.state.t_ns + 10'000'000;
      g.position_enu_m =
          live.EnuFromWorld() * p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      g.sigma_m = 3.0;
      samples.push_back(g);
    }
  }
  for (auto _ : state)
    benchmark::DoNotOptimize(
        vio::SmoothGnssAlignment(estimates, {}, samples, {}, vio::GnssFusionOptions{}));
}
BENCHMARK(BM_GnssSmoother)->Arg(1000)->Arg(4000)->Arg(16000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
