#include "optinav/io/euroc_dataset.h"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "optinav/io/text_parse.h"
#include "optinav/util/config.h"

namespace fs = std::filesystem;

namespace optinav::io {
namespace {

Rigid3d ReadTbs(const YamlFile& f) {
  const std::vector<double> d = YamlGetNumbers(f, f.root, "T_BS", 16);
  Eigen::Matrix<double, 3, 4> m;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = d[4 * r + c];
  }
  const Eigen::Matrix3d rot = m.leftCols<3>();
  if ((rot * rot.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-3 ||
      rot.determinant() < 0) {
    throw Error("T_BS rotation block is not a rotation", {.file = f.path, .field = "T_BS"});
  }
  return Rigid3d::FromMatrix(m);
}

void CheckIncreasing(int64_t prev, int64_t t, const ErrorContext& ctx) {
  if (t <= prev) {
    throw Error(fmt::format("timestamp {} ns does not increase (previous {} ns)", t, prev), ctx);
  }
}

}  // namespace

CameraCalibration ReadCameraCalibration(const std::string& sensor_yaml) {
  const YamlFile f = LoadYamlFile(sensor_yaml);
  CameraCalibration c;
  c.camera_model = YamlGetOr<std::string>(f, f.root, "camera_model", "pinhole");
  if (c.camera_model != "pinhole") {
    throw Error("unsupported camera_model '" + c.camera_model + "' (only pinhole)",
                {.file = sensor_yaml, .field = "camera_model"});
  }
  const auto res = YamlGetNumbers(f, f.root, "resolution", 2);
  // Checked before the conversion: a value beyond int is undefined behaviour (a fuzz finding).
  for (const double side : res) {
    if (!(side >= 1 && side <= 1e6 && side == std::floor(side))) {
      throw Error("resolution must be two whole numbers in [1, 1000000]",
                  {.file = sensor_yaml, .field = "resolution"});
    }
  }
  c.width = static_cast<int>(res[0]);
  c.height = static_cast<int>(res[1]);
  const auto k = YamlGetNumbers(f, f.root, "intrinsics", 4);
  c.fx = k[0];
  c.fy = k[1];
  c.cx = k[2];
  c.cy = k[3];
  if (c.fx <= 0 || c.fy <= 0) {
    throw Error("focal lengths must be positive", {.file = sensor_yaml, .field = "intrinsics"});
  }
  camera::DistortionModel model;
  try {
    model =
        camera::ParseDistortionModel(YamlGetOr<std::string>(f, f.root, "distortion_model", "none"));
  } catch (const Error& e) {
    throw Error(e.what(), {.file = sensor_yaml, .field = "distortion_model"});
  }
  c.distortion_model = camera::DistortionModelName(model);  // canonical name
  if (model != camera::DistortionModel::kNone) {
    c.distortion = YamlGetNumbers(f, f.root, "distortion_coefficients", 4);
  }
  c.rate_hz = YamlGetOr<double>(f, f.root, "rate_hz", 0.0);
  c.body_from_cam = ReadTbs(f);
  return c;
}

ImuCalibration ReadImuCalibration(const std::string& sensor_yaml) {
  const YamlFile f = LoadYamlFile(sensor_yaml);
  ImuCalibration c;
  c.rate_hz = YamlGet<double>(f, f.root, "rate_hz");
  c.gyroscope_noise_density = YamlGet<double>(f, f.root, "gyroscope_noise_density");
  c.gyroscope_random_walk = YamlGet<double>(f, f.root, "gyroscope_random_walk");
  c.accelerometer_noise_density = YamlGet<double>(f, f.root, "accelerometer_noise_density");
  c.accelerometer_random_walk = YamlGet<double>(f, f.root, "accelerometer_random_walk");
  for (const auto& [name, value] : {std::pair{"rate_hz", c.rate_hz},
                                    {"gyroscope_noise_density", c.gyroscope_noise_density},
                                    {"gyroscope_random_walk", c.gyroscope_random_walk},
                                    {"accelerometer_noise_density", c.accelerometer_noise_density},
                                    {"accelerometer_random_walk", c.accelerometer_random_walk}}) {
    if (!(value > 0)) throw Error("must be positive", {.file = sensor_yaml, .field = name});
  }
  c.body_from_imu = ReadTbs(f);
  return c;
}

std::vector<ImageEntry> ReadImageList(const std::string& data_csv, const std::string& image_dir,
                                      bool check_exist, bool drop_missing) {
  size_t dropped = 0;
  std::string first_dropped;
  const std::string text = ReadFileToString(data_csv);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  std::vector<ImageEntry> out;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = data_csv, .line = cursor.line_number()};
    SplitFields(line, ',', &f);
    if (f.size() != 2) {
      throw Error(fmt::format("expected 'timestamp [ns], filename', found {} fields", f.size()),
                  ctx);
    }
    ctx.field = "timestamp";
    ImageEntry e{.t_ns = ParseInt64(f[0], ctx), .path = (fs::path(image_dir) / f[1]).string()};
    if (!out.empty()) CheckIncreasing(out.back().t_ns, e.t_ns, ctx);
    // The error_code overload: a name the OS refuses (too long, ...) is a missing image, not a
    // filesystem_error escaping the reader (found by fuzz/euroc_images).
    std::error_code exists_ec;
    if (check_exist && !fs::is_regular_file(e.path, exists_ec)) {
      ctx.field = "filename";
      if (drop_missing) {
        if (dropped++ == 0) first_dropped = FormatErrorMessage(e.path, ctx);
        continue;
      }
      throw Error("image file not found: " + e.path, ctx);
    }
    out.push_back(std::move(e));
  }
  if (dropped > 0) {
    spdlog::warn("{}: dropped {} listed image(s) that do not exist, first: {}", data_csv, dropped,
                 first_dropped);
  }
  return out;
}

