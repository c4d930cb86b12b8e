#include "optinav/app/vio_run.h"

#include <algorithm>
#include <filesystem>
#include <map>

#include <fmt/format.h>

#include "optinav/eval/metrics.h"
#include "optinav/geo/geo.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/geo_export.h"
#include "optinav/report/html_report.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"

namespace optinav::app {
namespace fs = std::filesystem;
namespace {

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

// The pipeline's options from the settings (config file, mode, vehicle, loop closure, GNSS
// input); `vehicle`: the motion model resolved.
vio::VioRunOptions MakeRunOptions(const VioRunSettings& st,
                                  std::optional<vio::GnssInput>* gnss_input,
                                  VehicleModel* vehicle) {
  vio::VioRunOptions options;
  if (!st.config_path.empty()) options.vio = vio::LoadVioOptions(st.config_path);
  if (st.mode) options.vio.mode = *st.mode;
  // AirSim recordings have no IMU.
  if (st.format == VioDatasetFormat::kAirsim && !st.mode) options.vio.mode = vio::VioMode::kStereo;
  // After the mode is settled: an AirSim recording runs stereo-only.
  *vehicle = ResolveVehicleModel(st.vehicle, st.dataset);
  if (options.vio.mode == vio::VioMode::kStereo && *vehicle == VehicleModel::kGround) {
    // Stereo-only states have no velocity to constrain; the constraint between consecutive
    // states is opt-in (it turned the stereo odometry's translation-direction bias into a yaw
    // drift on the car route, docs/VIO.md, weather, 2026-12-05 evening).
    if (st.vehicle == VehicleModel::kGround)
      spdlog::warn(
          "--vehicle ground sets no default in stereo mode; backend.ground_vehicle_*_sigma_m_s "
          "in the config constrain the motion between consecutive states");
    *vehicle = VehicleModel::kFree;
  }
  if (*vehicle == VehicleModel::kGround) ApplyGroundVehicleDefaults(&options.vio.backend);
  if (st.loop_closure) {
    (options.vio.mode == vio::VioMode::kStereo ? options.vio.loop_closure.stereo_only
                                               : options.vio.loop_closure.stereo_imu) =
        *st.loop_closure;
  }
  options.threaded = !st.sequential;
  options.max_frames = st.max_frames;
  options.injected_backend_delay_ms = st.injected_backend_delay_ms;
  if (!st.gnss) return options;
  if (options.vio.mode != vio::VioMode::kStereoImu || st.format != VioDatasetFormat::kEuroc)
    throw Error("GNSS fusion needs a EuRoC dataset in stereo-imu mode", {.field = "--gnss"});
  *gnss_input = vio::LoadGnssInput(st.dataset, st.gnss_input);
  vio::GnssFusionOptions g = st.gnss_fusion;
  g.lever_arm_in_body = (*gnss_input)->lever_arm_in_body;
  options.gnss = g;
  options.gnss_samples = (*gnss_input)->samples;
  spdlog::info("gnss: {} samples from {} (sigma {:.2f} m, norm {}, time {})",
               (*gnss_input)->samples.size(), (*gnss_input)->file, (*gnss_input)->default_sigma_m,
               vio::GnssNormName(g.norm), vio::GnssTimeModeName(g.time_mode));
  return options;
}

// The output trajectory: the body in the VIO world frame, or in ENU once GNSS aligned it.
Trajectory OutputTrajectory(const VioRunSettings& st, VioRunReport* report) {
  const vio::VioRunResult& r = report->run;
  if (!st.gnss) return vio::EstimatesToTrajectory(r.estimates);
  Trajectory enu = vio::EstimatesToEnuTrajectory(r.estimates, r.gnss_smoothing.enu_from_world);
  if (enu.empty()) {
    spdlog::warn(
        "gnss: the ENU alignment was never initialised (too little horizontal motion or no "
        "usable GNSS): {} is in the VIO world frame",
        st.out);
    return vio::EstimatesToTrajectory(r.estimates);
  }
  report->frame = "enu";
  return enu;
}

void WriteTrajectories(const VioRunSettings& st, const VioRunReport& report,
                       const Trajectory& body) {
  const vio::VioRunResult& r = report.run;
  io::WriteTrajectory(st.out, body, io::TrajectoryFormat::kTum);
  if (!st.odometry_out.empty()) {
    io::WriteTrajectory(st.odometry_out,
                        vio::EstimatesToTrajectory(r.odometry.empty() ? r.estimates : r.odometry),
                        io::TrajectoryFormat::kTum);
  }
  if (!st.camera_out.empty()) {
    const Trajectory c = report.frame == "enu"
                             ? vio::EstimatesToEnuTrajectory(
                                   r.estimates, r.gnss_smoothing.enu_from_world, r.body_from_cam0)
                             : vio::EstimatesToTrajectory(r.estimates, r.body_from_cam0);
    io::WriteTrajectory(st.camera_out, c, io::TrajectoryFormat::kTum);
  }
}

// Rejected samples, the live estimate beside the smoothed one, WGS84 csv and GeoJSON.
void WriteGnssOutputs(const VioRunSettings& st, const vio::GnssInput& input, const Trajectory& body,
                      VioRunReport* report) {
  const vio::VioRunResult& r = report->run;
  const bool enu = report->frame == "enu";
  const std::string stem = StemOf(st.out);
  report->gnss_rejected_out =
      st.gnss_rejected_out.empty() ? stem + ".gnss_rejected.csv" : st.gnss_rejected_out;
  io::WriteFileAtomically(report->gnss_rejected_out, RejectedCsv(r.gnss_rejected));
  // By default the live estimate is written only when it differs (smoothed output).
  report->gnss_live_out = st.gnss_live_out;
  if (enu && report->gnss_live_out.empty() && r.gnss_smoothing.tracks_smoothed)
    report->gnss_live_out = stem + ".live.tum";
  if (!enu && !report->gnss_live_out.empty()) {
    spdlog::warn("gnss: no ENU alignment: {} not written", report->gnss_live_out);
  } else if (!report->gnss_live_out.empty()) {
    io::WriteTrajectory(report->gnss_live_out, vio::EstimatesToEnuTrajectory(r.estimates),
                        io::TrajectoryFormat::kTum);
  }
  report->wgs84_out = st.wgs84_out;
  if (enu && input.origin_lat_lon_height) {
    if (report->wgs84_out.empty()) report->wgs84_out = stem + ".wgs84.csv";
    const std::string geojson = st.geojson_out.empty() ? stem + ".geojson" : st.geojson_out;
    WriteWgs84(body, *input.origin_lat_lon_height, report->wgs84_out, geojson);
  } else if (enu) {
    spdlog::warn("gnss: no ENU origin known (give --gnss-origin): no WGS84 output");
  }
}

// [north, east] of every k-th pose (Leaflet's order in a local view).
std::vector<Eigen::Vector2d> LocalPoints(const Trajectory& t) {
  constexpr size_t kMaxPoints = 2000;
  std::vector<Eigen::Vector2d> pts;
  const size_t step = std::max<size_t>(1, t.size() / kMaxPoints);
  for (size_t i = 0; i < t.size(); i += step)
    pts.emplace_back(t.positions[i].y(), t.positions[i].x());
  return pts;
}

// TRAJ.report.json: the output, the live estimate and the dataset's ground truth (when it has
// one) in the local ENU frame, every GNSS sample as a fix (its error against the truth's antenna
// position, else its residual to the output; rejected ones with their reason), the error over
// time; the figures and the settings.
void WriteGnssReportDocument(const VioRunSettings& st, const vio::GnssInput& input,
                             const Trajectory& body, VioRunReport* report) {
  const vio::VioRunResult& r = report->run;
  report::ReportView v;
  v.name = "trajectories in the local ENU frame of the GNSS origin (metres)";
  v.frame = "local";
  const bool enu = report->frame == "enu";
  std::optional<Trajectory> truth;
  const std::string truth_path = st.dataset + "/mav0/state_groundtruth_estimate0/data.csv";
  if (std::filesystem::is_regular_file(truth_path)) {
    try {
      truth = io::ReadTrajectory(truth_path);
    } catch (const Error& e) {
      spdlog::warn("report: ground truth not shown: {}", e.what());
    }
  }
  if (truth && !truth->empty())
    v.paths.push_back(
        {"ground truth", "ground truth (the dataset's)", "#14a03c", 3, false, LocalPoints(*truth)});
  if (enu) {
    v.paths.push_back(
        {"output (smoothed)", "output: " + st.out, "#e66e14", 2, false, LocalPoints(body)});
    v.paths.push_back({"live estimate", "live estimate", "#1f77b4", 1.5, true,
                       LocalPoints(vio::EstimatesToEnuTrajectory(r.estimates))});
  }
  std::map<int64_t, std::string> rejected;
  for (const vio::RejectedGnss& g : r.gnss_rejected) rejected.emplace(g.t_ns, g.reason);
  const Trajectory& reference = truth && !truth->empty() ? *truth : body;
  const bool vs_truth = truth && !truth->empty();
  const int64_t t0 = reference.empty() ? 0 : reference.t_ns.front();
  report::ReportChart chart{"error over time (no alignment)", "time (s)", "error (m)", {}};
  report::ReportSeries dots{
      vs_truth ? "GNSS sample error" : "GNSS residual to the output", "#c828c8", {}, {}, true};
  for (const vio::GnssSample& s : input.samples) {
    const auto pose = reference.InterpolateAt(s.t_ns);
    const double error_m = pose && (vs_truth || enu)
                               ? (s.position_enu_m - *pose * input.lever_arm_in_body).norm()
                               : NAN;
    const double t_s = (s.t_ns - t0) * 1e-9;
    const auto it = rejected.find(s.t_ns);
    v.fixes.push_back({"GNSS samples", fmt::format("GNSS sample at {:.1f} s", t_s),
                       Eigen::Vector2d(s.position_enu_m.y(), s.position_enu_m.x()), t_s, error_m,
                       vs_truth ? "gnss (error to the truth)" : "gnss (residual to the output)", -1,
                       it == rejected.end(), it == rejected.end() ? "" : it->second});
    dots.x.push_back(t_s);
    dots.y.push_back(error_m);
  }
  chart.series.push_back(std::move(dots));
  v.fix_error_scale_m = 3 * input.default_sigma_m + 1;  // red: beyond what the noise explains
  if (vs_truth && enu) {
    const eval::SyncedPair synced = eval::Synchronize(*truth, body);
    const eval::ErrorSeries e =
        eval::ComputeApe(synced.ref, synced.est, eval::PoseRelation::kTranslation);
    report::ReportSeries line{"output error", "#e66e14", {}, {}, false};
    for (size_t i = 0; i < e.errors.size(); ++i) {
      line.x.push_back((synced.ref.t_ns[e.indices[i]] - t0) * 1e-9);
      line.y.push_back(e.errors[i]);
    }
    chart.series.push_back(std::move(line));
  }
  v.chart = std::move(chart);
  const Trajectory& start_end = enu ? body : reference;
  if (!start_end.empty()) {
    v.markers.push_back({"start / end", "start", "start", LocalPoints(start_end).front()});
    const Eigen::Vector3d end = start_end.positions.back();
    v.markers.push_back({"start / end", "end", "end", {end.y(), end.x()}});
  }
  report::ReportDocument doc;
  doc.kind = "vio gnss";
  doc.title = "optinav vio --gnss: " + st.dataset;
  const std::string summary = FormatVioSummary(st, *report);
  for (size_t a = 0, b; a < summary.size(); a = b + 1) {
    b = summary.find('\n', a);
    if (b == std::string::npos) b = summary.size();
    if (b > a) doc.notes.push_back(summary.substr(a, b - a));
  }
  if (!enu) doc.notes.push_back("the ENU alignment was never made: no output path is drawn");
  doc.views.push_back(std::move(v));
  const vio::GnssFusionStats& g = r.gnss_stats;
  doc.tables.push_back({"GNSS fusion",
                        {"figure", "value"},
                        {{"samples", std::to_string(g.received)},
                         {"factors", std::to_string(g.factors)},
                         {"rejected", std::to_string(g.rejected)},
                         {"alignments", std::to_string(g.alignments)},
                         {"poses", std::to_string(r.estimates.size())},
                         {"lost intervals", std::to_string(r.lost.size())},
                         {"output frame", report->frame}}});
  doc.settings = {
      {"dataset", st.dataset},
      {"out", st.out},
      {"gnss_file", input.file},
      {"norm", vio::GnssNormName(st.gnss_fusion.norm)},
      {"time_mode", vio::GnssTimeModeName(st.gnss_fusion.time_mode)},
      {"default_sigma_m", input.default_sigma_m},
      {"lever_arm_in_body_m",
       {input.lever_arm_in_body.x(), input.lever_arm_in_body.y(), input.lever_arm_in_body.z()}},
      {"stats", VioStatsJson(*report)}};
  if (input.origin_lat_lon_height)
    doc.settings["enu_origin_lat_lon_height"] = {(*input.origin_lat_lon_height)[0],
                                                 (*input.origin_lat_lon_height)[1],
                                                 (*input.origin_lat_lon_height)[2]};
  report->report_document = StemOf(st.out) + ".report.json";
  report::WriteReportDocument(report->report_document, doc);
}

}  // namespace

void ApplyGroundVehicleDefaults(vio::BackendOptions* backend) {
  vio::BackendOptions& b = *backend;
  if (b.ground_vehicle_lateral_sigma_m_s == 0 && b.ground_vehicle_vertical_sigma_m_s == 0)
    b.ground_vehicle_vertical_sigma_m_s = kGroundVehicleVerticalSigmaMs;
  if (b.predicted_gate_pixels == 0) {
    b.predicted_gate_pixels = kGroundVehicleGatePixels;
    if (b.predicted_gate_median_factor == 0)
      b.predicted_gate_median_factor = kGroundVehicleGateMedianFactor;
  }
}

std::optional<VehicleModel> ParseVehicleModel(const std::string& name) {
  if (name == "auto") return VehicleModel::kAuto;
  if (name == "ground") return VehicleModel::kGround;
  if (name == "free") return VehicleModel::kFree;
  return std::nullopt;
}

const char* VehicleModelName(VehicleModel model) {
  switch (model) {
    case VehicleModel::kAuto:
      return "auto";
    case VehicleModel::kGround:
      return "ground";
    case VehicleModel::kFree:
      break;
  }
  return "free";
}

VehicleModel ResolveVehicleModel(VehicleModel model, const std::string& dataset) {
  if (model != VehicleModel::kAuto) return model;
  const fs::path marker = fs::path(dataset) / "sim_complete.json";
  if (!fs::is_regular_file(marker)) return VehicleModel::kFree;
  try {
    const nlohmann::json j = nlohmann::json::parse(io::ReadFileToString(marker.string()));
    return j.value("route", std::string()) == "car" ? VehicleModel::kGround : VehicleModel::kFree;
  } catch (const std::exception& e) {
    throw Error(std::string("cannot read the simulator's route (--vehicle auto): ") + e.what(),
                {.file = marker.string()});
  }
}

std::string VioRunSettings::Check() const {
  if (dataset.empty()) return "--dataset must be given";
  if (out.empty()) return "--out must be given";
  if (!(injected_backend_delay_ms >= 0 && injected_backend_delay_ms <= 10000))
    return fmt::format("--inject-backend-delay-ms must be in [0, 10000], got {}",
                       injected_backend_delay_ms);
  if (gnss && loop_closure.value_or(false)) return "--loop-closure cannot be on with GNSS fusion";
  if (html && !gnss) return "--html needs --gnss (the report shows the fused run)";
  // (A config file's stereo mode is found when the run loads it.)
  if (gnss && (format == VioDatasetFormat::kAirsim || mode == vio::VioMode::kStereo))
    return "--gnss fusion needs a EuRoC dataset in stereo-imu mode";
  if (gnss_input.sigma_m && !(*gnss_input.sigma_m > 0))
    return fmt::format("--gnss-sigma must be > 0, got {}", *gnss_input.sigma_m);
  if (const std::string m = gnss_fusion.Check(); gnss && !m.empty())
    return "--gnss fusion options: " + m;
  return "";
}

std::string EffectiveVioOptionsYaml(const VioRunSettings& settings) {
  VioRunSettings st = settings;
  st.gnss = false;  // the GNSS fusion options are not VIO options; no GNSS file is read
  std::optional<vio::GnssInput> gnss_input;
  VehicleModel vehicle = VehicleModel::kFree;
  return vio::VioOptionsYaml(MakeRunOptions(st, &gnss_input, &vehicle).vio);
}

VioRunReport RunVioDataset(const VioRunSettings& st) {
  if (const std::string m = st.Check(); !m.empty()) throw Error(m);
  if (st.html) report::LoadLeafletAssets();  // missing: say so before the run, not after
  std::optional<vio::GnssInput> gnss_input;
  VehicleModel vehicle = VehicleModel::kFree;
  const vio::VioRunOptions options = MakeRunOptions(st, &gnss_input, &vehicle);
  VioRunReport report;
  report.mode = vio::VioModeName(options.vio.mode);
  report.vehicle = VehicleModelName(vehicle);
  report.vio_options_yaml = vio::VioOptionsYaml(options.vio);
  if (options.vio.mode == vio::VioMode::kStereoImu) {
    report.predicted_gate_px = options.vio.backend.predicted_gate_pixels;
    report.predicted_gate_median_factor = options.vio.backend.predicted_gate_median_factor;
  }
  report.run = st.format == VioDatasetFormat::kAirsim ? vio::RunVioOnAirsim(st.dataset, options)
                                                      : vio::RunVioOnEuroc(st.dataset, options);
  if (report.run.estimates.empty())
    throw Error("no pose estimated (never initialised: no stereo features or no IMU window)",
                {.file = st.dataset});
  const Trajectory body = OutputTrajectory(st, &report);
  WriteTrajectories(st, report, body);
  if (st.gnss) WriteGnssOutputs(st, *gnss_input, body, &report);
  if (!st.stats_path.empty())
    io::WriteFileAtomically(st.stats_path, VioStatsJson(report).dump(2) + "\n");
  if (st.gnss) WriteGnssReportDocument(st, *gnss_input, body, &report);
  if (st.html) report.html = WriteHtmlReport(report.report_document);
  for (const vio::LostInterval& l : report.run.lost)
    spdlog::warn("lost {:.3f} s .. {:.3f} s: {}", l.start_ns * 1e-9, l.end_ns * 1e-9, l.reason);
  return report;
}

nlohmann::json VioStatsJson(const VioRunReport& report) {
  const vio::VioRunResult& r = report.run;
  nlohmann::json j;
  j["mode"] = report.mode;
  j["vehicle"] = report.vehicle;
  j["predicted_gate"] = {{"pixels", report.predicted_gate_px},
                         {"median_factor", report.predicted_gate_median_factor}};
  j["frame"] = report.frame;
  j["vio_options_yaml"] = report.vio_options_yaml;
  j["frames"] = r.frames_total;
  j["frames_processed"] = r.frames_processed;
  j["frames_unpaired"] = r.frames_unpaired;
  j["poses"] = r.estimates.size();
  j["initializations"] = r.initializations;
  j["frozen_frames"] = r.frozen_frames;
  j["imu_inflated_frames"] = r.imu_inflated_frames;
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
    loops.push_back(
        {{"old_keyframe_s", l.t_old_ns * 1e-9},
         {"new_keyframe_s", l.t_new_ns * 1e-9},
         {"inliers", l.inliers},
         {"relative_translation_m", l.old_body_from_new_body.translation.norm()},
         {"old_body_from_new_body",
          {l.old_body_from_new_body.translation.x(), l.old_body_from_new_body.translation.y(),
           l.old_body_from_new_body.translation.z(), l.old_body_from_new_body.rotation.x(),
           l.old_body_from_new_body.rotation.y(), l.old_body_from_new_body.rotation.z(),
           l.old_body_from_new_body.rotation.w()}},
         {"correction_m", l.correction_m},
         {"residual_m", l.residual_m},
         {"sigma_m", l.sigma_m},
         {"sigma_rad", l.sigma_rad}});
  j["loops"] = loops;
  if (r.loop_closure_ran) {
    j["loop_keyframes"] = r.loop_keyframes;
    j["loop_faded_keyframes"] = r.loop_faded_keyframes;
    j["loops_unsupported"] = r.loops_unsupported;
    j["loops_aliased"] = r.loops_aliased;
  }
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

std::string FormatVioSummary(const VioRunSettings& st, const VioRunReport& report) {
  const vio::VioRunResult& r = report.run;
  std::string s;
  if (!r.loops.empty()) {
    s += fmt::format("loop closure: {} loop(s) closed, the output is corrected{}\n", r.loops.size(),
                     st.odometry_out.empty() ? " (--odometry-out writes it before)" : "");
  }
  if (st.gnss) {
    std::string where = "trajectory in the VIO world frame (no alignment)";
    if (report.frame == "enu") {
      where = "trajectory in ENU";
      if (r.gnss_smoothing.tracks_smoothed)
        where += " (smoothed over the run; live estimate -> " + report.gnss_live_out + ")";
      if (!report.wgs84_out.empty()) where += ", WGS84 -> " + report.wgs84_out;
    }
    const vio::GnssFusionStats& g = r.gnss_stats;
    s += fmt::format("gnss: {} samples, {} factors, {} rejected (-> {}), {}\n", g.received,
                     g.factors, g.rejected, report.gnss_rejected_out, where);
  }
  const TimingSummary total = r.timing.count("total") ? r.timing.at("total") : TimingSummary{};
  s += fmt::format(
      "vio {}: {} poses from {} stereo frames, {} lost interval(s), {} initialisation, {} "
      "vehicle; per frame median {:.1f} ms, p95 {:.1f} ms -> {}\n",
      report.mode, r.estimates.size(), r.frames_total, r.lost.size(), r.first_init_kind,
      report.vehicle, total.median_s * 1e3, total.p95_s * 1e3, st.out);
  return s;
}

}  // namespace optinav::app
