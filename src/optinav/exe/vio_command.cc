// optinav vio: stereo visual-inertial odometry on a EuRoC/ASL dataset.
#include <cmath>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "optinav/exe/cli_common.h"
#include "optinav/exe/commands.h"
#include "optinav/geo/geo.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/geo_export.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"
#include "optinav/vio/gnss_input.h"
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
  j["loop_closure"] = r.loop_closure_ran;
  nlohmann::json loops = nlohmann::json::array();
  for (const vio::LoopEdge& l : r.loops)
    loops.push_back({{"old_keyframe_s", l.t_old_ns * 1e-9},
                     {"new_keyframe_s", l.t_new_ns * 1e-9},
                     {"inliers", l.inliers},
                     {"relative_translation_m", l.old_body_from_new_body.translation.norm()},
                     {"correction_m", l.correction_m}});
  j["loops"] = loops;
  if (!r.gnss_stats.received) return j;
  const vio::GnssFusionStats& g = r.gnss_stats;
  j["gnss"] = {{"received", g.received},
               {"factors", g.factors},
               {"rejected", g.rejected},
               {"alignments", g.alignments},
               {"drift_inflations", g.drift_inflations},
               {"smoothed_tracks", r.gnss_smoothing.tracks_smoothed},
               {"smoothed_samples", r.gnss_smoothing.samples},
               {"smoother_solve_s", r.gnss_smoothing.solve_s},
               {"aligned_at_s", g.aligned_at_ns ? nlohmann::json(*g.aligned_at_ns * 1e-9)
                                                : nlohmann::json(nullptr)}};
  return j;
}

std::string StemOf(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path;
  return path.substr(0, dot);
}

// The rejected samples with their reason.
std::string RejectedCsv(const std::vector<vio::RejectedGnss>& rejected) {
  std::string s = "#timestamp [ns], x [m], y [m], z [m], innovation [m], reason\n";
  for (const vio::RejectedGnss& r : rejected)
    s += fmt::format("{},{:.4f},{:.4f},{:.4f},{:.3f},\"{}\"\n", r.t_ns, r.position_enu_m.x(),
                     r.position_enu_m.y(), r.position_enu_m.z(), r.innovation_m, r.reason);
  return s;
}

// WGS84 csv and GeoJSON LineString of an ENU trajectory.
void WriteWgs84(const Trajectory& enu, const Eigen::Vector3d& origin, const std::string& csv_path,
                const std::string& geojson_path) {
  const geo::LocalEnu frame(geo::LatLon{origin[0], origin[1]}, origin[2]);
  std::string csv = "#timestamp [ns], latitude [deg], longitude [deg], height [m]\n";
  report::GeoLine line;
  line.name = "optinav vio (GNSS fused)";
  line.properties["origin"] = fmt::format("{:.9f},{:.9f},{:.3f}", origin[0], origin[1], origin[2]);
  for (size_t i = 0; i < enu.size(); ++i) {
    double h = 0;
    const geo::LatLon ll = frame.FromEnu(enu.pose(i).translation, &h);
    csv += fmt::format("{},{:.10f},{:.10f},{:.4f}\n", enu.t_ns[i], ll.lat_deg, ll.lon_deg, h);
    line.points.push_back(ll);
  }
  io::WriteFileAtomically(csv_path, csv);
  io::WriteFileAtomically(geojson_path, report::ToGeoJson({line}, {}));
}

}  // namespace

