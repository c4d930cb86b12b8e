// GNSS position files: the `gnss0/data.csv` of the GNSS-VIO document ("timestamp [ns], x, y, z"
// in a local ENU frame, metres) and latitude/longitude/height files ("timestamp [ns], latitude
// [deg], longitude [deg], height [m]"), both with an optional per-sample sigma column (metres,
// per axis) named "sigma..." in the header. Rows with a non-finite value are dropped (a receiver
// without a fix) and reported; unsorted or duplicated stamps, a sigma <= 0, coordinates out of
// range and malformed rows are errors naming the file, line and field.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace optinav::io {

enum class GnssFileKind { kEnu, kLatLonHeight };

struct GnssRecord {
  int64_t t_ns = 0;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();  // x y z [m], or lat [deg] lon [deg] h [m]
  std::optional<double> sigma_m;                    // per axis
  int64_t line = 0;                                 // 1-based line in the file
};

struct GnssFile {
  GnssFileKind kind = GnssFileKind::kEnu;
  std::vector<GnssRecord> records;
  size_t dropped_non_finite = 0;
  int64_t first_dropped_line = 0;
};

// `kind`: nullopt detects it from the header (a column named "lat..." -> latitude/longitude/
// height; otherwise, and without a header, ENU). Throws Error naming the file/line/field.
GnssFile ReadGnssFile(const std::string& path, std::optional<GnssFileKind> kind = std::nullopt);

// What `gnss0/sensor.yaml` (as `optinav sim` writes it) says; every field optional.
struct GnssSensorInfo {
  std::optional<Eigen::Vector3d> lever_arm_in_body;  // translation of T_BS
  std::optional<double> sigma_m;
  std::optional<Eigen::Vector3d> origin_lat_lon_height;  // deg, deg, m
};
GnssSensorInfo ReadGnssSensorYaml(const std::string& path);

}  // namespace optinav::io
