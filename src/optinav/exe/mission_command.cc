// optinav mission: GNSS-denied flights to a target over an orthophoto map, repeated over seeded
// runs (app::RunMissionExperiment), with a table on stdout; exit 3 when some run missed.
#include <cstdio>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "optinav/app/mission_experiment.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"

namespace optinav {
namespace {

// The flag values that are not app::MissionExperimentOptions fields as they are.
struct MissionFlags {
  std::string start, target;
  std::string nadir_camera = "640x480";
  bool no_odometry = false;
  cli::OutputDirOptions out;
};

void AddMissionFlags(CLI::App& app, app::MissionExperimentOptions& a, MissionFlags& f) {
  nav::MissionOptions& o = a.mission;
  app.add_option("--map", a.map_path, "map database (optinav map build)")->required();
  app.add_option("--start", f.start, "start LAT,LON, or 'random'")->required();
  app.add_option("--target", f.target, "target LAT,LON, or 'random'")->required();
  f.out.Add(app, "output folder", "write into a non-empty output folder");
  app.add_option("--runs", a.runs, "number of runs (seeds seed..seed+runs-1)")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "first seed")->capture_default_str();
  app.add_option("--speed", o.speed_m_s, "ground speed (m/s)")->capture_default_str();
  app.add_option("--altitude", o.altitude_m, "altitude above ground (m; default: the map's)");
  app.add_option("--step", o.step_s, "time between frames (s)")->capture_default_str();
  app.add_option("--frames-from", a.frames_from,
                 "synthesise frames from another orthophoto of the area (e.g. a later year)");
  app.add_option("--ortho", a.ortho_path, "the map's orthophoto, if moved since the build");
  app.add_option("--model", a.model_path,
                 "XFeat network (.onnx) of an xfeat map (default: shared data)");
  app.add_option("--weather", a.weather, "none | fog:50 | dust:50 | ...")->capture_default_str();
  app.add_option("--min-distance", a.min_distance_m, "random start/target: at least this far (m)")
      ->capture_default_str();
  app.add_option("--margin", a.margin_m, "random start/target: distance from the map edge (m)")
      ->capture_default_str();
  app.add_option("--arrive-radius", o.arrive_radius_m,
                 "the mission ends when the estimate is this close to the target (m)")
      ->capture_default_str();
  app.add_option("--success-radius", o.success_radius_m,
                 "a run succeeds when the true drone ends this close (m)")
      ->capture_default_str();
  app.add_option("--time-limit", o.time_limit_s, "seconds (0: 3x straight-line time + 120 s)")
      ->capture_default_str();
  app.add_option("--wind", o.wind_m_s, "constant wind speed, seeded direction (m/s)")
      ->capture_default_str();
  app.add_option("--compass-bias", o.compass_bias_deg, "heading-hold error, +- deg per run")
      ->capture_default_str();
  app.add_option("--tilt", o.effects.max_tilt_deg, "max roll/pitch from gusts (deg)")
      ->capture_default_str();
  app.add_option("--attitude-noise", o.attitude_noise_deg,
                 "error of the roll/pitch given to locate (deg, 1-sigma)")
      ->capture_default_str();
  app.add_option("--blur", o.effects.motion_blur_px, "max motion blur (px)")->capture_default_str();
  app.add_option("--exposure", o.effects.exposure_variation, "exposure change (+- fraction)")
      ->capture_default_str();
  app.add_option("--altitude-variation", o.effects.altitude_variation,
                 "altitude change (+- fraction)")
      ->capture_default_str();
  app.add_option("--estimator", o.estimator,
                 "2d: the 2-D filter (fixes + frame odometry); nav: optinav nav's estimator "
                 "(IMU + barometer + nadir camera + map fixes)")
      ->check(CLI::IsMember({"2d", "nav"}))
      ->capture_default_str();
  app.add_option("--nadir-camera", f.nadir_camera, "nav: the nadir camera's frame size WxH")
      ->capture_default_str();
  app.add_option("--nadir-hfov", o.nadir.hfov_deg, "nav: its horizontal field of view (deg)")
      ->capture_default_str();
  app.add_option("--nadir-rate", o.nadir.rate_hz, "nav: its frame rate (Hz)")
      ->capture_default_str();
  app.add_flag(
      "--no-odometry", f.no_odometry,
      "fixes only: the estimate is the latest fix, keep the last bearing when a fix fails");
  app.add_option("--pictures", a.pictures, "all | summary | none")->capture_default_str();
  app.add_flag("--save-frames", a.save_frames, "write every camera frame to run_NNN/frames/");
  app.add_flag("--html", a.html, "also write the HTML report DIR/report.html (optinav report)");
}

// "random" or LAT,LON (Error naming the flag when malformed).
std::optional<geo::LatLon> ParseLeg(const std::string& text, const std::string& flag) {
  if (text == "random") return std::nullopt;
  return ParseLatLon(text, flag);
}

int Run(app::MissionExperimentOptions& a, const MissionFlags& f) {
  a.out_dir = f.out.dir;
  a.force = f.out.force;
  a.mission.use_odometry = !f.no_odometry;
  ParseFrameSize(f.nadir_camera, "--nadir-camera", 64, &a.mission.nadir.width,
                 &a.mission.nadir.height);
  if ((f.start == "random") != (f.target == "random")) {
    throw cli::UsageError("give both --start and --target as LAT,LON, or both as 'random'",
                          "--start");
  }
  a.start = ParseLeg(f.start, "--start");
  a.target = ParseLeg(f.target, "--target");
  cli::ThrowIfCheckFailed(a.Check());
  const app::MissionExperimentResult r =
      app::RunMissionExperiment(a, [](const app::MissionRunOutcome& run) {
        if (run.run == 1) std::fputs(app::FormatMissionRunHeader().c_str(), stdout);
        std::fputs(app::FormatMissionRunRow(run).c_str(), stdout);
        std::fflush(stdout);
      });
  std::fputs(app::FormatMissionSummary(r).c_str(), stdout);
  if (r.html) PrintHtmlReportLine(*r.html);
  return r.all_reached() ? 0 : 3;
}

}  // namespace

int RunMission(int argc, char** argv) {
  CLI::App app{
      "Fly GNSS-denied missions to a target over an orthophoto map: camera frames are "
      "synthesised at the true pose, localized against the map database, blended with "
      "frame-to-frame odometry, and the drone turns towards the target."};
  app.name("optinav mission");
  app::MissionExperimentOptions a;
  MissionFlags f;
  AddMissionFlags(app, a, f);
  return cli::RunCli(app, argc, argv, [&] { return Run(a, f); });
}

}  // namespace optinav
