#include "optinav/app/nav_run.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/geo/geo.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/report/geo_export.h"
#include "optinav/util/error.h"

namespace optinav::app {

namespace fs = std::filesystem;

std::string NavRunSettings::Check() const {
  if (dataset.empty()) return "--dataset is required";
  if (out.empty()) return "--out is required";
  if (!no_map && map_path.empty()) return "--map is required (or --no-map with --start)";
  if (no_map && !nav.start) return "--no-map needs --start LAT,LON,HEADING";
  for (const auto& [start, duration] : blank)
    if (!(start >= 0) || !(duration > 0)) return "--blank needs START_S >= 0 and DURATION_S > 0";
  const std::string problem = nav.Check();
  if (!problem.empty()) return "--nav options: " + problem;
  return "";
}

namespace {

// The ENU origin of a simulator dataset (sim_complete.json "gnss_origin"), when there is one.
std::optional<geo::LatLon> SimOrigin(const std::string& dataset) {
  for (const fs::path& p : {fs::path(dataset) / "sim_complete.json",
                            fs::path(dataset).parent_path() / "sim_complete.json"}) {
    std::ifstream in(p);
    if (!in) continue;
    try {
      const nlohmann::json j = nlohmann::json::parse(in);
      if (j.contains("gnss_origin") && j["gnss_origin"].size() >= 2)
        return geo::LatLon{j["gnss_origin"][0].get<double>(), j["gnss_origin"][1].get<double>()};
    } catch (const std::exception& e) {
      throw Error(std::string("cannot read the simulator's origin: ") + e.what(),
                  {.file = p.string()});
    }
  }
  return std::nullopt;
}

// Ground truth position (world of the dataset) at t by linear interpolation; nullopt outside.
std::optional<Eigen::Vector3d> PositionAt(const Trajectory& gt, int64_t t_ns) {
  if (gt.empty() || t_ns < gt.t_ns.front() || t_ns > gt.t_ns.back()) return std::nullopt;
  const auto it = std::lower_bound(gt.t_ns.begin(), gt.t_ns.end(), t_ns);
  const size_t i = static_cast<size_t>(it - gt.t_ns.begin());
  if (gt.t_ns[i] == t_ns || i == 0) return gt.positions[i];
  const double a =
      static_cast<double>(t_ns - gt.t_ns[i - 1]) / static_cast<double>(gt.t_ns[i] - gt.t_ns[i - 1]);
  return (1 - a) * gt.positions[i - 1] + a * gt.positions[i];
}

// The yaw of the ground-truth sample nearest to t_ns (degrees; the truth is sampled at the IMU
// rate).
std::optional<double> HeadingAt(const Trajectory& gt, int64_t t_ns) {
  if (gt.empty() || t_ns < gt.t_ns.front() || t_ns > gt.t_ns.back()) return std::nullopt;
  size_t i =
      static_cast<size_t>(std::lower_bound(gt.t_ns.begin(), gt.t_ns.end(), t_ns) - gt.t_ns.begin());
  if (i > 0 && (i == gt.t_ns.size() || t_ns - gt.t_ns[i - 1] < gt.t_ns[i] - t_ns)) --i;
  double roll, pitch, heading;
  nav::AttitudeOfEnuFromBody(gt.rotations[i], &roll, &pitch, &heading);
  return heading;
}

}  // namespace

std::optional<SimTruth> ReadSimTruth(const std::string& dataset) {
  const auto origin = SimOrigin(dataset);
  if (!origin) return std::nullopt;
  const io::EurocDataset ds = io::OpenEurocDataset(dataset, {.check_images_exist = false});
  if (ds.groundtruth_csv.empty()) return std::nullopt;
  return SimTruth{*origin, io::ReadTrajectory(ds.groundtruth_csv)};
}

nav::NavStart SimTruth::Start() const {
  const geo::LocalEnu enu(origin, 0.0);
  double roll, pitch, heading;
  nav::AttitudeOfEnuFromBody(groundtruth.rotations.front(), &roll, &pitch, &heading);
  return {enu.FromEnu(groundtruth.positions.front()), heading, 5.0, 3.0};
}

NavRunReport RunNav(const NavRunSettings& st, const std::function<void(size_t, size_t)>& progress) {
  const std::string problem = st.Check();
  if (!problem.empty()) throw Error(problem);
  const auto wall_start = std::chrono::steady_clock::now();
  const io::EurocDataset ds = io::OpenEurocDataset(st.dataset);
  if (!ds.cam2) throw Error("the dataset has no nadir camera (mav0/cam2)", {.file = ds.mav0_dir});
  if (ds.imu_csv.empty()) throw Error("the dataset has no IMU (mav0/imu0)", {.file = ds.mav0_dir});
  const std::vector<io::ImuSample> imu = io::ReadImuCsv(ds.imu_csv);
  std::vector<io::BaroSample> baro;
  if (!ds.baro_csv.empty()) baro = io::ReadBaroCsv(ds.baro_csv);
  if (ds.cam2->images.empty()) throw Error("no nadir frames", {.file = ds.mav0_dir + "/cam2"});

  nav::NavOptions options = st.nav;
  if (ds.imu_calibration) {
    const io::ImuCalibration& c = *ds.imu_calibration;
    if (c.gyroscope_noise_density > 0) options.gyro_noise_density = c.gyroscope_noise_density;
    if (c.accelerometer_noise_density > 0)
      options.accel_noise_density = c.accelerometer_noise_density;
    if (c.gyroscope_random_walk > 0) options.gyro_random_walk = c.gyroscope_random_walk;
    if (c.accelerometer_random_walk > 0) options.accel_random_walk = c.accelerometer_random_walk;
  }
  if (ds.baro_calibration) {
    options.baro_sigma_m = std::max(options.baro_sigma_m, ds.baro_calibration->noise_sigma_m);
  }
  nav::NavSensors sensors;
  sensors.camera = io::ToPinholeCamera(ds.cam2->calibration);
  sensors.body_from_cam = ds.cam2->calibration.body_from_cam;

  std::optional<maploc::MapDatabase> db;
  NavRunReport report;
  if (!st.no_map) {
    db.emplace(maploc::LoadMapDatabase(st.map_path));
    const geo::CrsTransform crs(db->crs_wkt);
    report.origin =
        crs.ToLatLon(db->transform.PixelToCrs(Eigen::Vector2d(db->width / 2.0, db->height / 2.0)));
  } else {
    report.origin = st.nav.start->position;
  }
  nav::MapAidedNavigator navigator(options, sensors, db ? &*db : nullptr, st.locate, report.origin);

  // GNSS positions into the navigator's ENU frame.
  std::vector<std::pair<int64_t, Eigen::Vector3d>> gnss;
  double gnss_sigma = st.gnss_sigma_m;
  if (st.gnss) {
    if (ds.gnss_csv.empty())
      throw Error("--gnss: the dataset has no mav0/gnss0", {.file = ds.mav0_dir});
    const io::GnssFile file = io::ReadGnssFile(ds.gnss_csv);
    const geo::LocalEnu nav_enu(report.origin, 0.0);
    std::optional<geo::LocalEnu> file_enu;
    if (file.kind == io::GnssFileKind::kEnu) {
      const auto origin = SimOrigin(st.dataset);
      if (!origin)
        throw Error("--gnss: an ENU GNSS file needs its origin (sim_complete.json)",
                    {.file = ds.gnss_csv});
      file_enu.emplace(*origin, 0.0);
    }
    for (const io::GnssRecord& r : file.records) {
      Eigen::Vector3d p;
      if (file_enu) {
        p = nav_enu.ToEnu(file_enu->FromEnu(r.value), 0.0);
        p.z() = r.value.z();  // height above the (flat) map plane
      } else {
        p = nav_enu.ToEnu(geo::LatLon{r.value.x(), r.value.y()}, 0.0);
        p.z() = r.value.z();
      }
      gnss.emplace_back(r.t_ns, p);
      if (gnss_sigma <= 0 && r.sigma_m) gnss_sigma = *r.sigma_m;
    }
    if (gnss_sigma <= 0) gnss_sigma = 3.0;
  }

  const auto& frames = ds.cam2->images;
  const size_t total = st.max_frames > 0 ? std::min(st.max_frames, frames.size()) : frames.size();
  size_t next_imu = 0, next_baro = 0, next_gnss = 0;
  for (size_t k = 0; k < total; ++k) {
    const int64_t t = frames[k].t_ns;
    // Sensors up to (and the IMU one sample past) the frame.
    while (next_imu < imu.size() && (next_imu == 0 || imu[next_imu - 1].t_ns < t))
      navigator.AddImu(imu[next_imu++]);
    while (next_baro < baro.size() && baro[next_baro].t_ns <= t)
      navigator.AddBaro(baro[next_baro++]);
    while (next_gnss < gnss.size() && gnss[next_gnss].first <= t) {
      navigator.AddGnss(gnss[next_gnss].first, gnss[next_gnss].second, gnss_sigma);
      ++next_gnss;
    }
    cv::Mat gray = cv::imread(frames[k].path, cv::IMREAD_GRAYSCALE);
    if (gray.empty()) throw Error("cannot read the nadir frame", {.file = frames[k].path});
    const double since_start = (t - frames[0].t_ns) * 1e-9;
    for (const auto& [start, duration] : st.blank)
      if (since_start >= start && since_start < start + duration) gray.setTo(128);
    if (const auto pose = navigator.AddFrame(t, gray)) report.poses.push_back(*pose);
    if (progress) progress(k + 1, total);
  }
  report.fixes = navigator.fixes();
  report.stats = navigator.stats();
  report.wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  report.duration_s = (frames[total - 1].t_ns - frames[0].t_ns) * 1e-9;
  report.first_frame_ns = frames[0].t_ns;
  if (report.poses.empty())
    throw Error(fmt::format("no pose was estimated ({} nadir frames, {} map fixes tried, none "
                            "confirmed an initialisation)",
                            total, report.stats.fixes_tried),
                {.file = st.dataset});

  // The global error against simulator ground truth (evaluation only).
  if (!ds.groundtruth_csv.empty()) {
    if (const auto sim_origin = SimOrigin(st.dataset)) {
      const Trajectory gt = io::ReadTrajectory(ds.groundtruth_csv);
      const geo::LocalEnu sim_enu(*sim_origin, 0.0), nav_enu(report.origin, 0.0);
      NavError e;
      double sum2 = 0, sum2_alt = 0, sum2_yaw = 0;
      size_t n_yaw = 0;
      for (const nav::NavPose& p : report.poses) {
        const auto truth_world = PositionAt(gt, p.t_ns);
        if (!truth_world) continue;
        double h = 0;
        const geo::LatLon ll = sim_enu.FromEnu(*truth_world, &h);
        Eigen::Vector3d truth = nav_enu.ToEnu(ll, 0.0);
        truth.z() = truth_world->z();  // height above the (flat) map plane
        const double err = (p.world_from_body.translation.head<2>() - truth.head<2>()).norm();
        const double err_alt = p.world_from_body.translation.z() - truth.z();
        report.error_t_ns.push_back(p.t_ns);
        report.errors_m.push_back(err);
        report.altitude_errors_m.push_back(err_alt);
        report.heading_errors_deg.push_back(std::numeric_limits<double>::quiet_NaN());
        if (const auto truth_heading = HeadingAt(gt, p.t_ns)) {
          double roll, pitch, heading;
          nav::AttitudeOfEnuFromBody(p.world_from_body.rotation.toRotationMatrix(), &roll, &pitch,
                                     &heading);
          const double err_yaw = std::remainder(heading - *truth_heading, 360.0);
          report.heading_errors_deg.back() = err_yaw;
          sum2_yaw += err_yaw * err_yaw;
          ++n_yaw;
          e.heading_max_deg = std::max(e.heading_max_deg, std::abs(err_yaw));
        }
        sum2 += err * err;
        sum2_alt += err_alt * err_alt;
        e.max_m = std::max(e.max_m, err);
        e.final_m = err;
        ++e.poses;
      }
      if (e.poses > 0) {
        e.rmse_m = std::sqrt(sum2 / e.poses);
        e.altitude_rmse_m = std::sqrt(sum2_alt / e.poses);
        if (n_yaw > 0) e.heading_rmse_deg = std::sqrt(sum2_yaw / n_yaw);
        report.error = e;
      }
    }
  }

  // Outputs.
  Trajectory traj;
  for (const nav::NavPose& p : report.poses) traj.Add(p.t_ns, p.world_from_body);
  io::WriteTrajectory(st.out, traj, io::TrajectoryFormat::kTum);
  const geo::LocalEnu enu(report.origin, 0.0);
  if (!st.wgs84_out.empty() || !st.geojson_out.empty()) {
    std::string csv =
        "#timestamp [ns], latitude [deg], longitude [deg], height above map [m], sigma east [m], "
        "sigma north [m], sigma up [m], sigma yaw [deg]\n";
    report::GeoLine line;
    line.name = "optinav nav";
    for (const nav::NavPose& p : report.poses) {
      const geo::LatLon ll = enu.FromEnu(
          Eigen::Vector3d(p.world_from_body.translation.x(), p.world_from_body.translation.y(), 0));
      const Eigen::Vector3d s = p.position_covariance.diagonal().cwiseMax(0).cwiseSqrt();
      csv += fmt::format("{},{:.10f},{:.10f},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f}\n", p.t_ns,
                         ll.lat_deg, ll.lon_deg, p.world_from_body.translation.z(), s.x(), s.y(),
                         s.z(), p.yaw_sigma_deg);
      line.points.push_back(ll);
    }
    if (!st.wgs84_out.empty()) io::WriteFileAtomically(st.wgs84_out, csv);
    if (!st.geojson_out.empty())
      io::WriteFileAtomically(st.geojson_out, report::ToGeoJson({line}, {}));
  }
  if (!st.stats_path.empty())
    io::WriteFileAtomically(st.stats_path, report.ToJson().dump(2) + "\n");
  return report;
}

nlohmann::json NavRunReport::ToJson() const {
  nlohmann::json j;
  j["generator"] = "optinav nav";
  j["origin"] = {origin.lat_deg, origin.lon_deg};
  j["frame"] = "enu";
  j["poses"] = poses.size();
  j["frames"] = stats.frames;
  j["duration_s"] = duration_s;
  j["wall_s"] = wall_s;
  j["realtime_factor"] = wall_s > 0 ? duration_s / wall_s : 0.0;
  j["initialized_at_s"] = stats.initialized_at_ns
                              ? nlohmann::json((*stats.initialized_at_ns) * 1e-9)
                              : nlohmann::json();
  j["fixes"] = {{"tried", stats.fixes_tried},
                {"found", stats.fixes_found},
                {"accepted", stats.fixes_accepted},
                {"rejected", stats.fixes_rejected}};
  j["factors"] = {{"odometry", stats.odometry_factors},
                  {"odometry_rejected", stats.odometry_rejected},
                  {"baro", stats.baro_factors},
                  {"fix_yaw", stats.fix_yaws}};
  j["resets"] = stats.resets;
  j["gnss"] = {{"received", stats.gnss_received}, {"accepted", stats.gnss_accepted}};
  j["outliers"] = {{"injected", stats.outliers_injected}, {"accepted", stats.outliers_accepted}};
  j["time_ms"] = {
      {"locate", stats.locate_ms}, {"odometry", stats.odometry_ms}, {"solve", stats.solve_ms}};
  if (error) {
    j["error"] = {{"poses", error->poses},
                  {"rmse_m", error->rmse_m},
                  {"max_m", error->max_m},
                  {"final_m", error->final_m},
                  {"altitude_rmse_m", error->altitude_rmse_m},
                  {"heading_rmse_deg", error->heading_rmse_deg},
                  {"heading_max_deg", error->heading_max_deg}};
    // Per pose (NaN, written as null, where the truth has no heading): for error-over-time plots.
    j["error"]["series"] = {{"t_ns", error_t_ns},
                            {"horizontal_m", errors_m},
                            {"altitude_m", altitude_errors_m},
                            {"heading_deg", heading_errors_deg}};
  }
  nlohmann::json fx = nlohmann::json::array();
  for (const nav::FixLog& f : fixes) {
    fx.push_back({{"t_ns", f.t_ns},
                  {"global", f.global},
                  {"found", f.found},
                  {"accepted", f.accepted},
                  {"injected", f.injected},
                  {"method", f.method},
                  {"reason", f.reason},
                  {"x", f.enu.x()},
                  {"y", f.enu.y()},
                  {"sigma_m", f.sigma_m},
                  {"innovation_m", f.innovation_m},
                  {"chi2", f.chi2},
                  {"locate_ms", f.locate_ms}});
  }
  j["fix_log"] = fx;
  return j;
}

}  // namespace optinav::app
