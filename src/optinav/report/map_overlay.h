// The orthophoto under the HTML report's map: Leaflet stretches an overlay image linearly in Web
// Mercator between its corners, so a map in any other CRS (UTM, ...) is resampled onto a
// north-up Mercator grid first; it then lies in its true position at every zoom.
#pragma once

#include <functional>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "optinav/geo/geo.h"

namespace optinav::report {

struct MercatorImage {
  cv::Mat image;  // 8-bit grey or BGR; outside the picture: light grey
  geo::LatLon south_west, north_east;
};

// `picture` is the map image (any size); the two functions convert between WGS84 and its pixel
// coordinates (continuous, (0, 0) the top-left corner). The result is at most `max_side` pixels
// across. The projection is evaluated on a coarse grid and interpolated between (it is smooth at
// the scale of a picture).
MercatorImage ToMercatorImage(
    const cv::Mat& picture,
    const std::function<Eigen::Vector2d(const geo::LatLon&)>& latlon_to_picture_px,
    const std::function<geo::LatLon(const Eigen::Vector2d&)>& picture_px_to_latlon, int max_side);

// JPEG bytes of an image (quality 0-100) written atomically; throws Error on failure.
void WriteJpeg(const std::string& path, const cv::Mat& image, int quality = 80);

}  // namespace optinav::report
