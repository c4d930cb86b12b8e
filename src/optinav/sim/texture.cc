#include "optinav/sim/internal/texture.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "optinav/util/error.h"

namespace optinav::sim {

Texture::Texture(const cv::Mat& image) {
  OPTINAV_CHECK(image.type() == CV_8UC3 && !image.empty());
  int s = 1;
  while (s < std::max(image.cols, image.rows)) s *= 2;
  cv::Mat base = image;
  if (image.cols != s || image.rows != s) cv::resize(image, base, {s, s}, 0, 0, cv::INTER_AREA);
  size_ = s;
  levels_.push_back(base.clone());
  while (levels_.back().cols > 1) {
    cv::Mat down;
    cv::resize(levels_.back(), down, {levels_.back().cols / 2, levels_.back().rows / 2}, 0, 0,
               cv::INTER_AREA);
    levels_.push_back(down);
  }
  for (const cv::Mat& l : levels_) views_.push_back({l.data, l.step[0], l.cols});
}

cv::Mat TileableNoise(int size, int cell, uint64_t seed) {
  const int g = std::max(1, size / cell);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  cv::Mat grid(g, g, CV_32F);
  for (int i = 0; i < g * g; ++i) grid.at<float>(i / g, i % g) = u(rng);
  // 3x3 copies, upsample, keep the centre: seamless wrap-around.
  cv::Mat tiled;
  cv::repeat(grid, 3, 3, tiled);
  cv::Mat big;
  cv::resize(tiled, big, {3 * size, 3 * size}, 0, 0, cv::INTER_CUBIC);
  return big(cv::Rect(size, size, size, size)).clone();
}

cv::Mat FractalNoise(int size, uint64_t seed, int finest_cell) {
  cv::Mat sum = cv::Mat::zeros(size, size, CV_32F);
  double amp = 1, total = 0;
  int k = 0;
  for (int cell = size / 4; cell >= finest_cell; cell /= 2, amp *= 0.6, ++k) {
    sum += amp * TileableNoise(size, cell, seed * 131 + k);
    total += amp;
  }
  cv::Mat out = sum / total;
  cv::normalize(out, out, 0, 1, cv::NORM_MINMAX);
  return out;
}

namespace {

// Colour image from noise n in [0,1] blending colours a -> b.
cv::Mat Blend(const cv::Mat& n, cv::Scalar a, cv::Scalar b) {
  cv::Mat out(n.size(), CV_8UC3);
  for (int y = 0; y < n.rows; ++y) {
    for (int x = 0; x < n.cols; ++x) {
      const float t = n.at<float>(y, x);
      auto& px = out.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) px[c] = cv::saturate_cast<uint8_t>(a[c] * (1 - t) + b[c] * t);
    }
  }
  return out;
}

// Random small marks (stones, pebbles, blades): ellipses with random colour jitter.
void Speckle(cv::Mat& img, int count, int min_r, int max_r, cv::Scalar base, int jitter,
             std::mt19937_64& rng) {
  std::uniform_int_distribution<int> px(0, img.cols - 1), r(min_r, max_r), ang(0, 179),
      j(-jitter, jitter);
  for (int i = 0; i < count; ++i) {
    const int d = j(rng);
    const cv::Scalar c(base[0] + d, base[1] + d, base[2] + d);
    const cv::Point p(px(rng), px(rng));
    // Draw the wrapped copies too, so the texture stays seamless.
    for (int oy : {-img.rows, 0, img.rows}) {
      for (int ox : {-img.cols, 0, img.cols}) {
        cv::ellipse(img, p + cv::Point(ox, oy), {r(rng), std::max(1, r(rng) / 2)}, ang(rng), 0, 360,
                    c, cv::FILLED, cv::LINE_AA);
      }
    }
  }
}

}  // namespace

