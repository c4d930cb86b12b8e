// optinav demo: the end-to-end jobs on generated data.
//  1. Evaluation: a drone flight and a drifting odometry estimate of it (yaw drift, scale error,
//     velocity random walk, its own start frame, a lower and jittered rate), written in their
//     usual formats and evaluated as a user would with `optinav eval`.
//  2. GNSS-denied missions: a generated orthophoto, its map database, and seeded flights from a
//     start to a target 2.5 km away in light fog, navigating by matching camera frames to the
//     map (`optinav mission`), with pictures of the true and estimated paths.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "optinav/app/evaluation.h"
#include "optinav/app/mission_experiment.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/maploc/map_db.h"
#include "optinav/sim/synthetic_ortho.h"

namespace optinav {
namespace {

struct DemoOptions {
  std::string out_dir = "demo_out";
  unsigned seed = 42;
  double duration_s = 120.0;
  int mission_runs = 3;
  // Check(): empty when valid, else a message that starts with the flag at fault.
  std::string Check() const {
    if (out_dir.empty()) return "--out must not be empty";
    if (!(duration_s >= 10 && duration_s <= 3600)) return "--duration must be in [10, 3600] s";
    if (mission_runs < 0 || mission_runs > 100) return "--mission-runs must be in [0, 100]";
    return "";
  }
};

// A figure-eight flight at 20 Hz: 10 m above ground, yaw along the velocity.
Trajectory MakeGroundTruth(double duration_s) {
  Trajectory gt;
  const int64_t t0 = 1'700'000'000'000'000'000;
  const double w = 2 * M_PI / 60.0;  // one figure-eight per minute
  for (int k = 0; k <= static_cast<int>(duration_s * 20); ++k) {
    const double t = k / 20.0;
    const Eigen::Vector3d p(60 * std::sin(w * t), 30 * std::sin(2 * w * t),
                            10 + 2 * std::sin(0.5 * w * t));
    const Eigen::Vector3d v(60 * w * std::cos(w * t), 60 * w * std::cos(2 * w * t), 0);
    const double yaw = std::atan2(v.y(), v.x());
    gt.Add(t0 + static_cast<int64_t>(k) * 50'000'000,
           Rigid3d(ExpSO3(Eigen::Vector3d(0, 0, yaw)), p));
  }
  return gt;
}

// Dead-reckoning with errors: integrates the true relative motion with a scale error, a yaw
// drift and a velocity random walk; sampled at 10 Hz with +-2 ms stamp jitter, in a start frame
// of its own (rotated and shifted), starting 1 s late.
Trajectory MakeDriftingEstimate(const Trajectory& gt, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_int_distribution<int64_t> jitter(-2'000'000, 2'000'000);
  const double scale = 1.01, yaw_drift_rad_s = 0.5 * M_PI / 180.0 / 60.0;
  Eigen::Vector3d vel_err = Eigen::Vector3d::Zero();
  const Rigid3d start_frame(ExpSO3(Eigen::Vector3d(0, 0, 0.5)), Eigen::Vector3d(5, -3, 0));
  Rigid3d est = gt.pose(20);
  Trajectory out;
  for (size_t k = 21; k < gt.size(); ++k) {
    const double dt = 0.05;
    const Rigid3d rel = gt.pose(k - 1).Inverse() * gt.pose(k);
    Rigid3d step(rel.rotation * ExpSO3(Eigen::Vector3d(0, 0, yaw_drift_rad_s * dt)),
                 scale * rel.translation);
    vel_err += 0.01 * std::sqrt(dt) * Eigen::Vector3d(n01(rng), n01(rng), 0.3 * n01(rng));
    step.translation += vel_err * dt;
    est = est * step;
    if (k % 2 == 0) {
      Rigid3d noisy = est;
      noisy.translation += 0.02 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      out.Add(gt.t_ns[k] + jitter(rng), start_frame * noisy);
    }
  }
  return out;
}

// A 4.1 x 4.1 km procedural farmland orthophoto at 4 m/px, its map for a 500 m altitude (256x256
// frames, 90 deg FOV: 1 km footprint), and missions of >= 2.5 km in 25 % fog.
int RunDemoMissions(const DemoOptions& opt) {
  namespace fs = std::filesystem;
  const fs::path dir(opt.out_dir);
  const std::string ortho = (dir / "ortho.tif").string();
  const std::string map = (dir / "map.db").string();
  std::printf("\n--- GNSS-denied missions over a generated orthophoto ---\n");
  sim::WriteSyntheticFarmland(ortho, 1024, 4.0, opt.seed);
  maploc::MapBuildOptions bo;
  bo.frame_width = bo.frame_height = 256;
  bo.hfov_deg = 90;
  bo.altitude_m = 500;
  const maploc::MapDatabase db = maploc::BuildMapDatabase(ortho, bo, map);
  std::printf("  wrote %s (1024 x 1024 px at 4 m/px) and %s (%zu tiles, %zu ORB features)\n\n",
              ortho.c_str(), map.c_str(), db.tiles.size(), db.FeatureCount());
  app::MissionExperimentOptions m;
  m.map_path = map;  // start and target unset: seeded random legs
  m.min_distance_m = 2500;
  m.margin_m = 250;
  m.runs = opt.mission_runs;
  m.weather = "fog:25";
  m.out_dir = (dir / "mission").string();
  m.force = true;  // the demo's own folder, rewritten on every run
  m.mission.seed = opt.seed;
  const app::MissionExperimentResult r =
      app::RunMissionExperiment(m, [](const app::MissionRunOutcome& run) {
        if (run.run == 1) std::fputs(app::FormatMissionRunHeader().c_str(), stdout);
        std::fputs(app::FormatMissionRunRow(run).c_str(), stdout);
        std::fflush(stdout);
      });
  std::fputs(app::FormatMissionSummary(r).c_str(), stdout);
  std::printf("  pictures: %s/summary.png (all runs), %s/run_001/path.png (one run)\n",
              m.out_dir.c_str(), m.out_dir.c_str());
  return r.all_reached() ? 0 : 3;
}

// The flight, its drifting estimate in their usual formats, and three evaluations of them.
void RunDemoEvaluation(const DemoOptions& opt) {
  namespace fs = std::filesystem;
  fs::create_directories(opt.out_dir);
  const Trajectory gt = MakeGroundTruth(opt.duration_s);
  const Trajectory est = MakeDriftingEstimate(gt, opt.seed);
  const std::string gt_path = (fs::path(opt.out_dir) / "groundtruth.csv").string();
  const std::string est_path = (fs::path(opt.out_dir) / "estimate.tum").string();
  io::WriteTrajectory(gt_path, gt, io::TrajectoryFormat::kEuroc);
  io::WriteTrajectory(est_path, est, io::TrajectoryFormat::kTum);
  std::printf(
      "optinav demo: %.0f s figure-eight flight, %.0f m path; estimate with yaw drift, "
      "1%% scale error and velocity random walk (seed %u)\n",
      opt.duration_s, gt.PathLength(), opt.seed);
  std::printf("  wrote %s (EuRoC csv, %zu poses) and %s (TUM, %zu poses)\n\n", gt_path.c_str(),
              gt.size(), est_path.c_str(), est.size());

  struct Job {
    const char* name;
    app::EvaluationSettings::Metric metric;
    eval::AlignMode align;
  };
  double ape_se3_rmse = 0;
  for (const Job& job :
       {Job{"ape_se3", app::EvaluationSettings::Metric::kApe, eval::AlignMode::kSe3},
        Job{"ape_posyaw", app::EvaluationSettings::Metric::kApe, eval::AlignMode::kPosYaw},
        Job{"rpe_10m", app::EvaluationSettings::Metric::kRpe, eval::AlignMode::kSe3}}) {
    app::EvaluationSettings st;
    st.metric = job.metric;
    st.ref_path = gt_path;
    st.est_path = est_path;
    st.alignment.mode = job.align;
    st.rpe = {.delta = 10, .unit = eval::DeltaUnit::kMeters};
    st.json_path = (fs::path(opt.out_dir) / (std::string(job.name) + ".json")).string();
    st.plot_path = (fs::path(opt.out_dir) / (std::string(job.name) + ".svg")).string();
    const app::EvaluationOutcome o = app::RunEvaluation(st);
    if (std::string(job.name) == "ape_se3") ape_se3_rmse = o.series.stats.rmse;
    std::printf("[%s] ", job.name);
    std::fputs(app::FormatEvaluationTable(st, o).c_str(), stdout);
    std::printf("  -> %s, %s\n\n", st.json_path.c_str(), st.plot_path.c_str());
  }
  std::printf("summary: APE rmse after SE(3) alignment %.3f m = %.2f %% of the %.0f m path\n",
              ape_se3_rmse, 100.0 * ape_se3_rmse / gt.PathLength(), gt.PathLength());
}

}  // namespace

int RunDemo(int argc, char** argv) {
  CLI::App app{"Generate a flight and a drifting estimate, then evaluate it", "optinav demo"};
  DemoOptions opt;
  app.add_option("--out", opt.out_dir, "output folder")->capture_default_str();
  app.add_option("--seed", opt.seed, "random seed")->capture_default_str();
  app.add_option("--duration", opt.duration_s, "flight duration (s)")->capture_default_str();
  app.add_option("--mission-runs", opt.mission_runs, "GNSS-denied missions to fly (0: none)")
      ->capture_default_str();
  return cli::RunCli(app, argc, argv, [&] {
    cli::ThrowIfCheckFailed(opt.Check());
    RunDemoEvaluation(opt);
    return opt.mission_runs > 0 ? RunDemoMissions(opt) : 0;
  });
}

}  // namespace optinav
