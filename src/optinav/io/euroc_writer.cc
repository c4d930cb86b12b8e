#include "optinav/io/euroc_writer.h"

#include <fmt/format.h>

#include "optinav/io/text_parse.h"
#include "optinav/util/error.h"

namespace optinav::io {
namespace {

// The T_BS block of a sensor.yaml (OpenCV matrix layout, row-major).
std::string MatrixYaml(const Eigen::Matrix4d& m) {
  std::string s = "  cols: 4\n  rows: 4\n  data: [";
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      s += fmt::format("{:.12f}{}", m(r, c),
                       r == 3 && c == 3 ? "]\n" : (c == 3 ? ",\n         " : ", "));
    }
  }
  return s;
}

}  // namespace

void WriteImageList(const std::string& path, const std::vector<ImageEntry>& images) {
  std::string s = "#timestamp [ns],filename\n";
  for (const ImageEntry& e : images) s += fmt::format("{},{}\n", e.t_ns, e.path);
  WriteFileAtomically(path, s);
}

void WriteCameraSensorYaml(const std::string& path, const CameraCalibration& c,
                           const std::string& comment) {
  const bool none = c.distortion_model == "none";
  if (!none && c.distortion.size() != 4) {
    throw Error(fmt::format("distortion model {} needs 4 coefficients, got {}", c.distortion_model,
                            c.distortion.size()),
                {.file = path, .field = "distortion_coefficients"});
  }
  const std::vector<double> k = none ? std::vector<double>(4, 0.0) : c.distortion;
  WriteFileAtomically(
      path,
      fmt::format(
          "%YAML:1.0\n# written by optinav sim\nsensor_type: camera\ncomment: {}\n\n# Sensor "
          "extrinsics wrt. the "
          "body-frame.\nT_BS:\n{}\n# Camera specific definitions.\nrate_hz: {:.6f}\nresolution: "
          "[{}, {}]\ncamera_model: pinhole\nintrinsics: [{:.9f}, {:.9f}, {:.9f}, {:.9f}] #fu, fv, "
          "cu, cv\ndistortion_model: {}\ndistortion_coefficients: [{:.12g}, {:.12g}, {:.12g}, "
          "{:.12g}]\n",
          comment, MatrixYaml(c.body_from_cam.ToMatrix()), c.rate_hz, c.width, c.height, c.fx, c.fy,
          c.cx, c.cy, none ? "radial-tangential" : c.distortion_model, k[0], k[1], k[2], k[3]));
}

void WriteImuSensorYaml(const std::string& path, const ImuCalibration& c, bool noise_free,
                        const std::string& comment) {
  WriteFileAtomically(
      path,
      fmt::format("%YAML:1.0\n# written by optinav sim\nsensor_type: imu\ncomment: {}\n\n# Sensor "
                  "extrinsics wrt. the body-frame.\nT_BS:\n{}\n"
                  "rate_hz: {:.6f}\n\n# inertial sensor noise model parameters (static)\n"
                  "gyroscope_noise_density: {:.9g}     # [ rad / s / sqrt(Hz) ]\n"
                  "gyroscope_random_walk: {:.9g}       # [ rad / s^2 / sqrt(Hz) ]\n"
                  "accelerometer_noise_density: {:.9g} # [ m / s^2 / sqrt(Hz) ]\n"
                  "accelerometer_random_walk: {:.9g}   # [ m / s^3 / sqrt(Hz) ]\n"
                  "noise_free: {}\n",
                  comment, MatrixYaml(c.body_from_imu.ToMatrix()), c.rate_hz,
                  c.gyroscope_noise_density, c.gyroscope_random_walk, c.accelerometer_noise_density,
                  c.accelerometer_random_walk, noise_free ? "true" : "false"));
}

void WriteImuCsv(const std::string& path, const std::vector<ImuSample>& samples) {
  std::string s =
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
      "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  for (const ImuSample& m : samples) {
    s += fmt::format("{},{:.12f},{:.12f},{:.12f},{:.12f},{:.12f},{:.12f}\n", m.t_ns,
                     m.gyro_rad_s.x(), m.gyro_rad_s.y(), m.gyro_rad_s.z(), m.accel_m_s2.x(),
                     m.accel_m_s2.y(), m.accel_m_s2.z());
  }
  WriteFileAtomically(path, s);
}

void WriteBaroCsv(const std::string& path, const std::vector<BaroSample>& samples) {
  std::string s = "#timestamp [ns],altitude [m]\n";
  for (const BaroSample& m : samples) s += fmt::format("{},{:.6f}\n", m.t_ns, m.altitude_m);
  WriteFileAtomically(path, s);
}