cv::Mat MakeSurfaceImage(SurfaceKind kind, uint64_t seed) {
  std::mt19937_64 rng(seed * 7919 + static_cast<int>(kind));
  constexpr int kSize = 512;
  switch (kind) {
    case SurfaceKind::kAsphalt: {
      cv::Mat img = Blend(FractalNoise(kSize, seed, 2), {60, 62, 64}, {115, 118, 120});
      Speckle(img, 1500, 1, 3, {140, 140, 140}, 40, rng);
      Speckle(img, 200, 3, 8, {50, 52, 55}, 10, rng);  // patches, cracks
      // Lane markings: edge lines at u = 0.05 and 0.95, a centre dash of 3 m every 8 m
      // (this texture spans 8 m along v).
      const int w = kSize / 40;
      cv::rectangle(img, {kSize / 20 - w / 2, 0}, {kSize / 20 + w / 2, kSize}, {225, 225, 225},
                    cv::FILLED);
      cv::rectangle(img, {kSize * 19 / 20 - w / 2, 0}, {kSize * 19 / 20 + w / 2, kSize},
                    {225, 225, 225}, cv::FILLED);
      cv::rectangle(img, {kSize / 2 - w / 2, kSize / 8},
                    {kSize / 2 + w / 2, kSize / 8 + 3 * kSize / 8}, {40, 200, 230}, cv::FILLED);
      // Wear on the markings keeps them from being perfectly uniform.
      Speckle(img, 300, 1, 3, {90, 92, 95}, 20, rng);
      return img;
    }
    case SurfaceKind::kSidewalk: {
      cv::Mat img = Blend(FractalNoise(kSize, seed, 2), {150, 160, 165}, {190, 198, 205});
      const int tile = kSize / 8;
      for (int y = 0; y < 8; ++y) {
        const int shift = (y % 2) * tile / 2;
        cv::line(img, {0, y * tile}, {kSize, y * tile}, {95, 100, 105}, 3);
        for (int x = 0; x <= 8; ++x) {
          cv::line(img, {x * tile + shift, y * tile}, {x * tile + shift, (y + 1) * tile},
                   {95, 100, 105}, 3);
        }
      }
      Speckle(img, 250, 2, 6, {120, 128, 135}, 25, rng);
      return img;
    }
    case SurfaceKind::kGrass:
    case SurfaceKind::kSoil: {
      const bool soil = kind == SurfaceKind::kSoil;
      cv::Mat n = FractalNoise(kSize, seed, 2);
      cv::Mat img =
          soil ? Blend(n, {25, 55, 75}, {85, 150, 125}) : Blend(n, {15, 60, 25}, {90, 180, 120});
      // Dark clumps, dry tufts and bare patches: structure at several scales for trackers.
      Speckle(img, 600, 3, 9, soil ? cv::Scalar(20, 40, 50) : cv::Scalar(10, 35, 15), 12, rng);
      Speckle(img, 350, 3, 8, soil ? cv::Scalar(120, 150, 170) : cv::Scalar(90, 170, 190), 25, rng);
      std::uniform_int_distribution<int> px(0, kSize - 1), len(4, 12), d(-3, 3);
      for (int i = 0; i < 3000; ++i) {  // blades
        const cv::Point p(px(rng), px(rng));
        const int g = 90 + 8 * d(rng);
        cv::line(img, p, p + cv::Point(d(rng), -len(rng)), {30.0 + 5 * d(rng), double(g + 50), 60},
                 1, cv::LINE_AA);
      }
      Speckle(img, soil ? 900 : 500, 2, soil ? 7 : 5,
              soil ? cv::Scalar(100, 115, 125) : cv::Scalar(60, 100, 120), 35, rng);
      return img;
    }
    case SurfaceKind::kFacade: {
      // Variant colours from the seed: plaster or brick tones.
      std::uniform_int_distribution<int> c(0, 5);
      const cv::Scalar tones[] = {{170, 190, 215}, {120, 130, 170}, {200, 200, 200},
                                  {90, 110, 160},  {150, 170, 180}, {180, 160, 140}};
      const cv::Scalar tone = tones[c(rng)];
      cv::Mat img = Blend(FractalNoise(kSize, seed, 2), tone * 0.75, tone * 1.1);
      if (seed % 2) {  // brick courses
        for (int y = 0; y < kSize; y += 16) cv::line(img, {0, y}, {kSize, y}, tone * 0.55, 2);
      }
      // A window with frame, sill and a random blind / reflection.
      std::uniform_int_distribution<int> blind(0, 200);
      const cv::Rect win(kSize * 3 / 10, kSize * 2 / 10, kSize * 2 / 5, kSize / 2);
      cv::rectangle(img, win + cv::Size(24, 24) - cv::Point(12, 12), {235, 235, 235}, cv::FILLED);
      cv::Mat glass =
          Blend(TileableNoise(kSize, 64, seed + 5)(cv::Rect(0, 0, win.width, win.height)),
                {90, 70, 50}, {160, 130, 110});
      glass.copyTo(img(win));
      cv::rectangle(img, {win.x, win.y + blind(rng) * win.height / 400}, {win.x + win.width, win.y},
                    {120, 170, 200}, cv::FILLED);
      cv::line(img, {win.x + win.width / 2, win.y}, {win.x + win.width / 2, win.y + win.height},
               {235, 235, 235}, 8);
      cv::rectangle(img, {win.x - 20, win.y + win.height + 10},
                    {win.x + win.width + 20, win.y + win.height + 26}, tone * 0.5, cv::FILLED);
      return img;
    }
    case SurfaceKind::kRoof: {
      cv::Mat img = Blend(FractalNoise(kSize, seed, 2), {45, 50, 75}, {80, 85, 120});
      for (int y = 0; y < kSize; y += 24) cv::line(img, {0, y}, {kSize, y}, {35, 35, 50}, 2);
      return img;
    }
    case SurfaceKind::kCarBody: {
      std::uniform_int_distribution<int> c(30, 220);
      const cv::Scalar paint(c(rng), c(rng), c(rng));
      cv::Mat img = Blend(TileableNoise(256, 64, seed), paint * 0.8, paint * 1.1);
      cv::rectangle(img, {30, 40}, {110, 120}, {60, 40, 30}, cv::FILLED);  // windows
      cv::rectangle(img, {140, 40}, {225, 120}, {60, 40, 30}, cv::FILLED);
      cv::circle(img, {60, 215}, 34, {25, 25, 25}, cv::FILLED);  // wheels
      cv::circle(img, {195, 215}, 34, {25, 25, 25}, cv::FILLED);
      cv::circle(img, {60, 215}, 14, {170, 170, 170}, cv::FILLED);
      cv::circle(img, {195, 215}, 14, {170, 170, 170}, cv::FILLED);
      return img;
    }
    case SurfaceKind::kBark: {
      cv::Mat img = Blend(FractalNoise(256, seed, 2), {20, 40, 60}, {60, 90, 110});
      for (int x = 0; x < 256; x += 12) cv::line(img, {x, 0}, {x + 3, 256}, {15, 30, 45}, 2);
      return img;
    }
    case SurfaceKind::kFoliage: {
      cv::Mat img = Blend(FractalNoise(256, seed, 2), {20, 70, 30}, {50, 140, 70});
      Speckle(img, 600, 2, 6, {25, 100, 45}, 30, rng);
      Speckle(img, 200, 1, 3, {20, 45, 25}, 10, rng);
      return img;
    }
    case SurfaceKind::kRock: {
      cv::Mat img = Blend(FractalNoise(256, seed, 2), {80, 85, 90}, {160, 165, 170});
      Speckle(img, 300, 1, 4, {60, 65, 70}, 30, rng);
      return img;
    }
    case SurfaceKind::kSnowGround: {
      cv::Mat img = Blend(FractalNoise(kSize, seed, 2), {215, 215, 210}, {250, 250, 248});
      Speckle(img, 400, 1, 3, {190, 195, 200}, 15, rng);
      return img;
    }
  }
  return {};
}

}  // namespace optinav::sim