int RunVio(int argc, char** argv) {
  CLI::App app{
      "Stereo visual-inertial odometry (Ceres sliding window) on a EuRoC/ASL dataset or an AirSim "
      "recording (stereo-only)",
      "optinav vio"};
  std::string dataset, format = "euroc", config, out, camera_out, stats, mode_name,
                       log_level = "info", loop_closure, odometry_out;
  bool sequential = false;
  size_t max_frames = 0;
  bool gnss = false;
  std::string gnss_file, gnss_format = "auto", gnss_norm = "huber", gnss_time = "exact",
                         gnss_origin, gnss_lever, gnss_walk, gnss_drift, wgs84_out, geojson_out,
                         rejected_out, gnss_live_out;
  bool gnss_no_smooth = false;
  double gnss_norm_param = -1, gnss_sigma = -1, gnss_gate = -1, gnss_init_distance = -1,
         gnss_factor_scale = -1, gnss_smooth_walk_scale = -1;
  double gnss_init_yaw_sigma = -1;
  app.add_option("--dataset", dataset, "sequence folder (holding mav0/)")->required();
  app.add_option("--format", format, "dataset format: euroc|airsim (airsim: stereo-only)")
      ->capture_default_str();
  app.add_option("--config", config, "YAML options (see config/vio_euroc.yaml); defaults built in");
  app.add_option("--out", out, "output trajectory of the body (IMU) frame, TUM")->required();
  app.add_option("--camera-out", camera_out, "also write the left camera's trajectory, TUM");
  app.add_option("--stats", stats,
                 "timing per module (median, p95 per frame) and lost intervals, JSON");
  app.add_option("--mode", mode_name, "stereo-imu|stereo (default: the config's, else stereo-imu)");
  app.add_option("--loop-closure", loop_closure,
                 "on|off: close loops with earlier keyframes and correct the output (default: "
                 "the config's: on in stereo mode, off in stereo-imu mode; never with --gnss)");
  app.add_option("--odometry-out", odometry_out,
                 "also write the body trajectory before the loop corrections, TUM");
  app.add_flag("--sequential", sequential,
               "run in one thread, deterministic (default: loader, frontend and backend threads; "
               "close to, not identical with, the sequential results)");
  app.add_option("--max-frames", max_frames, "process only the first N stereo frames (0: all)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str();
  app.add_flag("--gnss", gnss,
               "fuse GNSS positions (stereo-imu); --out is then in the ENU frame of the GNSS "
               "origin");
  app.add_option("--gnss-file", gnss_file,
                 "GNSS csv (default DIR/mav0/gnss0/data.csv): t_ns,x,y,z ENU or "
                 "t_ns,lat,lon,height, optional sigma column");
  app.add_option("--gnss-format", gnss_format, "auto|enu|llh (auto: from the header)")
      ->capture_default_str();
  app.add_option("--gnss-norm", gnss_norm, "l2|huber|tukey")->capture_default_str();
  app.add_option("--gnss-norm-param", gnss_norm_param,
                 "norm parameter in sigmas (default huber 2.5, tukey 5)");
  app.add_option("--gnss-sigma", gnss_sigma,
                 "GNSS sigma per axis, m (default: gnss0/sensor.yaml sigma_m, else 1)");
  app.add_option("--gnss-origin", gnss_origin,
                 "ENU origin LAT,LON,HEIGHT (default: gnss0/sensor.yaml, else the first fix)");
  app.add_option("--gnss-lever-arm", gnss_lever,
                 "antenna in the body frame X,Y,Z, m (default: gnss0/sensor.yaml T_BS)");
  app.add_option("--gnss-time", gnss_time,
                 "exact (factor at the sample time) | frame (the document's interpolation to "
                 "frame times)")
      ->capture_default_str();
  app.add_option("--gnss-gate", gnss_gate,
                 "chi-square gate, 3 DoF (default 16.27 = 99.9 %; 0: off)");
  app.add_option("--gnss-init-yaw-sigma", gnss_init_yaw_sigma,
                 fmt::format("yaw sigma (deg) the ENU alignment waits for (default {:g}; smaller: "
                             "a later but steadier alignment)",
                             vio::GnssFusionOptions{}.init_max_yaw_sigma_rad * 180 / M_PI));
  app.add_option("--gnss-init-distance", gnss_init_distance,
                 fmt::format("horizontal distance before the ENU alignment is initialised, m "
                             "(default {:g})",
                             vio::GnssFusionOptions{}.init_min_distance_m));
  app.add_option("--gnss-factor-scale", gnss_factor_scale,
                 fmt::format("GNSS factor sigma x this (the gate is not scaled; default {:g})",
                             vio::GnssFusionOptions{}.factor_sigma_scale));
  app.add_option("--gnss-walk", gnss_walk,
                 "VIO drift vs ENU as a random walk of the alignment per metre travelled: "
                 "M_PER_SQRT_M,RAD_PER_SQRT_M (default from GnssFusionOptions)");
  app.add_option("--gnss-drift-test", gnss_drift,
                 "drift detection on the mean innovation: SAMPLES,CHI2 (CHI2 0: off; default "
                 "from GnssFusionOptions)");
  app.add_flag("--gnss-no-smooth", gnss_no_smooth,
               "output the live estimate (each frame through the ENU alignment known right after "
               "it) instead of the one smoothed over the whole run");
  app.add_option("--gnss-smooth-walk-scale", gnss_smooth_walk_scale,
                 "the smoother's random walk = the alignment walk (--gnss-walk) x this (default 1; "
                 "raise it for a VIO that drifts more)");
  app.add_option("--gnss-live-out", gnss_live_out,
                 "the live estimate in ENU, TUM (default with smoothing: TRAJ.live.tum)");
  app.add_option("--wgs84-out", wgs84_out,
                 "fused trajectory in WGS84 csv (default TRAJ.wgs84.csv)");
  app.add_option("--geojson-out", geojson_out,
                 "fused trajectory as GeoJSON (default TRAJ.geojson)");
  app.add_option("--gnss-rejected-out", rejected_out,
                 "rejected GNSS samples with their reason (default TRAJ.gnss_rejected.csv)");
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
  if (!loop_closure.empty() && loop_closure != "on" && loop_closure != "off") {
    spdlog::error("--loop-closure: expected on or off, got '{}'", loop_closure);
    return 2;
  }
  std::optional<vio::GnssNorm> norm = vio::ParseGnssNorm(gnss_norm);
  std::optional<vio::GnssTimeMode> time_mode = vio::ParseGnssTimeMode(gnss_time);
  if (!norm) {
    spdlog::error("--gnss-norm: unknown norm '{}' (l2|huber|tukey)", gnss_norm);
    return 2;
  }
  if (!time_mode) {
    spdlog::error("--gnss-time: unknown mode '{}' (exact|frame)", gnss_time);
    return 2;
  }
  if (gnss_format != "auto" && gnss_format != "enu" && gnss_format != "llh") {
    spdlog::error("--gnss-format: unknown format '{}' (auto|enu|llh)", gnss_format);
    return 2;
  }
  try {
    vio::VioRunOptions options;
    if (!config.empty()) options.vio = vio::LoadVioOptions(config);
    if (mode) options.vio.mode = *mode;
    if (format == "airsim" && !mode) options.vio.mode = vio::VioMode::kStereo;  // no IMU in AirSim
    if (!loop_closure.empty()) {
      (options.vio.mode == vio::VioMode::kStereo ? options.vio.loop_closure.stereo_only
                                                 : options.vio.loop_closure.stereo_imu) =
          loop_closure == "on";
      if (loop_closure == "on" && gnss)
        throw Error("loop closure does not run with GNSS fusion", {.field = "--loop-closure"});
    }
    options.threaded = !sequential;
    options.max_frames = max_frames;
    std::optional<vio::GnssInput> gnss_input;
    if (gnss) {
      if (options.vio.mode != vio::VioMode::kStereoImu || format != "euroc")
        throw Error("GNSS fusion needs a EuRoC dataset in stereo-imu mode", {.field = "--gnss"});
      vio::GnssInputOptions in;
      in.file = gnss_file;
      if (gnss_format == "enu") in.kind = io::GnssFileKind::kEnu;
      if (gnss_format == "llh") in.kind = io::GnssFileKind::kLatLonHeight;
      if (!gnss_origin.empty())
        in.origin_lat_lon_height = ParseTriple(gnss_origin, "--gnss-origin");
      if (!gnss_lever.empty()) in.lever_arm_in_body = ParseTriple(gnss_lever, "--gnss-lever-arm");
      if (gnss_sigma != -1) {
        if (!(gnss_sigma > 0))
          throw Error(fmt::format("must be > 0, got {}", gnss_sigma), {.field = "--gnss-sigma"});
        in.sigma_m = gnss_sigma;
      }
      gnss_input = vio::LoadGnssInput(dataset, in);
      vio::GnssFusionOptions g;
      g.norm = *norm;
      if (gnss_norm_param != -1) {
        if (!(gnss_norm_param > 0))
          throw Error(fmt::format("must be > 0, got {}", gnss_norm_param),
                      {.field = "--gnss-norm-param"});
        g.norm_parameter = gnss_norm_param;
      }
      g.time_mode = *time_mode;
      g.lever_arm_in_body = gnss_input->lever_arm_in_body;
      if (gnss_gate != -1) g.gate_chi2 = gnss_gate;
      if (gnss_init_distance != -1) g.init_min_distance_m = gnss_init_distance;
      if (gnss_factor_scale != -1) g.factor_sigma_scale = gnss_factor_scale;
      g.smooth = !gnss_no_smooth;
      if (gnss_smooth_walk_scale != -1) g.smooth_walk_scale = gnss_smooth_walk_scale;
      if (gnss_init_yaw_sigma != -1) {
        if (!(gnss_init_yaw_sigma > 0))
          throw Error("must be > 0 (degrees)", {.field = "--gnss-init-yaw-sigma"});
        g.init_max_yaw_sigma_rad = gnss_init_yaw_sigma * M_PI / 180;
      }
      if (!gnss_drift.empty()) {
        const std::vector<double> v =
            ParseNumbers(gnss_drift, 2, "SAMPLES,CHI2", "--gnss-drift-test");
        if (v[0] != std::floor(v[0]) || !(v[0] >= 1))
          throw Error(fmt::format("SAMPLES must be a whole number >= 1, got {}", v[0]),
                      {.field = "--gnss-drift-test"});
        g.drift_window_samples = static_cast<int>(v[0]);
        g.drift_test_chi2 = v[1];
      }
      if (!gnss_walk.empty()) {
        const std::vector<double> v =
            ParseNumbers(gnss_walk, 2, "M_PER_SQRT_M,RAD_PER_SQRT_M", "--gnss-walk");
        g.alignment_walk_m_per_sqrt_m = v[0];
        g.alignment_walk_rad_per_sqrt_m = v[1];
      }
      if (const std::string e = g.Check(); !e.empty()) throw Error(e, {.field = "--gnss"});
      options.gnss = g;
      options.gnss_samples = gnss_input->samples;
      spdlog::info("gnss: {} samples from {} (sigma {:.2f} m, norm {}, time {})",
                   gnss_input->samples.size(), gnss_input->file, gnss_input->default_sigma_m,
                   gnss_norm, gnss_time);
    }
    const vio::VioRunResult r = format == "airsim" ? vio::RunVioOnAirsim(dataset, options)
                                                   : vio::RunVioOnEuroc(dataset, options);
    if (r.estimates.empty())
      throw Error("no pose estimated (never initialised: no stereo features or no IMU window)",
                  {.file = dataset});
    Trajectory body = vio::EstimatesToTrajectory(r.estimates);
    std::string frame = "world";
    if (gnss) {
      Trajectory enu = vio::EstimatesToEnuTrajectory(r.estimates, r.gnss_smoothing.enu_from_world);
      if (enu.empty()) {
        spdlog::warn(
            "gnss: the ENU alignment was never initialised (too little horizontal motion or no "
            "usable GNSS): {} is in the VIO world frame",
            out);
      } else {
        body = std::move(enu);
        frame = "enu";
      }
    }
    io::WriteTrajectory(out, body, io::TrajectoryFormat::kTum);
    if (!odometry_out.empty())
      io::WriteTrajectory(odometry_out,
                          vio::EstimatesToTrajectory(r.odometry.empty() ? r.estimates : r.odometry),
                          io::TrajectoryFormat::kTum);
    if (!r.loops.empty())
      std::printf("loop closure: %zu loop(s) closed, the output is corrected%s\n", r.loops.size(),
                  odometry_out.empty() ? " (--odometry-out writes it before)" : "");
    if (!camera_out.empty()) {
      const Trajectory c = frame == "enu"
                               ? vio::EstimatesToEnuTrajectory(
                                     r.estimates, r.gnss_smoothing.enu_from_world, r.body_from_cam0)
                               : vio::EstimatesToTrajectory(r.estimates, r.body_from_cam0);
      io::WriteTrajectory(camera_out, c, io::TrajectoryFormat::kTum);
    }
    if (gnss) {
      const std::string stem = StemOf(out);
      if (rejected_out.empty()) rejected_out = stem + ".gnss_rejected.csv";
      io::WriteFileAtomically(rejected_out, RejectedCsv(r.gnss_rejected));
      // The live estimate beside the smoothed one (by default only when they differ).
      if (frame == "enu" && gnss_live_out.empty() && r.gnss_smoothing.tracks_smoothed)
        gnss_live_out = stem + ".live.tum";
      if (frame != "enu" && !gnss_live_out.empty())
        spdlog::warn("gnss: no ENU alignment: {} not written", gnss_live_out);
      else if (!gnss_live_out.empty())
        io::WriteTrajectory(gnss_live_out, vio::EstimatesToEnuTrajectory(r.estimates),
                            io::TrajectoryFormat::kTum);
      if (frame == "enu" && gnss_input->origin_lat_lon_height) {
        if (wgs84_out.empty()) wgs84_out = stem + ".wgs84.csv";
        if (geojson_out.empty()) geojson_out = stem + ".geojson";
        WriteWgs84(body, *gnss_input->origin_lat_lon_height, wgs84_out, geojson_out);
      } else if (frame == "enu") {
        spdlog::warn("gnss: no ENU origin known (give --gnss-origin): no WGS84 output");
      }
      const vio::GnssFusionStats& g = r.gnss_stats;
      std::printf("gnss: %zu samples, %zu factors, %zu rejected (-> %s), %s\n", g.received,
                  g.factors, g.rejected, rejected_out.c_str(),
                  frame == "enu" ? ("trajectory in ENU" +
                                    std::string(r.gnss_smoothing.tracks_smoothed
                                                    ? " (smoothed over the run; live estimate -> " +
                                                          gnss_live_out + ")"
                                                    : "") +
                                    (wgs84_out.empty() ? std::string() : ", WGS84 -> " + wgs84_out))
                                       .c_str()
                                 : "trajectory in the VIO world frame (no alignment)");
    }
    const std::string mode_used = vio::VioModeName(options.vio.mode);
    if (!stats.empty()) {
      nlohmann::json j = StatsJson(r, mode_used);
      j["frame"] = frame;
      io::WriteFileAtomically(stats, j.dump(2) + "\n");
    }
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