void WriteBaroSensorYaml(const std::string& path, const BaroCalibration& c,
                         const std::string& comment) {
  WriteFileAtomically(
      path, fmt::format("%YAML:1.0\n# written by optinav sim\nsensor_type: barometer\n"
                        "comment: {}\n\n# altitude = z of the body in the world frame + bias + "
                        "noise\nrate_hz: {:.6f}\n"
                        "noise_sigma_m: {:.9g}     # [ m ] white noise per sample\n"
                        "bias_sigma_m: {:.9g}      # [ m ] initial bias, 1 sigma\n"
                        "bias_random_walk: {:.9g}  # [ m / sqrt(s) ]\n",
                        comment, c.rate_hz, c.noise_sigma_m, c.bias_sigma_m, c.bias_random_walk));
}

void WriteGroundTruthCsv(const std::string& path, const std::vector<GroundTruthState>& states) {
  std::string s =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
      "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad "
      "s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m "
      "s^-2], b_a_RS_S_z [m s^-2]\n";
  for (const GroundTruthState& st : states) {
    const Eigen::Vector3d& p = st.world_from_body.translation;
    const Eigen::Vector4d q = QuaternionToWxyz(st.world_from_body.rotation);
    const Eigen::Vector3d& v = st.velocity_in_world;
    s += fmt::format(
        "{},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9g},{:.9g},"
        "{:.9g},{:.9g},{:.9g},{:.9g}\n",
        st.t_ns, p.x(), p.y(), p.z(), q[0], q[1], q[2], q[3], v.x(), v.y(), v.z(), st.gyro_bias.x(),
        st.gyro_bias.y(), st.gyro_bias.z(), st.accel_bias.x(), st.accel_bias.y(),
        st.accel_bias.z());
  }
  WriteFileAtomically(path, s);
}

void WriteGnssCsv(const std::string& path, GnssFileKind kind,
                  const std::vector<GnssRecord>& records, const std::vector<bool>* outliers) {
  if (outliers && outliers->size() != records.size()) {
    throw Error(
        fmt::format("{} outlier flags for {} GNSS records", outliers->size(), records.size()),
        {.file = path, .field = "outlier"});
  }
  const bool enu = kind == GnssFileKind::kEnu;
  std::string s = enu ? "#timestamp [ns], x [m], y [m], z [m]"
                      : "#timestamp [ns], latitude [deg], longitude [deg], height [m]";
  s += outliers ? ", outlier\n" : "\n";
  for (size_t i = 0; i < records.size(); ++i) {
    const GnssRecord& r = records[i];
    s += enu ? fmt::format("{},{:.6f},{:.6f},{:.6f}", r.t_ns, r.value.x(), r.value.y(), r.value.z())
             : fmt::format("{},{:.10f},{:.10f},{:.6f}", r.t_ns, r.value.x(), r.value.y(),
                           r.value.z());
    s += outliers ? fmt::format(",{}\n", (*outliers)[i] ? 1 : 0) : "\n";
  }
  WriteFileAtomically(path, s);
}

void WriteGnssSensorYaml(const std::string& path, const GnssSensorDescription& g) {
  std::string outages = "[";
  for (size_t i = 0; i < g.outages_s.size(); ++i) {
    outages += fmt::format("{}[{:.3f}, {:.3f}]", i ? ", " : "", g.outages_s[i].first,
                           g.outages_s[i].second);
  }
  outages += "]";
  WriteFileAtomically(
      path,
      fmt::format(
          "%YAML:1.0\n# written by optinav sim\nsensor_type: gnss\ncomment: antenna position; "
          "data.csv local ENU metres about the origin, llh.csv WGS84\n\n# Antenna (lever arm) "
          "wrt. the body-frame.\nT_BS:\n{}\nrate_hz: {:.6f}\nsigma_m: {:.6f}\n"
          "outlier_fraction: {:.6f}\noutlier_magnitude_m: {:.6f}\noutages_s: {} # [start, "
          "duration] after the first sample\norigin_latitude_deg: {:.9f}\norigin_longitude_deg: "
          "{:.9f}\norigin_height_m: {:.4f}\n",
          MatrixYaml(Rigid3d(Eigen::Quaterniond::Identity(), g.lever_arm_in_body).ToMatrix()),
          g.rate_hz, g.sigma_m, g.outlier_fraction, g.outlier_magnitude_m, outages,
          g.origin_lat_lon_height.x(), g.origin_lat_lon_height.y(), g.origin_lat_lon_height.z()));
}

}  // namespace optinav::io
