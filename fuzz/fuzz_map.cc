#include "fuzz/fuzz_map.h"

#include <filesystem>

#include <opencv2/imgproc.hpp>

#include "optinav/geo/raster.h"
#include "optinav/maploc/map_db.h"

namespace optinav::fuzz {

std::string BuildSmallMap(const std::string& dir) {
  const std::string ortho = dir + "/fuzz_ortho.tif", db = dir + "/fuzz_map.db";
  if (std::filesystem::exists(db)) return db;
  std::filesystem::create_directories(dir);
  // Blurred noise at two scales: corners and blobs for ORB, no repeated pattern.
  cv::RNG rng(22);
  cv::Mat fine(256, 256, CV_8UC1), coarse(32, 32, CV_8UC1);
  rng.fill(fine, cv::RNG::UNIFORM, 0, 256);
  rng.fill(coarse, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(fine, fine, cv::Size(5, 5), 1.5);
  cv::resize(coarse, coarse, fine.size(), 0, 0, cv::INTER_CUBIC);
  cv::Mat img;
  cv::addWeighted(fine, 0.5, coarse, 0.5, 0, img);
  geo::GeoTransform gt;
  gt.c = {500000.0, 1.0, 0.0, 5560000.0, 0.0, -1.0};
  geo::WriteGeoTiff(ortho, img, gt, "EPSG:32633", {.tiled = false, .compress = "NONE"});
  maploc::MapBuildOptions o;
  o.altitude_m = 100;  // footprint 115 m: 115 px tiles, a 4 x 4 grid at overlap 0.5
  o.frame_width = 160;
  o.frame_height = 120;
  o.max_features = 24;
  o.threads = 1;
  maploc::BuildMapDatabase(ortho, o, db);
  return db;
}

}  // namespace optinav::fuzz
