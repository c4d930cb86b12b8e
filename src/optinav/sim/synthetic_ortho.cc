#include "optinav/sim/synthetic_ortho.h"

#include <algorithm>
#include <random>

#include <opencv2/imgproc.hpp>

#include "optinav/geo/raster.h"

namespace optinav::sim {

void WriteSyntheticOrtho(const std::string& path, int size, double gsd_m, unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat acc(size, size, CV_32F, cv::Scalar(0));
  double amp = 1.0;
  for (int cells = 8; cells <= size / 4; cells *= 4) {
    cv::Mat small(cells, cells, CV_32F);
    cv::randu(small, cv::Scalar(-1), cv::Scalar(1));
    cv::Mat big;
    cv::resize(small, big, acc.size(), 0, 0, cv::INTER_CUBIC);
    acc += amp * big;
    amp *= 0.6;
  }
  cv::Mat img;
  cv::normalize(acc, acc, 30, 225, cv::NORM_MINMAX);
  acc.convertTo(img, CV_8U);
  std::uniform_int_distribution<int> pos(0, size - 1);
  for (int i = 0; i < size / 400; ++i) {
    cv::line(img, {pos(rng), 0}, {pos(rng), size - 1}, cv::Scalar(235), std::max(2, size / 2000));
    cv::line(img, {0, pos(rng)}, {size - 1, pos(rng)}, cv::Scalar(20), std::max(2, size / 2500));
  }
  geo::GeoTransform gt;
  gt.c = {480000.0, gsd_m, 0.0, 5210000.0, 0.0, -gsd_m};
  geo::WriteGeoTiff(path, img, gt, "EPSG:26914", {.tiled = true, .compress = "NONE"});
}

}  // namespace optinav::sim
