#include "optinav/vio/gnss_input.h"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "optinav/geo/geo.h"
#include "optinav/util/error.h"
#include "optinav/util/logging.h"

namespace fs = std::filesystem;

namespace optinav::vio {

GnssInput LoadGnssInput(const std::string& dataset_dir, const GnssInputOptions& options) {
  GnssInput in;
  in.file = options.file;
  if (in.file.empty()) {
    fs::path root(dataset_dir);
    if (fs::is_directory(root / "mav0")) root /= "mav0";
    in.file = (root / "gnss0" / "data.csv").string();
  }
  if (!fs::is_regular_file(in.file))
    throw Error("GNSS file not found (give one with --gnss-file)", {.file = in.file});
  std::string yaml = options.sensor_yaml;
  if (yaml.empty() && fs::is_regular_file(fs::path(in.file).parent_path() / "sensor.yaml"))
    yaml = (fs::path(in.file).parent_path() / "sensor.yaml").string();
  io::GnssSensorInfo info;
  if (!yaml.empty()) info = io::ReadGnssSensorYaml(yaml);
  in.lever_arm_in_body =
      options.lever_arm_in_body.value_or(info.lever_arm_in_body.value_or(Eigen::Vector3d::Zero()));
  in.default_sigma_m = options.sigma_m.value_or(info.sigma_m.value_or(1.0));
  if (!(in.default_sigma_m > 0)) throw Error("GNSS sigma must be > 0", {.field = "--gnss-sigma"});
  in.origin_lat_lon_height =
      options.origin_lat_lon_height ? options.origin_lat_lon_height : info.origin_lat_lon_height;
  if (options.origin_lat_lon_height) {
    const Eigen::Vector3d& o = *options.origin_lat_lon_height;
    if (std::abs(o[0]) > 90 || std::abs(o[1]) > 180)
      throw Error(fmt::format("origin latitude {} / longitude {} out of range", o[0], o[1]),
                  {.field = "--gnss-origin"});
  }

  const io::GnssFile file = io::ReadGnssFile(in.file, options.kind);
  in.dropped_non_finite = file.dropped_non_finite;
  if (file.records.empty()) throw Error("no usable GNSS sample", {.file = in.file});
  std::optional<geo::LocalEnu> enu;
  if (file.kind == io::GnssFileKind::kLatLonHeight) {
    if (!in.origin_lat_lon_height) {
      in.origin_lat_lon_height = file.records.front().value;
      spdlog::info("gnss: ENU origin = the first fix ({:.8f}, {:.8f}, {:.2f} m)",
                   file.records.front().value[0], file.records.front().value[1],
                   file.records.front().value[2]);
    }
    const Eigen::Vector3d& o = *in.origin_lat_lon_height;
    enu.emplace(geo::LatLon{o[0], o[1]}, o[2]);
  }
  in.samples.reserve(file.records.size());
  for (const io::GnssRecord& r : file.records) {
    GnssSample s;
    s.t_ns = r.t_ns;
    s.sigma_m = r.sigma_m.value_or(in.default_sigma_m);
    s.position_enu_m = enu ? enu->ToEnu(geo::LatLon{r.value[0], r.value[1]}, r.value[2]) : r.value;
    in.samples.push_back(s);
  }
  return in;
}

}  // namespace optinav::vio
