// The VIO run behind `optinav vio`: loads the options, runs vio::RunVioOnEuroc / RunVioOnAirsim
// (optionally fusing GNSS) and writes the trajectory, the camera and pre-loop-closure
// trajectories, the statistics JSON and, with GNSS, the side outputs (rejected samples, the live
// estimate, WGS84 csv, GeoJSON, the HTML report's document TRAJ.report.json). Every file is
// written atomically.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "optinav/app/html_report.h"
#include "optinav/vio/gnss_input.h"
#include "optinav/vio/pipeline.h"

namespace optinav::app {

enum class VioDatasetFormat { kEuroc, kAirsim };

// The platform's motion model (`optinav vio --vehicle`). kGround: a wheeled ground vehicle, whose
// body-frame vertical velocity is ~ N(0, (kGroundVehicleVerticalSigmaMs)^2) on every state
// (vio::BackendOptions::ground_vehicle_vertical_sigma_m_s, stereo-imu only) unless the config sets
// a ground-vehicle sigma itself. kFree: no motion model (a drone, a handheld rig). kAuto: kGround
// when the dataset is a simulator car route (its sim_complete.json says "route": "car"), else
// kFree. On a car the IMU cannot tell a slow vertical velocity error from none, and vision with
// near points only (fog) lets the height drift (docs/VIO.md, weather, 2026-12-03). kGround also
// gates the landmarks on the IMU-predicted pose (vio::BackendOptions::predicted_gate_pixels
// kGroundVehicleGatePixels, widened to kGroundVehicleGateMedianFactor x the frame's median
// predicted error) unless the config sets a gate: falling leaves and snow drift through the
// scene with the wind, and a car's smooth motion is predicted well enough to tell them apart
// (measured on the simulator's car routes only, docs/VIO.md, weather, 2026-12-03 later).
enum class VehicleModel { kAuto, kGround, kFree };
inline constexpr double kGroundVehicleVerticalSigmaMs = 0.05;
inline constexpr double kGroundVehicleGatePixels = 2.0;
inline constexpr double kGroundVehicleGateMedianFactor = 2.0;
// The ground vehicle's defaults in `backend`: the vertical-velocity sigma unless a ground-vehicle
// sigma is set, the gate unless predicted_gate_pixels is set (and its median factor unless set).
// What `--vehicle ground` does to a stereo-imu run (MakeRunOptions; bench/vio_bench.cc).
void ApplyGroundVehicleDefaults(vio::BackendOptions* backend);
std::optional<VehicleModel> ParseVehicleModel(const std::string& name);  // auto|ground|free
const char* VehicleModelName(VehicleModel model);
// kAuto resolved for `dataset` (kGround or kFree); the others as given. Throws Error naming the
// file when a sim_complete.json is there but unreadable.
VehicleModel ResolveVehicleModel(VehicleModel model, const std::string& dataset);

struct VioRunSettings {
  std::string dataset;  // sequence folder (holding mav0/, or an AirSim recording)
  VioDatasetFormat format = VioDatasetFormat::kEuroc;
  std::string config_path;           // YAML vio::VioOptions; empty: the built-in defaults
  std::optional<vio::VioMode> mode;  // nullopt: the config's (AirSim: stereo, it has no IMU)
  std::optional<bool> loop_closure;  // nullopt: the config's for the mode
  VehicleModel vehicle = VehicleModel::kAuto;
  bool sequential = false;               // one thread, deterministic
  size_t max_frames = 0;                 // 0: all
  double injected_backend_delay_ms = 0;  // testing: vio::VioRunOptions::injected_backend_delay_ms

  // Outputs: the body (IMU) trajectory, TUM (required); the others are optional (empty: none).
  std::string out, camera_out, odometry_out, stats_path;

  // GNSS fusion (EuRoC, stereo-imu). The fusion's lever arm comes from the input.
  bool gnss = false;
  vio::GnssInputOptions gnss_input;
  vio::GnssFusionOptions gnss_fusion;
  // GNSS side outputs; empty: beside `out` (TRAJ.gnss_rejected.csv; TRAJ.live.tum when the output
  // is smoothed; TRAJ.wgs84.csv and TRAJ.geojson when the ENU origin is known).
  std::string gnss_live_out, wgs84_out, geojson_out, gnss_rejected_out;
  // With GNSS, the HTML report's document is always written (TRAJ.report.json); html: also
  // render TRAJ.report.html (app/html_report.h) at the end.
  bool html = false;

  // Empty when valid, else a message that starts with the flag at fault ("--gnss-sigma ...").
  std::string Check() const;
};

struct VioRunReport {
  vio::VioRunResult run;
  std::string mode;     // the mode that ran: "stereo-imu" | "stereo"
  std::string vehicle;  // the motion model that ran: "ground" | "free"
  // The gate on the IMU-predicted pose that ran (vio::BackendOptions::predicted_gate_*; 0: off).
  double predicted_gate_px = 0, predicted_gate_median_factor = 0;
  // Every VIO option the run used (config, mode, vehicle defaults, --loop-closure), as
  // vio::VioOptionsYaml: a config file that reproduces the run.
  std::string vio_options_yaml;
  std::string frame = "world";  // of `out`: "world", or "enu" once GNSS aligned it
  // The GNSS side outputs as resolved (defaults beside `out`); live: empty when not written.
  std::string gnss_live_out, wgs84_out, gnss_rejected_out;
  std::string report_document;           // TRAJ.report.json (GNSS runs)
  std::optional<HtmlReportResult> html;  // when settings.html
};

// Throws Error on invalid settings (Check()), bad input (naming file/line/field), a GNSS request
// the dataset or mode cannot serve, and when no pose was estimated.
VioRunReport RunVioDataset(const VioRunSettings& settings);

// VioRunReport::vio_options_yaml of a run with `settings`, without running it (reads the config
// and, for --vehicle auto, the dataset's sim_complete.json; not the GNSS input).
std::string EffectiveVioOptionsYaml(const VioRunSettings& settings);

// What `optinav vio` prints on stdout: the loop-closure line, the GNSS line, the summary line.
std::string FormatVioSummary(const VioRunSettings& settings, const VioRunReport& report);

// The statistics JSON (--stats): frames, poses, initialisation, timing per stage, lost
// intervals, loops, GNSS counts, the effective options ("vio_options_yaml").
nlohmann::json VioStatsJson(const VioRunReport& report);

}  // namespace optinav::app
