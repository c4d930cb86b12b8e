// Shared fixtures for maploc tests: real imagery wrapped into GeoTIFFs.
#pragma once

#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/geo/raster.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/locator.h"
#include "optinav/maploc/map_db.h"
#include "optinav/util/testing.h"

namespace optinav::maploc::testmaps {

// aero1.jpg (a real aerial photograph) as a GeoTIFF at 0.25 m/px in WGS 84 / UTM 33N.
inline std::string Aero1GeoTiff(const std::filesystem::path& dir) {
  const cv::Mat img = cv::imread((testing::SharedDataDir() / "images" / "aero1.jpg").string());
  geo::GeoTransform gt;
  gt.c = {500000.0, 0.25, 0.0, 5560000.0, 0.0, -0.25};
  const std::string path = (dir / "aero1_utm33.tif").string();
  geo::WriteGeoTiff(path, img, gt, "EPSG:32633");
  return path;
}

inline std::string Naip(const std::string& year) {
  return (testing::SharedDataDir() / "geo" / "naip" / ("naip_" + year + ".tif")).string();
}

// The NAIP 2009 map of the tests: built for a 256x256 camera with a 90 deg field of view at
// 640 m (footprint 1280 m = 256 px at the tile's 5 m).
inline MapDatabase BuildNaip2009Map(const std::filesystem::path& dir,
                                    features::FeatureType type = features::FeatureType::kOrb) {
  MapBuildOptions o;
  o.frame_width = 256;
  o.frame_height = 256;
  o.hfov_deg = 90;
  o.altitude_m = 640;
  o.feature_type = type;
  if (type == features::FeatureType::kXFeat) {
    o.model_path = (testing::SharedDataDir() / "models" / "xfeat_640x640.onnx").string();
  }
  return BuildMapDatabase(Naip("20090818"), o,
                          (dir / ("naip2009_" + features::FeatureTypeName(type) + ".db")).string());
}

// A test suite sharing one NAIP 2009 map (built once per suite, in a temporary folder) with
// `kType` features.
template <features::FeatureType kType>
class Naip2009MapTestOf : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(testing::MakeTempDir("naip2009"));
    db_ = new MapDatabase(BuildNaip2009Map(*dir_, kType));
  }
  static void TearDownTestSuite() {
    delete db_;
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }
  inline static std::filesystem::path* dir_ = nullptr;
  inline static MapDatabase* db_ = nullptr;
};
using Naip2009MapTest = Naip2009MapTestOf<features::FeatureType::kOrb>;
using Naip2009XFeatMapTest = Naip2009MapTestOf<features::FeatureType::kXFeat>;

// What locate is given for a perspective frame: altitude and attitude always, the prior position
// and the heading when asked.
inline Prior GivenPrior(const PerspectiveFrame& f, bool with_prior, bool with_heading) {
  Prior p;
  p.altitude_m = f.given_altitude_m;
  p.roll_deg = f.given_roll_deg;
  p.pitch_deg = f.given_pitch_deg;
  if (with_prior) {
    p.position = f.prior;
    p.radius_m = f.prior_radius_m;
  }
  if (with_heading) {
    p.heading_deg = f.given_heading_deg;
    p.heading_sigma_deg = f.heading_sigma_deg;
  }
  return p;
}

}  // namespace optinav::maploc::testmaps