std::vector<ImuSample> ReadImuCsv(const std::string& data_csv) {
  static constexpr const char* kFields[] = {"timestamp", "w_x", "w_y", "w_z", "a_x", "a_y", "a_z"};
  const std::string text = ReadFileToString(data_csv);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  double v[6];
  std::vector<ImuSample> out;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = data_csv, .line = cursor.line_number()};
    SplitFields(line, ',', &f);
    if (f.size() != 7) {
      throw Error(
          fmt::format("expected 'timestamp, wx, wy, wz, ax, ay, az', found {} fields", f.size()),
          ctx);
    }
    ctx.field = kFields[0];
    const int64_t t = ParseInt64(f[0], ctx);
    for (size_t k = 0; k < 6; ++k) {
      ctx.field = kFields[k + 1];
      v[k] = ParseFiniteDouble(f[k + 1], ctx);
    }
    ctx.field = kFields[0];
    if (!out.empty()) CheckIncreasing(out.back().t_ns, t, ctx);
    out.push_back({t, Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5])});
  }
  return out;
}

std::vector<BaroSample> ReadBaroCsv(const std::string& data_csv) {
  const std::string text = ReadFileToString(data_csv);
  LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  std::vector<BaroSample> out;
  while (cursor.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    ErrorContext ctx{.file = data_csv, .line = cursor.line_number()};
    SplitFields(line, ',', &f);
    if (f.size() != 2) {
      throw Error(fmt::format("expected 'timestamp [ns], altitude [m]', found {} fields", f.size()),
                  ctx);
    }
    ctx.field = "timestamp";
    const int64_t t = ParseInt64(f[0], ctx);
    if (!out.empty()) CheckIncreasing(out.back().t_ns, t, ctx);
    ctx.field = "altitude";
    out.push_back({t, ParseFiniteDouble(f[1], ctx)});
  }
  return out;
}

BaroCalibration ReadBaroCalibration(const std::string& sensor_yaml) {
  const YamlFile f = LoadYamlFile(sensor_yaml);
  BaroCalibration c;
  c.rate_hz = YamlGet<double>(f, f.root, "rate_hz");
  c.noise_sigma_m = YamlGet<double>(f, f.root, "noise_sigma_m");
  c.bias_sigma_m = YamlGet<double>(f, f.root, "bias_sigma_m");
  c.bias_random_walk = YamlGet<double>(f, f.root, "bias_random_walk");
  for (const auto& [name, value] :
       {std::pair{"rate_hz", c.rate_hz}, {"noise_sigma_m", c.noise_sigma_m}}) {
    if (!(value > 0 && std::isfinite(value))) {
      throw Error("must be positive", {.file = sensor_yaml, .field = name});
    }
  }
  for (const auto& [name, value] :
       {std::pair{"bias_sigma_m", c.bias_sigma_m}, {"bias_random_walk", c.bias_random_walk}}) {
    if (!(value >= 0 && std::isfinite(value))) {
      throw Error("must be zero or positive", {.file = sensor_yaml, .field = name});
    }
  }
  return c;
}

