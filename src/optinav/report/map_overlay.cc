#include "optinav/report/map_overlay.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/io/text_parse.h"
#include "optinav/util/error.h"

namespace optinav::report {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Spherical Mercator (as Leaflet's EPSG:3857) on the unit sphere.
Eigen::Vector2d Mercator(const geo::LatLon& ll) {
  return {ll.lon_deg * kDegToRad, std::log(std::tan(M_PI / 4 + ll.lat_deg * kDegToRad / 2))};
}
geo::LatLon FromMercator(const Eigen::Vector2d& m) {
  return {(2 * std::atan(std::exp(m.y())) - M_PI / 2) / kDegToRad, m.x() / kDegToRad};
}

}  // namespace

MercatorImage ToMercatorImage(
    const cv::Mat& picture,
    const std::function<Eigen::Vector2d(const geo::LatLon&)>& latlon_to_picture_px,
    const std::function<geo::LatLon(const Eigen::Vector2d&)>& picture_px_to_latlon, int max_side) {
  OPTINAV_CHECK(!picture.empty() && max_side > 1);
  // The picture's outline in Mercator: its bounding box is the overlay's.
  Eigen::Vector2d lo(INFINITY, INFINITY), hi(-INFINITY, -INFINITY);
  constexpr int kEdge = 16;
  for (int k = 0; k <= kEdge; ++k) {
    const double f = static_cast<double>(k) / kEdge;
    for (const Eigen::Vector2d& px :
         {Eigen::Vector2d(f * picture.cols, 0), Eigen::Vector2d(f * picture.cols, picture.rows),
          Eigen::Vector2d(0, f * picture.rows), Eigen::Vector2d(picture.cols, f * picture.rows)}) {
      const Eigen::Vector2d m = Mercator(picture_px_to_latlon(px));
      lo = lo.cwiseMin(m);
      hi = hi.cwiseMax(m);
    }
  }
  const Eigen::Vector2d size = hi - lo;
  const double per_px = std::max(size.x(), size.y()) / max_side;
  const int w = std::max(2, static_cast<int>(std::ceil(size.x() / per_px)));
  const int h = std::max(2, static_cast<int>(std::ceil(size.y() / per_px)));
  // The projection at the nodes of a coarse grid over the output pixel centres, bilinearly
  // interpolated between them.
  constexpr int kGrid = 32;
  std::vector<Eigen::Vector2d> node((kGrid + 1) * (kGrid + 1));
  for (int r = 0; r <= kGrid; ++r)
    for (int c = 0; c <= kGrid; ++c) {
      const double ox = (w - 1) * static_cast<double>(c) / kGrid + 0.5;
      const double oy = (h - 1) * static_cast<double>(r) / kGrid + 0.5;
      const Eigen::Vector2d m(lo.x() + ox / w * size.x(), hi.y() - oy / h * size.y());
      // cv::remap addresses pixel centres at integers.
      node[r * (kGrid + 1) + c] = latlon_to_picture_px(FromMercator(m)) - Eigen::Vector2d(0.5, 0.5);
    }
  cv::Mat map_x(h, w, CV_32F), map_y(h, w, CV_32F);
  for (int y = 0; y < h; ++y) {
    const double v = static_cast<double>(y) * kGrid / (h - 1);
    const int r = std::min(static_cast<int>(v), kGrid - 1);
    const double fv = v - r;
    for (int x = 0; x < w; ++x) {
      const double u = static_cast<double>(x) * kGrid / (w - 1);
      const int c = std::min(static_cast<int>(u), kGrid - 1);
      const double fu = u - c;
      const auto at = [&](int rr, int cc) { return node[rr * (kGrid + 1) + cc]; };
      const Eigen::Vector2d p = (1 - fv) * ((1 - fu) * at(r, c) + fu * at(r, c + 1)) +
                                fv * ((1 - fu) * at(r + 1, c) + fu * at(r + 1, c + 1));
      map_x.at<float>(y, x) = static_cast<float>(p.x());
      map_y.at<float>(y, x) = static_cast<float>(p.y());
    }
  }
  MercatorImage out;
  const cv::Scalar outside = picture.channels() == 1 ? cv::Scalar(235) : cv::Scalar(235, 235, 235);
  cv::remap(picture, out.image, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, outside);
  out.south_west = FromMercator({lo.x(), lo.y()});
  out.north_east = FromMercator({hi.x(), hi.y()});
  return out;
}

void WriteJpeg(const std::string& path, const cv::Mat& image, int quality) {
  std::vector<unsigned char> bytes;
  if (!cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, quality}))
    throw Error("cannot encode the image as JPEG", {.file = path});
  io::WriteFileAtomically(path, std::string(bytes.begin(), bytes.end()));
}

}  // namespace optinav::report
