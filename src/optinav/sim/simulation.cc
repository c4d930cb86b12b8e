#include "optinav/sim/simulation.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "optinav/io/airsim_recording.h"
#include "optinav/io/euroc_dataset.h"
#include "optinav/io/euroc_writer.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/text_parse.h"
#include "optinav/io/waypoints.h"
#include "optinav/sim/internal/png_writer.h"
#include "optinav/sim/renderer.h"
#include "optinav/util/error.h"
#include "optinav/util/queue.h"

namespace fs = std::filesystem;

namespace optinav::sim {
namespace {

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;  // 2023-11-14T22:13:20Z
constexpr const char* kMarker = "sim_complete.json";

// The simulation's sensors in the io writers' terms (io/euroc_writer.h formats the files).
io::ImuCalibration ImuCalibrationOf(const ImuOptions& o) {
  io::ImuCalibration c;
  c.rate_hz = o.rate_hz;
  c.gyroscope_noise_density = o.gyroscope_noise_density;
  c.gyroscope_random_walk = o.gyroscope_random_walk;
  c.accelerometer_noise_density = o.accelerometer_noise_density;
  c.accelerometer_random_walk = o.accelerometer_random_walk;
  return c;  // body_from_imu: identity, the IMU defines the body frame
}

io::GnssSensorDescription GnssDescriptionOf(const GnssOptions& o) {
  io::GnssSensorDescription d;
  d.lever_arm_in_body = o.lever_arm_in_body;
  d.rate_hz = o.rate_hz;
  d.sigma_m = o.sigma_m;
  d.outlier_fraction = o.outlier_fraction;
  d.outlier_magnitude_m = o.outlier_magnitude_m;
  for (const GnssOutage& w : o.outages) d.outages_s.emplace_back(w.start_s, w.duration_s);
  d.origin_lat_lon_height = Eigen::Vector3d(o.origin.lat_deg, o.origin.lon_deg, o.origin_height_m);
  return d;
}

std::vector<io::ImuSample> ImuSamplesOf(const std::vector<ImuMeasurement>& imu) {
  std::vector<io::ImuSample> out;
  out.reserve(imu.size());
  for (const ImuMeasurement& m : imu) out.push_back({m.t_ns, m.gyro_rad_s, m.accel_m_s2});
  return out;
}

// The ground truth at the IMU's stamps, with the biases the IMU samples carry.
std::vector<io::GroundTruthState> GroundTruthOf(const BodyTrajectory& traj,
                                                const std::vector<ImuMeasurement>& imu) {
  std::vector<io::GroundTruthState> out;
  out.reserve(imu.size());
  for (const ImuMeasurement& m : imu) {
    const BodyState st = traj.At(m.t_ns);
    out.push_back({.t_ns = m.t_ns,
                   .world_from_body = st.world_from_body,
                   .velocity_in_world = st.velocity_in_world,
                   .gyro_bias = m.gyro_bias,
                   .accel_bias = m.accel_bias});
  }
  return out;
}

// The GNSS samples as ENU positions or latitude/longitude/height, with their outlier flags.
std::vector<io::GnssRecord> GnssRecordsOf(const std::vector<GnssMeasurement>& g,
                                          io::GnssFileKind kind, std::vector<bool>* outliers) {
  std::vector<io::GnssRecord> out;
  out.reserve(g.size());
  for (const GnssMeasurement& m : g) {
    io::GnssRecord r;
    r.t_ns = m.t_ns;
    r.value = kind == io::GnssFileKind::kEnu ? m.position_enu_m
                                             : Eigen::Vector3d(m.lat_deg, m.lon_deg, m.height_m);
    out.push_back(r);
    if (outliers) outliers->push_back(m.outlier);
  }
  return out;
}

struct ImageJob {
  std::string path;
  cv::Mat image;
};

BodyTrajectory MakeRouteWithoutDrag(const SimulationOptions& o, const World& world) {
  if (o.route == "car") {
    return MakeCarTrajectory(
        world.kind == WorldKind::kTerrain ? CarRouteOptions::Terrain() : CarRouteOptions::Urban(),
        world.ground_height, kStartNs);
  }
  if (o.route == "drone") {
    RandomDroneRouteOptions r;
    r.speed_m_s = o.speed_m_s;
    r.altitude_m = o.altitude_m;
    r.duration_s = o.duration_s > 0 ? o.duration_s : 60.0;
    r.area_min = world.area_min;
    r.area_max = world.area_max;
    r.start = Eigen::Vector2d::Zero().cwiseMax(world.area_min).cwiseMin(world.area_max);
    return MakeDroneTrajectory(RandomDroneWaypoints(r, world.ground_height, o.seed), o.speed_m_s,
                               kStartNs);
  }
  const std::string file = o.route.substr(6);
  std::vector<DroneWaypoint> wps;
  for (const io::WaypointRow& row : io::ReadWaypointsFile(file)) {
    DroneWaypoint w;
    w.position_in_world =
        Eigen::Vector3d(row.x_m, row.y_m, world.ground_height(row.x_m, row.y_m) + row.altitude_m);
    if (row.yaw_deg) w.yaw_rad = *row.yaw_deg * M_PI / 180.0;
    wps.push_back(w);
  }
  try {
    return MakeDroneTrajectory(wps, o.speed_m_s, kStartNs);
  } catch (const Error& e) {
    throw Error(e.message(), {.file = file});
  }
}

BodyTrajectory MakeRoute(const SimulationOptions& o, const World& world) {
  BodyTrajectory t = MakeRouteWithoutDrag(o, world);
  if (o.route != "car")
    t.SetAirDrag(o.drag_per_s, Eigen::Vector3d(o.wind_m_s.x(), o.wind_m_s.y(), 0));
  return t;
}

std::string FormatName(DatasetFormat f) { return f == DatasetFormat::kEuroc ? "euroc" : "airsim"; }

std::string WorldName(WorldKind k) {
  switch (k) {
    case WorldKind::kUrban:
      return "urban";
    case WorldKind::kTerrain:
      return "terrain";
    case WorldKind::kOrtho:
      return "ortho";
  }
  return "?";
}

// One camera's image with its weather (the stereo pair and the nadir camera render this way).
void RenderWithWeather(const Renderer& renderer, const camera::PinholeCamera& cam,
                       const Rigid3d& world_from_cam, int64_t t_ns, const WeatherSpec& weather,
                       uint64_t seed, const CameraNoiseOptions& noise, int camera_index,
                       cv::Mat* img) {
  cv::Mat depth;
  renderer.Render(cam, world_from_cam, img, &depth);
  if (!noise.enabled) {
    ApplyWeather(*img, depth, cam, world_from_cam, t_ns, weather, seed);
    return;
  }
  // The weather on the unrounded light, then the sensor's noise and its rounding to 8 bits.
  cv::Mat light;
  img->convertTo(light, CV_32FC3);
  ApplyWeather(light, depth, cam, world_from_cam, t_ns, weather, seed);
  *img = ExposeToEightBits(light, noise, CameraNoiseStream(seed, t_ns, camera_index));
}

}  // namespace

std::string SimulationOptions::Check() const {
  if (out_dir.empty()) return "--out must be given";
  if (!(duration_s >= 0 && duration_s <= 3600)) {
    return fmt::format("--duration {} s not in [0, 3600] (0: whole route)", duration_s);
  }
  if (!(scale >= 0.05 && scale <= 4)) return fmt::format("--scale {} not in [0.05, 4]", scale);
  if (!(speed_m_s > 0 && speed_m_s <= 60))
    return fmt::format("--speed {} m/s not in (0, 60]", speed_m_s);
  if (!(altitude_m > 0 && altitude_m <= 5000)) {
    return fmt::format("--altitude {} m not in (0, 5000]", altitude_m);
  }
  if (!(drag_per_s >= 0 && drag_per_s <= 2))
    return fmt::format("--drag {} 1/s not in [0, 2]", drag_per_s);
  if (!(wind_m_s.allFinite() && wind_m_s.norm() <= 40))
    return fmt::format("--wind {},{} m/s: must be finite, at most 40 m/s", wind_m_s.x(),
                       wind_m_s.y());
  if (route == "car" && (drag_per_s > 0 || !wind_m_s.isZero()))
    return "--drag and --wind apply to drone routes only";
  if (route != "car" && route != "drone" && !(route.rfind("drone:", 0) == 0 && route.size() > 6)) {
    return fmt::format("--route '{}' must be car, drone or drone:FILE", route);
  }
  if (png_compression < 0 || png_compression > 9) return "png compression not in [0, 9]";
  if (const std::string m = imu.Check(); !m.empty()) return m;
  if (const std::string m = gnss.Check(); !m.empty()) return m;
  if (const std::string m = camera_noise.Check(); !m.empty()) return m;
  if (baro.enabled) {
    if (const std::string m = baro.Check(); !m.empty()) return m;
  }
  if (nadir.enabled) {
    if (nadir.width < 16 || nadir.height < 16 || nadir.width > 8192 || nadir.height > 8192) {
      return fmt::format("--nadir-camera {}x{} not within 16x16 to 8192x8192", nadir.width,
                         nadir.height);
    }
    if (!(nadir.hfov_deg >= 5 && nadir.hfov_deg <= 150)) {
      return fmt::format("--nadir-hfov {} deg not in [5, 150]", nadir.hfov_deg);
    }
    if (!(nadir.rate_hz >= 0.1 && nadir.rate_hz <= 100)) {
      return fmt::format("--nadir-rate {} Hz not in [0.1, 100]", nadir.rate_hz);
    }
  }
  return "";
}

namespace {

// The parameters of a rendering as its completion marker records them (IsRenderingOf compares
// these keys).
nlohmann::ordered_json MarkerParameters(const SimulationOptions& options) {
  nlohmann::ordered_json j;
  j["world"] = WorldName(options.world.kind);
  if (!options.world.ortho_path.empty()) j["ortho"] = options.world.ortho_path;
  j["route"] = options.route;
  j["weather"] = options.weather.ToString();
  if (options.weather.particles_still) j["particles_still"] = true;
  // Urban only; a marker without it (written before 2026-12-06) is tiled.
  if (options.world.kind == WorldKind::kUrban)
    j["asphalt"] = AsphaltName(options.world.varied_asphalt);
  // Terrain only: its ground in variants per cell since 2026-12-07; a terrain marker without it
  // was written over the ground that repeats every 5 m, which this binary no longer renders.
  if (options.world.kind == WorldKind::kTerrain) j["ground"] = "varied";
  // Since 2026-12-07; a marker without it was rendered without the camera's noise.
  if (options.camera_noise.enabled) j["camera_noise"] = options.camera_noise.ToString();
  j["seed"] = options.seed;
  j["format"] = FormatName(options.format);
  j["scale"] = options.scale;
  j["requested_duration_s"] = options.duration_s;  // 0: the whole car route, 60 s for drones
  if (options.route != "car") {
    j["speed_m_s"] = options.speed_m_s;
    j["altitude_m"] = options.altitude_m;
    j["drag_per_s"] = options.drag_per_s;
    j["wind_m_s"] = {options.wind_m_s.x(), options.wind_m_s.y()};
  }
  return j;
}

}  // namespace

bool IsRenderingOf(const std::string& dir, const SimulationOptions& options, std::string* why) {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  const fs::path marker = fs::path(dir) / kMarker;
  if (!fs::is_regular_file(marker)) return fail("no " + marker.string() + " (not finished)");
  nlohmann::ordered_json j;
  try {
    j = nlohmann::ordered_json::parse(io::ReadFileToString(marker.string()));
  } catch (const std::exception& e) {
    return fail(fmt::format("{}: {}", marker.string(), e.what()));
  }
  if (!j.is_object()) return fail(marker.string() + ": not a JSON object");
  const nlohmann::ordered_json renderer =
      j.contains("renderer") ? j.at("renderer") : nlohmann::ordered_json(1);
  if (renderer != kRendererVersion) {
    return fail(fmt::format("renderer {} (this binary's: {})", renderer.dump(), kRendererVersion));
  }
  const nlohmann::ordered_json want = MarkerParameters(options);
  for (const char* key :
       {"world", "ortho", "route", "weather", "particles_still", "asphalt", "ground",
        "camera_noise", "seed", "format", "scale", "requested_duration_s", "speed_m_s",
        "altitude_m", "drag_per_s", "wind_m_s"}) {
    nlohmann::ordered_json have = j.contains(key) ? j.at(key) : nlohmann::ordered_json();
    // Markers written before 2026-12-06: without the asphalt (tiled), and without the requested
    // duration, which the rendered one stands for when it was reached (0: the whole route).
    if (std::string(key) == "asphalt" && have.is_null() && want.contains(key)) have = "tiled";
    if (std::string(key) == "requested_duration_s" && have.is_null() && j.contains("duration_s") &&
        j.at("duration_s").is_number()) {
      const double rendered = j.at("duration_s").get<double>();
      // 0 asks for the whole car or waypoint route, which the marker cannot confirm.
      const double asked = options.duration_s > 0     ? options.duration_s
                           : options.route == "drone" ? 60.0
                                                      : rendered;
      if (std::abs(rendered - asked) < 1e-6) have = options.duration_s;
    }
    const nlohmann::ordered_json expected =
        want.contains(key) ? want.at(key) : nlohmann::ordered_json();
    // The same orthophoto by another path (relative or absolute, "./", a link) is the same map.
    if (std::string(key) == "ortho" && have.is_string() && expected.is_string() &&
        have != expected) {
      std::error_code ec;
      if (fs::equivalent(have.get<std::string>(), expected.get<std::string>(), ec) && !ec)
        have = expected;
    }
    if (have != expected) {
      return fail(fmt::format("{}: {} (wanted {})", key, have.is_null() ? "absent" : have.dump(),
                              expected.is_null() ? "absent" : expected.dump()));
    }
  }
  return true;
}

SimulationSummary RunSimulation(const SimulationOptions& options,
                                const std::function<void(size_t, size_t)>& progress) {
  if (const std::string m = options.Check(); !m.empty()) throw Error(m);
  const auto wall_start = std::chrono::steady_clock::now();
  // Everything that can fail on bad input happens before the output folder is touched.
  WorldOptions wo = options.world;
  wo.seed = options.seed;
  wo.weather = options.weather;
  const World world = MakeWorld(wo);
  const BodyTrajectory traj = MakeRoute(options, world);
  GnssOptions gnss_opt = options.gnss;
  if (world.origin) {
    gnss_opt.origin = *world.origin;
    gnss_opt.origin_height_m = 0;
  }
  const bool drone = options.route != "car";
  const SensorRig rig =
      (options.rig ? *options.rig : (drone ? DroneRig() : CarRig())).Scaled(options.scale);
  int64_t end_ns = traj.end_ns();
  if (options.duration_s > 0) {
    end_ns =
        std::min(end_ns, kStartNs + static_cast<int64_t>(std::llround(options.duration_s * 1e9)));
  }
  std::vector<ImuMeasurement> imu = SimulateImu(traj, options.imu, options.seed);
  std::erase_if(imu, [&](const ImuMeasurement& m) { return m.t_ns > end_ns; });
  std::vector<GnssMeasurement> gnss = SimulateGnss(traj, gnss_opt, options.seed);
  std::erase_if(gnss, [&](const GnssMeasurement& m) { return m.t_ns > end_ns; });
  const int64_t period_ns = std::llround(1e9 / rig.camera_rate_hz);
  std::vector<int64_t> frame_times;
  for (int64_t t = kStartNs; t <= end_ns; t += period_ns) frame_times.push_back(t);
  std::vector<int64_t> nadir_times;
  if (options.nadir.enabled) {
    const int64_t nadir_period_ns = std::llround(1e9 / options.nadir.rate_hz);
    for (int64_t t = kStartNs; t <= end_ns; t += nadir_period_ns) nadir_times.push_back(t);
  }
  std::vector<BaroMeasurement> baro;
  if (options.baro.enabled) {
    baro = SimulateBaro(traj, options.baro, options.seed);
    std::erase_if(baro, [&](const BaroMeasurement& m) { return m.t_ns > end_ns; });
  }

  io::PrepareOutputDir(options.out_dir, options.force, io::OnForce::kClear, "--out", kMarker);
  io::MarkInProgress(options.out_dir, "optinav sim");
  const fs::path out(options.out_dir);
  const bool euroc = options.format == DatasetFormat::kEuroc;
  const fs::path mav0 = out / "mav0";
  const fs::path left_dir = euroc ? mav0 / "cam0" / "data" : out / "images";
  const fs::path right_dir = euroc ? mav0 / "cam1" / "data" : out / "images";
  fs::create_directories(left_dir);
  fs::create_directories(right_dir);
  // The nadir camera and the barometer: EuRoC layout in both formats.
  const fs::path extra_root = euroc ? mav0 : out;
  const fs::path nadir_dir = extra_root / "cam2" / "data";
  if (options.nadir.enabled) fs::create_directories(nadir_dir);

  // Writer threads encode and write the PNGs while the next frames render (PNG encoding costs
  // about as much as rendering; sim/internal/png_writer.h).
  ThreadSafeQueue<ImageJob> queue(8);
  std::mutex error_mutex;
  std::string write_error;
  std::vector<std::thread> writers;
  const int n_writers =
      std::max(1, std::min(4, static_cast<int>(std::thread::hardware_concurrency())));
  for (int w = 0; w < n_writers; ++w) {
    writers.emplace_back([&] {
      while (auto job = queue.Pop()) {
        std::string error;
        try {
          const std::vector<uint8_t> buf = EncodePng(job->image, options.png_compression);
          std::ofstream f(job->path, std::ios::binary);
          f.write(reinterpret_cast<const char*>(buf.data()),
                  static_cast<std::streamsize>(buf.size()));
          f.close();
          if (!f) error = "cannot write " + job->path + " (disk full?)";
        } catch (const Error& e) {
          error = job->path + ": " + e.what();
        }
        if (!error.empty()) {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (write_error.empty()) write_error = error;
          queue.Close();
        }
      }
    });
  }
  auto join_writers = [&] {
    queue.Close();
    for (auto& w : writers) w.join();
  };
  const Renderer renderer(world);
  std::vector<io::ImageEntry> image_list;  // EuRoC: the same file names for cam0 and cam1
  std::vector<io::ImageEntry> nadir_list;
  size_t next_nadir = 0;
  // Renders (and queues) the nadir frames up to time `until`; false when the writers stopped.
  auto render_nadir_until = [&](int64_t until) {
    for (; next_nadir < nadir_times.size() && nadir_times[next_nadir] <= until; ++next_nadir) {
      const int64_t t = nadir_times[next_nadir];
      cv::Mat img = RenderNadir(renderer, options.nadir, traj.At(t).world_from_body, t,
                                options.weather, options.seed, options.camera_noise);
      const std::string name = fmt::format("{}.png", t);
      nadir_list.push_back({.t_ns = t, .path = name});
      if (!queue.Push({(nadir_dir / name).string(), std::move(img)})) return false;
    }
    return true;
  };
  io::AirsimRecording airsim;  // AirSim: the rows of airsim_rec.txt and camera_info.csv
  try {
    for (size_t k = 0; k < frame_times.size(); ++k) {
      const int64_t t = frame_times[k];
      const BodyState st = traj.At(t);
      const Rigid3d world_from_left = st.world_from_body * rig.body_from_left;
      cv::Mat left, right;
      RenderStereo(renderer, rig, st.world_from_body, t, options.weather, options.seed,
                   options.camera_noise, &left, &right);
      std::string lname, rname;
      if (euroc) {
        lname = rname = fmt::format("{}.png", t);
        image_list.push_back({.t_ns = t, .path = lname});
      } else {
        lname = fmt::format("img_front_left_0_{}.png", t);
        rname = fmt::format("img_front_right_0_{}.png", t);
        const CarControls c = traj.ControlsAt(t).value_or(CarControls{});
        const double speed = st.velocity_in_world.norm();
        airsim.records.push_back(
            {.t_ns = t,
             .vehicle = drone ? "Drone1" : "PhysXCar",
             .world_from_body = st.world_from_body,
             .throttle = c.throttle,
             .steering = c.steering,
             .brake = c.brake,
             .rpm = c.gear ? 800 + 180 * speed : 0,  // a fixed gear ratio, idle 800
             .speed_m_s = speed,
             .gear = c.gear,
             .handbrake = c.handbrake,
             .image_paths = {lname, rname}});
        airsim.left_camera.push_back({.t_ns = t, .world_from_cam = world_from_left});
      }
      if (!queue.Push({(left_dir / lname).string(), std::move(left)}) ||
          !queue.Push({(right_dir / rname).string(), std::move(right)}) || !render_nadir_until(t)) {
        break;
      }
      if (progress) progress(k + 1, frame_times.size());
    }
    render_nadir_until(end_ns);
  } catch (...) {
    join_writers();
    throw;
  }
  join_writers();
  if (!write_error.empty()) throw Error(write_error, {.file = options.out_dir});

  const std::string comment = fmt::format(
      "optinav sim, world {}, weather {}{}{}, seed {}", WorldName(world.kind),
      options.weather.ToString(), options.weather.particles_still ? " (particles still)" : "",
      options.world.varied_asphalt ? " (varied asphalt)" : "", options.seed);
  const std::vector<io::ImuSample> imu_samples = ImuSamplesOf(imu);
  const std::vector<io::GroundTruthState> ground_truth = GroundTruthOf(traj, imu);
  std::vector<bool> outliers;
  const std::vector<io::GnssRecord> gnss_enu = GnssRecordsOf(gnss, io::GnssFileKind::kEnu, nullptr);
  const std::vector<io::GnssRecord> gnss_llh =
      GnssRecordsOf(gnss, io::GnssFileKind::kLatLonHeight, &outliers);
  if (options.nadir.enabled) {
    io::WriteImageList((extra_root / "cam2" / "data.csv").string(), nadir_list);
    io::WriteCameraSensorYaml(
        (extra_root / "cam2" / "sensor.yaml").string(),
        io::ToCameraCalibration(options.nadir.Camera(), NadirCameraMount(), options.nadir.rate_hz),
        "nadir mapping camera, " + comment);
  }
  if (options.baro.enabled) {
    fs::create_directories(extra_root / "baro0");
    std::vector<io::BaroSample> samples;
    samples.reserve(baro.size());
    for (const BaroMeasurement& m : baro) samples.push_back({m.t_ns, m.altitude_m});
    io::WriteBaroCsv((extra_root / "baro0" / "data.csv").string(), samples);
    io::WriteBaroSensorYaml((extra_root / "baro0" / "sensor.yaml").string(),
                            {.rate_hz = options.baro.rate_hz,
                             .noise_sigma_m = options.baro.noise_sigma_m,
                             .bias_sigma_m = options.baro.initial_bias_sigma_m,
                             .bias_random_walk = options.baro.bias_random_walk},
                            "simulated barometer, " + comment);
  }
  if (euroc) {
    io::WriteImageList((mav0 / "cam0" / "data.csv").string(), image_list);
    io::WriteImageList((mav0 / "cam1" / "data.csv").string(), image_list);
    io::WriteCameraSensorYaml(
        (mav0 / "cam0" / "sensor.yaml").string(),
        io::ToCameraCalibration(rig.left, rig.body_from_left, rig.camera_rate_hz),
        "left camera, " + comment);
    io::WriteCameraSensorYaml(
        (mav0 / "cam1" / "sensor.yaml").string(),
        io::ToCameraCalibration(rig.right, rig.body_from_right, rig.camera_rate_hz),
        "right camera, " + comment);
    fs::create_directories(mav0 / "imu0");
    fs::create_directories(mav0 / "gnss0");
    fs::create_directories(mav0 / "state_groundtruth_estimate0");
    io::WriteImuCsv((mav0 / "imu0" / "data.csv").string(), imu_samples);
    io::WriteImuSensorYaml((mav0 / "imu0" / "sensor.yaml").string(), ImuCalibrationOf(options.imu),
                           options.imu.noise_free, "simulated IMU, Kalibr/EuRoC noise model");
    io::WriteGnssCsv((mav0 / "gnss0" / "data.csv").string(), io::GnssFileKind::kEnu, gnss_enu);
    io::WriteGnssCsv((mav0 / "gnss0" / "llh.csv").string(), io::GnssFileKind::kLatLonHeight,
                     gnss_llh, &outliers);
    io::WriteGnssSensorYaml((mav0 / "gnss0" / "sensor.yaml").string(), GnssDescriptionOf(gnss_opt));
    io::WriteGroundTruthCsv((mav0 / "state_groundtruth_estimate0" / "data.csv").string(),
                            ground_truth);
  } else {
    io::WriteAirsimRecording(out.string(), airsim);
    // Extras beyond AirSim's own files, in the EuRoC layouts (ENU world, body x forward, y left).
    io::WriteImuCsv((out / "imu0.csv").string(), imu_samples);
    io::WriteGnssCsv((out / "gnss0.csv").string(), io::GnssFileKind::kEnu, gnss_enu);
    io::WriteGnssCsv((out / "gnss0_llh.csv").string(), io::GnssFileKind::kLatLonHeight, gnss_llh,
                     &outliers);
    io::WriteGroundTruthCsv((out / "groundtruth.csv").string(), ground_truth);
  }
  SimulationSummary summary;
  summary.frames = frame_times.size();
  summary.imu_samples = imu.size();
  summary.gnss_samples = gnss.size();
  summary.nadir_frames = nadir_list.size();
  summary.baro_samples = baro.size();
  summary.duration_s = (end_ns - kStartNs) * 1e-9;
  summary.world_triangles = world.TriangleCount();
  summary.width = rig.left.width;
  summary.height = rig.left.height;
  {
    double len = 0;
    Eigen::Vector3d prev = traj.At(kStartNs).world_from_body.translation;
    for (int64_t t = kStartNs + 50'000'000; t <= end_ns; t += 50'000'000) {
      const Eigen::Vector3d p = traj.At(t).world_from_body.translation;
      len += (p - prev).norm();
      prev = p;
    }
    summary.path_length_m = len;
  }
  // The completion marker: parameters and counts, nothing run-dependent (byte-identical reruns).
  nlohmann::ordered_json j;
  j["generator"] = "optinav sim";
  j["renderer"] = kRendererVersion;
  const nlohmann::ordered_json parameters = MarkerParameters(options);
  for (const auto& [key, value] : parameters.items()) j[key] = value;
  j["image_size"] = {rig.left.width, rig.left.height};
  j["camera_rate_hz"] = rig.camera_rate_hz;
  j["duration_s"] = summary.duration_s;
  j["path_length_m"] = summary.path_length_m;
  j["stereo_frames"] = summary.frames;
  j["imu_samples"] = summary.imu_samples;
  j["gnss_samples"] = summary.gnss_samples;
  if (options.nadir.enabled) {
    j["nadir_camera"] = {{"image_size", {options.nadir.width, options.nadir.height}},
                         {"hfov_deg", options.nadir.hfov_deg},
                         {"rate_hz", options.nadir.rate_hz},
                         {"frames", summary.nadir_frames}};
  }
  if (options.baro.enabled) j["baro_samples"] = summary.baro_samples;
  j["gnss_origin"] = {gnss_opt.origin.lat_deg, gnss_opt.origin.lon_deg, gnss_opt.origin_height_m};
  // Every data file is in place: the folder stops being refused by the readers, then the marker
  // tells the next run and the benchmarks that it is complete.
  io::ClearInProgress(options.out_dir);
  io::WriteFileAtomically((out / kMarker).string(), j.dump(2) + "\n");
  summary.wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return summary;
}

void RenderStereo(const Renderer& renderer, const SensorRig& rig, const Rigid3d& world_from_body,
                  int64_t t_ns, const WeatherSpec& weather, uint64_t seed,
                  const CameraNoiseOptions& noise, cv::Mat* left, cv::Mat* right) {
  auto one = [&](const camera::PinholeCamera& cam, const Rigid3d& body_from_cam, int index,
                 cv::Mat* img) {
    RenderWithWeather(renderer, cam, world_from_body * body_from_cam, t_ns, weather, seed, noise,
                      index, img);
  };
  auto right_done =
      std::async(std::launch::async, [&] { one(rig.right, rig.body_from_right, 1, right); });
  one(rig.left, rig.body_from_left, 0, left);
  right_done.get();
}

cv::Mat RenderNadir(const Renderer& renderer, const NadirCameraOptions& nadir,
                    const Rigid3d& world_from_body, int64_t t_ns, const WeatherSpec& weather,
                    uint64_t seed, const CameraNoiseOptions& noise) {
  cv::Mat img;
  RenderWithWeather(renderer, nadir.Camera(), world_from_body * NadirCameraMount(), t_ns, weather,
                    seed, noise, 2, &img);
  return img;
}

std::vector<SuiteEntry> WeatherSuite() {
  std::vector<SuiteEntry> out;
  for (WorldKind w : {WorldKind::kUrban, WorldKind::kTerrain}) {
    const std::string wn = WorldName(w);
    out.push_back({wn + "_default", w, {}});
    for (const char* k : {"rain", "snow", "leaves"}) {
      out.push_back({fmt::format("{}_{}", wn, k), w, ParseWeather(fmt::format("{}:50", k))});
    }
    std::vector<std::string> graded = {"fog", "dust"};
    if (w == WorldKind::kUrban) {
      for (const char* k : {"road-wetness", "road-snow", "road-leaves"}) graded.push_back(k);
    }
    for (const std::string& k : graded) {
      for (int level : {25, 50, 75, 100}) {
        std::string name = k;
        std::replace(name.begin(), name.end(), '-', '_');
        out.push_back({fmt::format("{}_{}_{}", wn, name, level), w,
                       ParseWeather(fmt::format("{}:{}", k, level))});
      }
    }
  }
  return out;
}

}  // namespace optinav::sim
