// VIO speed (issue 5), one core, 752x480 stereo at 20 Hz + 200 Hz IMU (EuRoC V1_01_micro, real):
//  - BM_VioEurocMicro: the whole estimator (frontend + backend, sequential) over the clip's
//    95 stereo frames per iteration, images decoded beforehand. Counters: per-module median and
//    p95 per frame (ms). Target: total median < 15 ms, p95 < 40 ms per frame (backend amortised
//    over frames: it solves every frame, marginalises at keyframes).
//  - BM_FrontendOnly: the frontend alone over the same frames.
// Data: ../shared/data (or $OPTINAV_SHARED_DATA).
#include <cstdlib>
#include <filesystem>
#include <map>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/io/euroc_dataset.h"
#include "optinav/vio/estimator.h"

namespace {

namespace fs = std::filesystem;
using namespace optinav;

struct Clip {
  io::EurocDataset ds;
  camera::StereoRig rig;
  std::vector<vio::TimedImuSample> imu;
  std::vector<int64_t> t_ns;
  std::vector<cv::Mat> left, right;
};

const Clip& LoadClip() {
  static const Clip clip = [] {
    const char* env = std::getenv("OPTINAV_SHARED_DATA");
    const fs::path dir =
        (env ? fs::path(env) : fs::path(OPTINAV_SHARED_DATA_DEFAULT)) / "euroc" / "V1_01_micro";
    Clip c;
    io::EurocOpenOptions open;
    open.drop_missing_images = true;
    c.ds = io::OpenEurocDataset(dir.string(), open);
    c.rig = io::ToStereoRig(c.ds.cam0->calibration, c.ds.cam1->calibration);
    for (const io::ImuSample& s : io::ReadImuCsv(c.ds.imu_csv))
      c.imu.push_back({s.t_ns, s.gyro_rad_s, s.accel_m_s2});
    std::map<int64_t, std::string> rights;
    for (const auto& r : c.ds.cam1->images) rights[r.t_ns] = r.path;
    for (const auto& l : c.ds.cam0->images) {
      if (!rights.count(l.t_ns)) continue;
      c.t_ns.push_back(l.t_ns);
      c.left.push_back(cv::imread(l.path, cv::IMREAD_GRAYSCALE));
      c.right.push_back(cv::imread(rights[l.t_ns], cv::IMREAD_GRAYSCALE));
    }
    return c;
  }();
  return clip;
}

void BM_VioEurocMicro(benchmark::State& state) {
  const Clip& c = LoadClip();
  for (auto _ : state) {
    vio::VioEstimator e(c.rig, c.ds.cam0->calibration.body_from_cam, vio::ImuNoise{},
                        vio::VioOptions{});
    size_t k = 0;
    for (size_t i = 0; i < c.t_ns.size(); ++i) {
      for (; k < c.imu.size() && c.imu[k].t_ns <= c.t_ns[i] + 20'000'000; ++k) e.AddImu(c.imu[k]);
      benchmark::DoNotOptimize(e.ProcessFrame(c.t_ns[i], c.left[i], c.right[i]));
    }
    for (const std::string& stage : e.timing().Stages()) {
      // Per-frame statistics of the last iteration.
      const TimingSummary s = e.timing().Summary(stage);
      state.counters[stage + "_median_ms"] = s.median_s * 1e3;
      state.counters[stage + "_p95_ms"] = s.p95_s * 1e3;
    }
  }
  state.counters["frames"] = static_cast<double>(c.t_ns.size());
}
BENCHMARK(BM_VioEurocMicro)->Unit(benchmark::kMillisecond)->Iterations(3);

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

}  // namespace

BENCHMARK_MAIN();
