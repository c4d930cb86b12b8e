// optinav vio: stereo visual-inertial odometry on a EuRoC/ASL dataset.
#include <cstdio>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "optinav/exe/commands.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/vio/pipeline.h"

namespace optinav {

namespace {

nlohmann::json StatsJson(const vio::VioRunResult& r, const std::string& mode) {
  nlohmann::json j;
  j["mode"] = mode;
  j["frames"] = r.frames_total;
  j["frames_processed"] = r.frames_processed;
  j["frames_unpaired"] = r.frames_unpaired;
  j["poses"] = r.estimates.size();
  j["initializations"] = r.initializations;
  j["first_initialization"] = r.first_init_kind;
  nlohmann::json timing = nlohmann::json::object();
  for (const auto& [stage, s] : r.timing)
    timing[stage] = {{"count", s.count},
                     {"median_ms", s.median_s * 1e3},
                     {"p95_ms", s.p95_s * 1e3},
                     {"mean_ms", s.mean_s * 1e3},
                     {"max_ms", s.max_s * 1e3}};
  j["timing_per_frame"] = timing;
  nlohmann::json lost = nlohmann::json::array();
  for (const vio::LostInterval& l : r.lost)
    lost.push_back({{"start_s", l.start_ns * 1e-9},
                    {"end_s", l.end_ns * 1e-9},
                    {"duration_s", (l.end_ns - l.start_ns) * 1e-9},
                    {"reason", l.reason}});
  j["lost_intervals"] = lost;
  return j;
}

}  // namespace

int RunVio(int argc, char** argv) {
  CLI::App app{
      "Stereo visual-inertial odometry (Ceres sliding window) on a EuRoC/ASL dataset or an AirSim "
      "recording (stereo-only)",
      "optinav vio"};
  std::string dataset, format = "euroc", config, out, camera_out, stats, mode_name,
                       log_level = "info";
  bool sequential = false;
  size_t max_frames = 0;
  app.add_option("--dataset", dataset, "sequence folder (holding mav0/)")->required();
  app.add_option("--format", format, "dataset format: euroc|airsim (airsim: stereo-only)")
      ->capture_default_str();
  app.add_option("--config", config, "YAML options (see config/vio_euroc.yaml); defaults built in");
  app.add_option("--out", out, "output trajectory of the body (IMU) frame, TUM")->required();
  app.add_option("--camera-out", camera_out, "also write the left camera's trajectory, TUM");
  app.add_option("--stats", stats,
                 "timing per module (median, p95 per frame) and lost intervals, JSON");
  app.add_option("--mode", mode_name, "stereo-imu|stereo (default: the config's, else stereo-imu)");
  app.add_flag("--sequential", sequential,
               "run in one thread (default: a loader thread feeds the estimator; same results)");
  app.add_option("--max-frames", max_frames, "process only the first N stereo frames (0: all)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    SetLogLevel(log_level);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  if (format != "euroc" && format != "airsim") {
    spdlog::error("--format: unknown format '{}' (euroc|airsim)", format);
    return 2;
  }
  std::optional<vio::VioMode> mode;
  if (!mode_name.empty()) {
    mode = vio::ParseVioMode(mode_name);
    if (!mode) {
      spdlog::error("--mode: unknown mode '{}' (stereo-imu|stereo)", mode_name);
      return 2;
    }
  }
  try {
    vio::VioRunOptions options;
    if (!config.empty()) options.vio = vio::LoadVioOptions(config);
    if (mode) options.vio.mode = *mode;
    if (format == "airsim" && !mode) options.vio.mode = vio::VioMode::kStereo;  // no IMU in AirSim
    options.threaded = !sequential;
    options.max_frames = max_frames;
    const vio::VioRunResult r = format == "airsim" ? vio::RunVioOnAirsim(dataset, options)
                                                   : vio::RunVioOnEuroc(dataset, options);
    if (r.estimates.empty())
      throw Error("no pose estimated (never initialised: no stereo features or no IMU window)",
                  {.file = dataset});
    io::WriteTrajectory(out, vio::EstimatesToTrajectory(r.estimates), io::TrajectoryFormat::kTum);
    if (!camera_out.empty())
      io::WriteTrajectory(camera_out, vio::EstimatesToTrajectory(r.estimates, r.body_from_cam0),
                          io::TrajectoryFormat::kTum);
    const std::string mode_used = vio::VioModeName(options.vio.mode);
    if (!stats.empty()) io::WriteFileAtomically(stats, StatsJson(r, mode_used).dump(2) + "\n");
    for (const vio::LostInterval& l : r.lost)
      spdlog::warn("lost {:.3f} s .. {:.3f} s: {}", l.start_ns * 1e-9, l.end_ns * 1e-9, l.reason);
    const auto total = r.timing.count("total") ? r.timing.at("total") : TimingSummary{};
    std::printf(
        "vio %s: %zu poses from %zu stereo frames, %zu lost interval(s), %s "
        "initialisation; per frame median %.1f ms, p95 %.1f ms -> %s\n",
        mode_used.c_str(), r.estimates.size(), r.frames_total, r.lost.size(),
        r.first_init_kind.c_str(), total.median_s * 1e3, total.p95_s * 1e3, out.c_str());
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}

}  // namespace optinav
