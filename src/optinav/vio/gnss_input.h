// GNSS input for the fusion: a file (the dataset's gnss0/data.csv by default, ENU, or a
// latitude/longitude/height csv) converted through the geo layer to the local ENU frame of an
// origin (gnss0/sensor.yaml's, a configured one, or the first fix), with the lever arm and the
// default sigma from gnss0/sensor.yaml unless given.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "optinav/io/gnss_io.h"
#include "optinav/vio/gnss_fusion.h"

namespace optinav::vio {

struct GnssInputOptions {
  std::string file;                      // empty: <dataset>/mav0/gnss0/data.csv
  std::string sensor_yaml;               // empty: sensor.yaml next to the file, when present
  std::optional<io::GnssFileKind> kind;  // nullopt: from the header
  std::optional<Eigen::Vector3d> origin_lat_lon_height;  // overrides the yaml's
  std::optional<double> sigma_m;                         // overrides the yaml's (default 1 m)
  std::optional<Eigen::Vector3d> lever_arm_in_body;      // overrides the yaml's (default 0)
};

struct GnssInput {
  std::vector<GnssSample> samples;  // ENU about `origin`
  // The ENU origin (lat deg, lon deg, ellipsoidal height m), when known: from the yaml, the
  // options, or the first fix of a latitude/longitude file. ENU files without one cannot be
  // written as WGS84.
  std::optional<Eigen::Vector3d> origin_lat_lon_height;
  Eigen::Vector3d lever_arm_in_body = Eigen::Vector3d::Zero();
  double default_sigma_m = 1.0;
  std::string file;
  size_t dropped_non_finite = 0;
};

// Throws Error naming the file/line/field on bad input (and when the file is missing).
GnssInput LoadGnssInput(const std::string& dataset_dir, const GnssInputOptions& options);

}  // namespace optinav::vio