EurocDataset OpenEurocDataset(const std::string& dir, const EurocOpenOptions& options) {
  fs::path root(dir);
  if (!fs::is_directory(root)) throw Error("dataset folder not found", {.file = dir});
  CheckNotInProgress(dir);
  if (fs::is_directory(root / "mav0")) root /= "mav0";
  EurocDataset ds;
  ds.mav0_dir = root.string();
  for (const char* cam : {"cam0", "cam1", "cam2"}) {
    const fs::path cdir = root / cam;
    if (!fs::is_directory(cdir)) continue;
    CameraStream stream;
    stream.calibration = ReadCameraCalibration((cdir / "sensor.yaml").string());
    stream.images = ReadImageList((cdir / "data.csv").string(), (cdir / "data").string(),
                                  options.check_images_exist, options.drop_missing_images);
    if (stream.images.empty()) {
      throw Error("camera lists no images", {.file = (cdir / "data.csv").string()});
    }
    const std::string name(cam);
    (name == "cam0" ? ds.cam0 : name == "cam1" ? ds.cam1 : ds.cam2) = std::move(stream);
  }
  if (fs::is_directory(root / "imu0")) {
    ds.imu_calibration = ReadImuCalibration((root / "imu0" / "sensor.yaml").string());
    ds.imu_csv = (root / "imu0" / "data.csv").string();
    if (!fs::is_regular_file(ds.imu_csv)) throw Error("missing IMU data", {.file = ds.imu_csv});
  }
  if (fs::is_directory(root / "baro0")) {
    ds.baro_calibration = ReadBaroCalibration((root / "baro0" / "sensor.yaml").string());
    ds.baro_csv = (root / "baro0" / "data.csv").string();
    if (!fs::is_regular_file(ds.baro_csv)) {
      throw Error("missing barometer data", {.file = ds.baro_csv});
    }
  }
  if (fs::is_regular_file(root / "gnss0" / "data.csv")) {
    ds.gnss_csv = (root / "gnss0" / "data.csv").string();
  }
  if (fs::is_regular_file(root / "state_groundtruth_estimate0" / "data.csv")) {
    ds.groundtruth_csv = (root / "state_groundtruth_estimate0" / "data.csv").string();
  }
  if (!ds.cam0 && !ds.imu_calibration) {
    throw Error("not a EuRoC/ASL dataset: neither mav0/cam0 nor mav0/imu0 found", {.file = dir});
  }
  return ds;
}

camera::PinholeCamera ToPinholeCamera(const CameraCalibration& c) {
  camera::PinholeCamera cam;
  cam.width = c.width;
  cam.height = c.height;
  cam.fx = c.fx;
  cam.fy = c.fy;
  cam.cx = c.cx;
  cam.cy = c.cy;
  cam.distortion = camera::ParseDistortionModel(c.distortion_model);
  if (cam.distortion != camera::DistortionModel::kNone) {
    if (c.distortion.size() != 4) {
      throw Error("distortion model " + c.distortion_model + " needs 4 coefficients, got " +
                  std::to_string(c.distortion.size()));
    }
    for (int i = 0; i < 4; ++i) cam.coeffs[i] = c.distortion[i];
  }
  cam.Validate();
  return cam;
}

CameraCalibration ToCameraCalibration(const camera::PinholeCamera& camera,
                                      const Rigid3d& body_from_cam, double rate_hz) {
  CameraCalibration c;
  c.width = camera.width;
  c.height = camera.height;
  c.fx = camera.fx;
  c.fy = camera.fy;
  c.cx = camera.cx;
  c.cy = camera.cy;
  c.distortion_model = camera::DistortionModelName(camera.distortion);
  if (camera.distortion != camera::DistortionModel::kNone) {
    c.distortion.assign(camera.coeffs.begin(), camera.coeffs.end());
  }
  c.rate_hz = rate_hz;
  c.body_from_cam = body_from_cam;
  return c;
}

camera::StereoRig ToStereoRig(const CameraCalibration& left, const CameraCalibration& right) {
  camera::StereoRig rig;
  rig.left = ToPinholeCamera(left);
  rig.right = ToPinholeCamera(right);
  rig.right_from_left = right.body_from_cam.Inverse() * left.body_from_cam;
  return rig;
}

}  // namespace optinav::io
