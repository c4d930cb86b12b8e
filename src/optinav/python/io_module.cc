// optinav.io: read_euroc() over io::OpenEurocDataset and the readers `optinav vio` uses.
#include <limits>
#include <string>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "optinav/io/euroc_dataset.h"
#include "optinav/io/gnss_io.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/python/convert.h"

namespace optinav::python {
namespace {

py::array_t<int64_t> Times(size_t n, const auto& t_of) {
  py::array_t<int64_t> t(static_cast<py::ssize_t>(n));
  auto w = t.mutable_unchecked<1>();
  for (size_t i = 0; i < n; ++i) w(i) = t_of(i);
  return t;
}

// An n x cols float array filled by fill(i, row pointer).
py::array_t<double> Rows(size_t n, py::ssize_t cols, const auto& fill) {
  py::array_t<double> a({static_cast<py::ssize_t>(n), cols});
  for (size_t i = 0; i < n; ++i) fill(i, a.mutable_data(i, 0));
  return a;
}

py::array_t<double> Matrix4(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  return Rows(4, 4, [&](size_t r, double* out) {
    for (int c = 0; c < 4; ++c) out[c] = m(r, c);
  });
}

py::dict Camera(const io::CameraStream& s) {
  const io::CameraCalibration& c = s.calibration;
  py::dict calibration;
  calibration["camera_model"] = c.camera_model;
  calibration["resolution"] = py::make_tuple(c.width, c.height);
  calibration["intrinsics"] = py::make_tuple(c.fx, c.fy, c.cx, c.cy);
  calibration["distortion_model"] = c.distortion_model;
  py::list distortion;
  for (double d : c.distortion) distortion.append(d);
  calibration["distortion"] = distortion;
  calibration["rate_hz"] = c.rate_hz;
  calibration["body_from_cam"] = Matrix4(c.body_from_cam);
  py::list paths;
  for (const io::ImageEntry& e : s.images) paths.append(ToStr(e.path));
  py::dict d;
  d["t_ns"] = Times(s.images.size(), [&](size_t i) { return s.images[i].t_ns; });
  d["images"] = paths;
  d["calibration"] = calibration;
  return d;
}

py::dict Imu(const io::EurocDataset& ds) {
  const std::vector<io::ImuSample> samples = io::ReadImuCsv(ds.imu_csv);
  const io::ImuCalibration& c = *ds.imu_calibration;
  py::dict calibration;
  calibration["rate_hz"] = c.rate_hz;
  calibration["gyroscope_noise_density"] = c.gyroscope_noise_density;
  calibration["gyroscope_random_walk"] = c.gyroscope_random_walk;
  calibration["accelerometer_noise_density"] = c.accelerometer_noise_density;
  calibration["accelerometer_random_walk"] = c.accelerometer_random_walk;
  calibration["body_from_imu"] = Matrix4(c.body_from_imu);
  py::dict d;
  d["t_ns"] = Times(samples.size(), [&](size_t i) { return samples[i].t_ns; });
  d["gyro_rad_s"] = Rows(samples.size(), 3, [&](size_t i, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = samples[i].gyro_rad_s[k];
  });
  d["accel_m_s2"] = Rows(samples.size(), 3, [&](size_t i, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = samples[i].accel_m_s2[k];
  });
  d["calibration"] = calibration;
  return d;
}

py::dict GroundTruth(const std::string& csv) {
  const Trajectory t = io::ReadTrajectory(csv, {.format = io::TrajectoryFormat::kEuroc});
  py::dict d;
  d["t_ns"] = Times(t.size(), [&](size_t i) { return t.t_ns[i]; });
  d["position"] = Rows(t.size(), 3, [&](size_t i, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = t.positions[i][k];
  });
  d["quaternion_wxyz"] = Rows(t.size(), 4, [&](size_t i, double* out) {
    const Eigen::Quaterniond q = t.quaternion(i);
    out[0] = q.w();
    out[1] = q.x();
    out[2] = q.y();
    out[3] = q.z();
  });
  return d;
}

py::dict Gnss(const std::string& csv) {
  const io::GnssFile f = io::ReadGnssFile(csv);
  const size_t n = f.records.size();
  py::dict d;
  d["kind"] = f.kind == io::GnssFileKind::kEnu ? "enu" : "lat_lon_height";
  d["t_ns"] = Times(n, [&](size_t i) { return f.records[i].t_ns; });
  d["values"] = Rows(n, 3, [&](size_t i, double* out) {
    for (int k = 0; k < 3; ++k) out[k] = f.records[i].value[k];
  });
  d["sigma_m"] = Rows(n, 1, [&](size_t i, double* out) {
                   out[0] = f.records[i].sigma_m.value_or(std::numeric_limits<double>::quiet_NaN());
                 }).attr("reshape")(n);
  return d;
}

py::dict Baro(const io::EurocDataset& ds) {
  const std::vector<io::BaroSample> samples = io::ReadBaroCsv(ds.baro_csv);
  const io::BaroCalibration& c = *ds.baro_calibration;
  py::dict calibration;
  calibration["rate_hz"] = c.rate_hz;
  calibration["noise_sigma_m"] = c.noise_sigma_m;
  calibration["bias_sigma_m"] = c.bias_sigma_m;
  calibration["bias_random_walk"] = c.bias_random_walk;
  py::dict d;
  d["t_ns"] = Times(samples.size(), [&](size_t i) { return samples[i].t_ns; });
  d["altitude_m"] = Rows(samples.size(), 1, [&](size_t i, double* out) {
                      out[0] = samples[i].altitude_m;
                    }).attr("reshape")(samples.size());
  d["calibration"] = calibration;
  return d;
}

}  // namespace

void DefineIo(py::module_& m) {
  m.def(
      "read_euroc",
      [](const py::object& path, bool skip_missing_images) {
        io::EurocOpenOptions open;
        open.drop_missing_images = skip_missing_images;
        const std::string dir = ToPath(path);
        const io::EurocDataset ds = io::OpenEurocDataset(dir, open);
        py::dict d;
        d["mav0"] = ToStr(ds.mav0_dir);
        d["cam0"] = ds.cam0 ? py::object(Camera(*ds.cam0)) : py::object(py::none());
        d["cam1"] = ds.cam1 ? py::object(Camera(*ds.cam1)) : py::object(py::none());
        d["cam2"] = ds.cam2 ? py::object(Camera(*ds.cam2)) : py::object(py::none());
        d["imu"] = ds.imu_csv.empty() ? py::object(py::none()) : py::object(Imu(ds));
        d["baro"] = ds.baro_csv.empty() ? py::object(py::none()) : py::object(Baro(ds));
        d["groundtruth"] = ds.groundtruth_csv.empty() ? py::object(py::none())
                                                      : py::object(GroundTruth(ds.groundtruth_csv));
        d["gnss"] = ds.gnss_csv.empty() ? py::object(py::none()) : py::object(Gnss(ds.gnss_csv));
        return d;
      },
      py::arg("path"), py::kw_only(), py::arg("skip_missing_images") = true,
      R"(Reads a EuRoC/ASL dataset folder (the sequence folder holding mav0/, or mav0/ itself),
as `optinav vio` reads it. Times are int64 nanoseconds. Returns a dict:
  cam0, cam1, cam2 (the nadir camera): {t_ns (K,), images (K paths), calibration {camera_model,
    resolution (w, h), intrinsics (fx, fy, cx, cy), distortion_model, distortion, rate_hz,
    body_from_cam (4x4)}}
  imu: {t_ns (M,), gyro_rad_s (M, 3), accel_m_s2 (M, 3), calibration {rate_hz, noise densities
    and random walks, body_from_imu (4x4)}}
  groundtruth: {t_ns (N,), position (N, 3), quaternion_wxyz (N, 4)}: the pose world_from_body
    (velocity and biases are not read); optinav.eval.ape/rpe take this dict as a trajectory
  gnss: {kind enu|lat_lon_height, t_ns, values (G, 3), sigma_m (G,; NaN when not given)}
  baro: {t_ns (B,), altitude_m (B,), calibration {rate_hz, noise_sigma_m, bias_sigma_m,
    bias_random_walk}}
A part the folder does not have is None. skip_missing_images drops listed frames whose file is
missing, with a warning (as `optinav vio` does; real clips list frames they do not ship); False
makes them an error. Raises optinav.Error naming the file, line and field of a malformed file.)");
}

}  // namespace optinav::python
