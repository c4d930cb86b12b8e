// Camera frames synthesised from an orthophoto, as the orthophoto-navigation thesis (SEEDS.md part
// 3) does (crop around the true position, rotate by the heading, crop larger then centre-crop),
// plus what real flights add: altitude (scale) and camera tilt (perspective). Used by tests,
// benchmarks and missions.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "optinav/geo/raster.h"

namespace optinav::maploc {

struct FrameSpec {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // ground point under the frame centre
  double heading_deg = 0;  // frame up direction, clockwise from map up (-y)
  double gsd_m = 1.0;      // metres per frame pixel at the centre
  int width = 640, height = 480;
  double tilt_deg = 0;          // camera pitch away from nadir (perspective)
  double tilt_azimuth_deg = 0;  // direction of the tilt in the frame (0 = towards frame up)
  double focal_px = 0;          // for the perspective of a tilt; 0: from a 60 deg FOV
};

// Renders the frame from the raster (map resolution map_gsd_m); pixels outside the map are 0.
// Returns also the 3x3 homography frame px -> map px when `frame_to_map` is given.
cv::Mat SynthesizeFrame(const geo::GeoRaster& raster, double map_gsd_m, const FrameSpec& spec,
                        cv::Matx33d* frame_to_map = nullptr);

}  // namespace optinav::maploc
