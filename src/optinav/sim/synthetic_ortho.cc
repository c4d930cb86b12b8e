#include "optinav/sim/synthetic_ortho.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

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

namespace {

// Smooth value noise in [-1, 1] (sum of octaves from `cells` up to size / 4).
cv::Mat ValueNoise(int size, int cells, double persistence, std::mt19937& rng) {
  cv::Mat acc(size, size, CV_32F, cv::Scalar(0));
  double amp = 1.0, total = 0;
  for (int c = cells; c <= size / 4; c *= 2) {
    cv::Mat small(c, c, CV_32F);
    cv::randu(small, cv::Scalar(-1), cv::Scalar(1));
    cv::Mat big;
    cv::resize(small, big, acc.size(), 0, 0, cv::INTER_CUBIC);
    acc += amp * big;
    total += amp;
    amp *= persistence;
  }
  return acc / total;
}

}  // namespace

void WriteSyntheticFarmland(const std::string& path, int size, double gsd_m, unsigned seed) {
  std::mt19937 rng(seed);
  cv::theRNG().state = seed;
  std::uniform_real_distribution<double> u(0, 1);
  cv::Mat img(size, size, CV_8UC3);
  // Parcels: a jittered grid of ~400 m fields, split in two at random.
  const double field_m = 400.0;
  const int n = std::max(2, static_cast<int>(size * gsd_m / field_m));
  const double cell = static_cast<double>(size) / n;
  for (int gy = 0; gy < n; ++gy) {
    for (int gx = 0; gx < n; ++gx) {
      std::vector<cv::Rect> parts = {
          cv::Rect(static_cast<int>(gx * cell), static_cast<int>(gy * cell),
                   static_cast<int>(cell) + 1, static_cast<int>(cell) + 1)};
      if (u(rng) < 0.5) {
        const cv::Rect r = parts[0];
        const double f = 0.3 + 0.4 * u(rng);
        if (u(rng) < 0.5) {
          parts = {cv::Rect(r.x, r.y, static_cast<int>(r.width * f), r.height),
                   cv::Rect(r.x + static_cast<int>(r.width * f), r.y,
                            r.width - static_cast<int>(r.width * f), r.height)};
        } else {
          parts = {cv::Rect(r.x, r.y, r.width, static_cast<int>(r.height * f)),
                   cv::Rect(r.x, r.y + static_cast<int>(r.height * f), r.width,
                            r.height - static_cast<int>(r.height * f))};
        }
      }
      for (const cv::Rect& part : parts) {
        const cv::Rect r = part & cv::Rect(0, 0, size, size);
        if (r.empty()) continue;
        // Crops are greens/yellows/browns; stripes along a random row direction.
        const double g = 90 + 100 * u(rng);
        const cv::Vec3d tone(g * (0.55 + 0.2 * u(rng)), g, g * (0.8 + 0.35 * u(rng)));
        const double angle = (u(rng) < 0.5 ? 0.0 : M_PI / 2) + 0.05 * (u(rng) - 0.5);
        const double period = 3 + 6 * u(rng), depth = 4 + 18 * u(rng);
        for (int y = r.y; y < r.y + r.height; ++y) {
          cv::Vec3b* row = img.ptr<cv::Vec3b>(y);
          for (int x = r.x; x < r.x + r.width; ++x) {
            const double s =
                std::sin((x * std::cos(angle) + y * std::sin(angle)) * 2 * M_PI / period);
            for (int c = 0; c < 3; ++c) row[x][c] = cv::saturate_cast<uint8_t>(tone[c] + depth * s);
          }
        }
      }
    }
  }
  // Fine texture and large-scale shading.
  const cv::Mat shade = ValueNoise(size, 4, 0.5, rng);
  const cv::Mat fine = ValueNoise(size, size / 8, 0.6, rng);
  // Water: where a low-frequency field is low; smooth shores.
  const cv::Mat water = ValueNoise(size, 6, 0.55, rng);
  for (int y = 0; y < size; ++y) {
    cv::Vec3b* row = img.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const double k = 1.0 + 0.12 * shade.at<float>(y, x) + 0.10 * fine.at<float>(y, x);
      for (int c = 0; c < 3; ++c) row[x][c] = cv::saturate_cast<uint8_t>(row[x][c] * k);
      const float w = water.at<float>(y, x);
      if (w < -0.32f) {
        const double d = std::min(1.0, (-0.32 - w) / 0.05);  // shore blend
        const cv::Vec3d lake(70, 55, 35);                    // BGR: dark blue-grey
        for (int c = 0; c < 3; ++c)
          row[x][c] = cv::saturate_cast<uint8_t>((1 - d) * row[x][c] + d * lake[c]);
      }
    }
  }
  // Roads along the parcel grid (gravel: light), and farmsteads (bright roofs, dark shade).
  for (int i = 0; i <= n; ++i) {
    const int p = static_cast<int>(i * cell);
    if (u(rng) < 0.6) cv::line(img, {p, 0}, {p, size - 1}, cv::Scalar(185, 195, 200), 2);
    if (u(rng) < 0.6) cv::line(img, {0, p}, {size - 1, p}, cv::Scalar(185, 195, 200), 2);
  }
  for (int i = 0; i < n * n / 3; ++i) {
    const cv::Point c(static_cast<int>(u(rng) * size), static_cast<int>(u(rng) * size));
    for (int b = 0; b < 3 + static_cast<int>(4 * u(rng)); ++b) {
      const cv::Point o(c.x + static_cast<int>(20 * (u(rng) - 0.5)),
                        c.y + static_cast<int>(20 * (u(rng) - 0.5)));
      const cv::Size s(2 + static_cast<int>(5 * u(rng)), 2 + static_cast<int>(4 * u(rng)));
      cv::rectangle(img, o + cv::Point(1, 1), o + cv::Point(s.width + 1, s.height + 1),
                    cv::Scalar(40, 50, 45), -1);
      cv::rectangle(img, o, o + cv::Point(s.width, s.height), cv::Scalar(215, 215, 220), -1);
    }
    cv::circle(img, c + cv::Point(12, 0), 6, cv::Scalar(40, 80, 50), -1);  // shelter belt
  }
  geo::GeoTransform gt;
  gt.c = {480000.0, gsd_m, 0.0, 5210000.0, 0.0, -gsd_m};
  geo::WriteGeoTiff(path, img, gt, "EPSG:26914", {.tiled = true, .compress = "NONE"});
}

}  // namespace optinav::sim
