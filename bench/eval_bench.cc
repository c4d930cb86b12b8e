// Evaluation speed: association + SE3 alignment + APE statistics on two 1,000,000-pose TUM
// trajectories, file parsing included, on one core; and the parser against a naive
// line-by-line std::istream parse of the same file.
//
//   build/bench/eval_bench [--benchmark_filter=...]
// The two input files are generated once into $TMPDIR (about 80 MB each).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <benchmark/benchmark.h>

#include "optinav/eval/metrics.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"

namespace {

constexpr size_t kPoses = 1'000'000;

struct Files {
  std::string ref, est;
};

// Reference at 100 Hz; the estimate at the same rate with stamps jittered by up to 2 ms, a yaw
// and position offset and noise, as a real estimate would be.
const Files& GetFiles() {
  static const Files files = [] {
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / "optinav_bench";
    fs::create_directories(dir);
    Files f{(dir / "ref_1M.tum").string(), (dir / "est_1M.tum").string()};
    if (fs::exists(f.ref) && fs::exists(f.est)) return f;
    std::mt19937 rng(1);
    std::normal_distribution<double> noise(0, 0.05);
    std::uniform_int_distribution<int64_t> jitter(-2'000'000, 2'000'000);
    optinav::Trajectory ref, est;
    ref.Reserve(kPoses, true);
    est.Reserve(kPoses, true);
    const optinav::Rigid3d offset(optinav::ExpSO3(Eigen::Vector3d(0, 0, 0.3)),
                                  Eigen::Vector3d(4, -2, 1));
    for (size_t i = 0; i < kPoses; ++i) {
      const double t = i * 0.01;
      const optinav::Rigid3d pose(optinav::ExpSO3(Eigen::Vector3d(0.01 * std::sin(t), 0, 0.05 * t)),
                                  Eigen::Vector3d(100 * std::sin(0.01 * t), 50 * std::cos(0.02 * t),
                                                  5 * std::sin(0.1 * t)));
      const int64_t stamp = 1'600'000'000'000'000'000 + static_cast<int64_t>(i) * 10'000'000;
      ref.Add(stamp, pose);
      optinav::Rigid3d e = offset * pose;
      e.translation += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      est.Add(stamp + jitter(rng), e);
    }
    optinav::io::WriteTrajectory(f.ref, ref, optinav::io::TrajectoryFormat::kTum);
    optinav::io::WriteTrajectory(f.est, est, optinav::io::TrajectoryFormat::kTum);
    return f;
  }();
  return files;
}

void BM_ApePipeline1M(benchmark::State& state) {
  const Files& f = GetFiles();
  for (auto _ : state) {
    auto ref = optinav::io::ReadTrajectory(f.ref, {.format = optinav::io::TrajectoryFormat::kTum});
    auto est = optinav::io::ReadTrajectory(f.est, {.format = optinav::io::TrajectoryFormat::kTum});
    auto synced = optinav::eval::Synchronize(std::move(ref), std::move(est), {.max_diff_s = 0.01});
    optinav::eval::AlignTrajectory(synced.ref, &synced.est,
                                   {.mode = optinav::eval::AlignMode::kSe3});
    const auto ape = optinav::eval::ComputeApe(synced.ref, synced.est,
                                               optinav::eval::PoseRelation::kTranslation);
    benchmark::DoNotOptimize(ape.stats.rmse);
    state.counters["pairs"] = static_cast<double>(ape.stats.n);
    state.counters["rmse_m"] = ape.stats.rmse;
  }
}
BENCHMARK(BM_ApePipeline1M)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_ParseTum1M(benchmark::State& state) {
  const Files& f = GetFiles();
  for (auto _ : state) {
    const auto t =
        optinav::io::ReadTrajectory(f.ref, {.format = optinav::io::TrajectoryFormat::kTum});
    benchmark::DoNotOptimize(t.positions.data());
  }
}
BENCHMARK(BM_ParseTum1M)->Unit(benchmark::kMillisecond)->Iterations(3);

// The usual hand-written reader: getline + istringstream >> double, no validation.
void BM_ParseTumNaiveStream1M(benchmark::State& state) {
  const Files& f = GetFiles();
  for (auto _ : state) {
    std::ifstream in(f.ref);
    std::string line;
    std::vector<double> values;
    values.reserve(8 * kPoses);
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream ss(line);
      double v;
      for (int k = 0; k < 8 && ss >> v; ++k) values.push_back(v);
    }
    benchmark::DoNotOptimize(values.data());
  }
}
BENCHMARK(BM_ParseTumNaiveStream1M)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_AssociateAlignApe1M(benchmark::State& state) {
  const Files& f = GetFiles();
  const auto ref = optinav::io::ReadTrajectory(f.ref);
  const auto est = optinav::io::ReadTrajectory(f.est);
  for (auto _ : state) {
    auto synced = optinav::eval::Synchronize(ref, est, {.max_diff_s = 0.01});  // copies inputs
    optinav::eval::AlignTrajectory(synced.ref, &synced.est,
                                   {.mode = optinav::eval::AlignMode::kSe3});
    const auto ape = optinav::eval::ComputeApe(synced.ref, synced.est,
                                               optinav::eval::PoseRelation::kTranslation);
    benchmark::DoNotOptimize(ape.stats.rmse);
  }
}
BENCHMARK(BM_AssociateAlignApe1M)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
