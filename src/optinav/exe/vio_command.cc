// optinav vio: stereo visual-inertial odometry on a EuRoC/ASL dataset or an AirSim recording.
// Parses the flags into app::VioRunSettings, runs app::RunVioDataset and prints its summary.
#include <cstdio>

#include <CLI/CLI.hpp>

#include "optinav/app/vio_run.h"
#include "optinav/exe/cli_common.h"
#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/exe/gnss_flags.h"

namespace optinav {
namespace {

// The flags that are names, numbers with an "unset" value or lists, resolved after parsing.
struct VioFlags {
  std::string format = "euroc", mode, loop_closure, vehicle = "auto";
  std::string gnss_format = "auto", gnss_norm = "huber", gnss_origin, gnss_lever_arm;
  double gnss_sigma = -1;
  cli::GnssFusionFlags fusion;
};

void AddRunOptions(CLI::App& cmd, app::VioRunSettings* st, VioFlags* f) {
  cmd.add_option("--dataset", st->dataset, "sequence folder (holding mav0/)")->required();
  cmd.add_option("--format", f->format, "dataset format: euroc|airsim (airsim: stereo-only)")
      ->capture_default_str();
  cmd.add_option("--config", st->config_path,
                 "YAML options (see config/vio_euroc.yaml); defaults built in");
  cli::OutputFile(
      cmd.add_option("--out", st->out, "output trajectory of the body (IMU) frame, TUM"))
      ->required();
  cli::OutputFile(cmd.add_option("--camera-out", st->camera_out,
                                 "also write the left camera's trajectory, TUM"));
  cli::OutputFile(
      cmd.add_option("--stats", st->stats_path,
                     "timing per module (median, p95 per frame) and lost intervals, JSON"));
  cmd.add_option("--mode", f->mode, "stereo-imu|stereo (default: the config's, else stereo-imu)");
  cmd.add_option("--vehicle", f->vehicle,
                 "auto|ground|free: ground: a wheeled vehicle's body-frame vertical velocity held "
                 "near 0 and landmarks gated on the IMU-predicted pose (2 px, or 2x the frame's "
                 "median error; stereo-imu; unless the config sets a backend.ground_vehicle_* "
                 "sigma or backend.predicted_gate_pixels); auto: ground on a simulator car route "
                 "(sim_complete.json), else free")
      ->capture_default_str();
  cmd.add_option("--loop-closure", f->loop_closure,
                 "on|off: close loops with earlier keyframes and correct the output (default: "
                 "the config's: on in both modes; never with --gnss)");
  cli::OutputFile(
      cmd.add_option("--odometry-out", st->odometry_out,
                     "also write the body trajectory before the loop corrections, TUM"));
  cmd.add_flag("--sequential", st->sequential,
               "run in one thread (default: loader, frontend and backend threads; the same "
               "result, the frontend waits for the backend feedback it uses)");
  cmd.add_option("--max-frames", st->max_frames, "process only the first N stereo frames (0: all)");
  cmd.add_option("--inject-backend-delay-ms", st->injected_backend_delay_ms,
                 "testing: the backend sleeps this long on every keyframe (the result must not "
                 "change, only the latency)");
}

void AddGnssOptions(CLI::App& cmd, app::VioRunSettings* st, VioFlags* f) {
  cmd.add_flag("--gnss", st->gnss,
               "fuse GNSS positions (stereo-imu); --out is then in the ENU frame of the GNSS "
               "origin");
  cmd.add_option("--gnss-file", st->gnss_input.file,
                 "GNSS csv (default DIR/mav0/gnss0/data.csv): t_ns,x,y,z ENU or "
                 "t_ns,lat,lon,height, optional sigma column");
  cmd.add_option("--gnss-format", f->gnss_format, "auto|enu|llh (auto: from the header)")
      ->capture_default_str();
  cmd.add_option("--gnss-norm", f->gnss_norm, "l2|huber|tukey")->capture_default_str();
  cmd.add_option("--gnss-sigma", f->gnss_sigma,
                 "GNSS sigma per axis, m (default: gnss0/sensor.yaml sigma_m, else 1)");
  cmd.add_option("--gnss-origin", f->gnss_origin,
                 "ENU origin LAT,LON,HEIGHT (default: gnss0/sensor.yaml, else the first fix)");
  cmd.add_option("--gnss-lever-arm", f->gnss_lever_arm,
                 "antenna in the body frame X,Y,Z, m (default: gnss0/sensor.yaml T_BS)");
  cli::AddGnssFusionFlags(cmd, &f->fusion);
  cli::OutputFile(
      cmd.add_option("--gnss-live-out", st->gnss_live_out,
                     "the live estimate in ENU, TUM (default with smoothing: TRAJ.live.tum)"));
  cli::OutputFile(cmd.add_option("--wgs84-out", st->wgs84_out,
                                 "fused trajectory in WGS84 csv (default TRAJ.wgs84.csv)"));
  cli::OutputFile(cmd.add_option("--geojson-out", st->geojson_out,
                                 "fused trajectory as GeoJSON (default TRAJ.geojson)"));
  cli::OutputFile(
      cmd.add_option("--gnss-rejected-out", st->gnss_rejected_out,
                     "rejected GNSS samples with their reason (default TRAJ.gnss_rejected.csv)"));
  cmd.add_flag("--html", st->html,
               "also write the HTML report TRAJ.report.html (optinav report; needs --gnss)");
}

// "A,B,C" of `flag` -> three numbers; a malformed value is a usage error.
Eigen::Vector3d ParseTripleFlag(const std::string& text, const std::string& flag) {
  try {
    return ParseTriple(text, flag);
  } catch (const Error& e) {
    throw cli::UsageError(e.message(), flag);
  }
}

void ResolveGnss(const VioFlags& f, app::VioRunSettings* st) {
  const std::optional<vio::GnssNorm> norm = vio::ParseGnssNorm(f.gnss_norm);
  if (!norm)
    throw cli::UsageError("unknown norm '" + f.gnss_norm + "' (l2|huber|tukey)", "--gnss-norm");
  st->gnss_fusion.norm = *norm;
  f.fusion.ApplyTo(&st->gnss_fusion);
  if (f.gnss_format == "enu")
    st->gnss_input.kind = io::GnssFileKind::kEnu;
  else if (f.gnss_format == "llh")
    st->gnss_input.kind = io::GnssFileKind::kLatLonHeight;
  else if (f.gnss_format != "auto")
    throw cli::UsageError("unknown format '" + f.gnss_format + "' (auto|enu|llh)", "--gnss-format");
  if (!f.gnss_origin.empty())
    st->gnss_input.origin_lat_lon_height = ParseTripleFlag(f.gnss_origin, "--gnss-origin");
  if (!f.gnss_lever_arm.empty())
    st->gnss_input.lever_arm_in_body = ParseTripleFlag(f.gnss_lever_arm, "--gnss-lever-arm");
  if (f.gnss_sigma != -1) st->gnss_input.sigma_m = f.gnss_sigma;
}

// Turns the named flags into the settings and checks them; throws cli::UsageError naming the
// flag at fault.
void Resolve(const VioFlags& f, app::VioRunSettings* st) {
  if (f.format == "airsim")
    st->format = app::VioDatasetFormat::kAirsim;
  else if (f.format != "euroc")
    throw cli::UsageError("unknown format '" + f.format + "' (euroc|airsim)", "--format");
  if (!f.mode.empty()) {
    st->mode = vio::ParseVioMode(f.mode);
    if (!st->mode)
      throw cli::UsageError("unknown mode '" + f.mode + "' (stereo-imu|stereo)", "--mode");
  }
  st->vehicle = ParseVehicle(f.vehicle, "--vehicle");
  if (!f.loop_closure.empty()) {
    if (f.loop_closure != "on" && f.loop_closure != "off")
      throw cli::UsageError("expected on or off, got '" + f.loop_closure + "'", "--loop-closure");
    st->loop_closure = f.loop_closure == "on";
  }
  ResolveGnss(f, st);
  cli::ThrowIfCheckFailed(st->Check());
}

}  // namespace

int RunVio(int argc, char** argv) {
  CLI::App command{
      "Stereo visual-inertial odometry (Ceres sliding window) on a EuRoC/ASL dataset or an AirSim "
      "recording (stereo-only)",
      "optinav vio"};
  app::VioRunSettings st;
  VioFlags flags;
  AddRunOptions(command, &st, &flags);
  AddGnssOptions(command, &st, &flags);
  return cli::RunCli(command, argc, argv, [&] {
    Resolve(flags, &st);
    const app::VioRunReport report = app::RunVioDataset(st);
    std::fputs(app::FormatVioSummary(st, report).c_str(), stdout);
    if (report.html) PrintHtmlReportLine(*report.html);
    return 0;
  });
}

}  // namespace optinav
