// Mip-mapped, repeating textures and the procedural texture generators of the synthetic worlds.
//
// Textures are BGR, square power-of-two sizes, addressed with wrap-around (u, v in texture
// repeats: 1.0 is one copy). Level k is level 0 reduced 2^k times by area averaging, so sampling
// at the level that matches the pixel footprint avoids aliasing on distant, grazing surfaces.
// Generators are deterministic functions of their seed: the same seed gives the same texels.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace optinav::sim {

class Texture {
 public:
  Texture() = default;
  // `image`: CV_8UC3; resized to the next power of two when needed.
  explicit Texture(const cv::Mat& image);

  int size() const { return size_; }
  int levels() const { return static_cast<int>(levels_.size()); }
  const cv::Mat& level(int k) const { return levels_[k]; }
  // Trilinear sample at (u, v): bilinear at the two levels around `lod` (log2 of texels per
  // pixel), blended by its fraction, so the sharpness changes continuously with distance (a
  // nearest-level sampler jumps at lod k + 0.5, and that seam travels with the camera and makes
  // corners no real camera sees). Inline: the renderer calls it for every textured pixel.
  void Sample(double u, double v, float lod, uint8_t bgr[3]) const {
    const int last = static_cast<int>(views_.size()) - 1;
    if (!(lod > 0.0f)) return Bilinear(views_[0], u, v, 256, bgr, nullptr);
    const int k = static_cast<int>(lod);
    if (k >= last) return Bilinear(views_[last], u, v, 256, bgr, nullptr);
    const int w1 = static_cast<int>((lod - static_cast<float>(k)) * 256.0f);  // weight of k + 1
    uint32_t acc[3] = {0, 0, 0};
    Bilinear(views_[k], u, v, 256 - w1, nullptr, acc);
    Bilinear(views_[k + 1], u, v, w1, nullptr, acc);
    for (int c = 0; c < 3; ++c) bgr[c] = static_cast<uint8_t>((acc[c] + (1 << 23)) >> 24);
  }

 private:
  struct LevelView {
    const uint8_t* data;
    size_t step;
    int n;
  };
  // Bilinear sample of one level, in fixed point: with `out`, the rounded colour (weight 256);
  // else `weight` / 256 of it added to `acc` in 8.24 fixed point (unsigned: two levels' worth
  // plus the rounding term reach 255 * 2^24 + 2^23, over a signed int's range).
  static void Bilinear(const LevelView& lv, double u, double v, int weight, uint8_t* out,
                       uint32_t* acc) {
    // Wrap first (in double: u may be hundreds of repeats), then work in float.
    const float x = static_cast<float>((u - std::floor(u)) * lv.n) - 0.5f;
    const float y = static_cast<float>((v - std::floor(v)) * lv.n) - 0.5f;
    const int ix = static_cast<int>(x + 1.0f) - 1, iy = static_cast<int>(y + 1.0f) - 1;  // floor
    const int mask = lv.n - 1;
    const int ax = ix & mask, ay = iy & mask, bx = (ix + 1) & mask, by = (iy + 1) & mask;
    const int wx = static_cast<int>((x - ix) * 256.0f), wy = static_cast<int>((y - iy) * 256.0f);
    const uint8_t* r0 = lv.data + ay * lv.step;
    const uint8_t* r1 = lv.data + by * lv.step;
    const uint8_t *p00 = r0 + 3 * ax, *p01 = r0 + 3 * bx, *p10 = r1 + 3 * ax, *p11 = r1 + 3 * bx;
    for (int c = 0; c < 3; ++c) {
      const int top = p00[c] * (256 - wx) + p01[c] * wx;
      const int bot = p10[c] * (256 - wx) + p11[c] * wx;
      const uint32_t value = static_cast<uint32_t>(top * (256 - wy) + bot * wy);  // 8.16
      if (out)
        out[c] = static_cast<uint8_t>((value + (1 << 15)) >> 16);
      else
        acc[c] += value * static_cast<uint32_t>(weight);  // sum <= 255 * 2^24 (+ 2^23) < 2^32
    }
  }

  std::vector<cv::Mat> levels_;
  std::vector<LevelView> views_;  // raw access to levels_ (same order)
  int size_ = 0;
};

// Tileable smooth noise in [0, 1]: random values on a (size / cell) grid, cubic-interpolated,
// with wrap-around so the texture repeats seamlessly.
cv::Mat TileableNoise(int size, int cell, uint64_t seed);
// Sum of octaves of TileableNoise (cells size/4, size/8, ..., 2 px), normalised to [0, 1].
cv::Mat FractalNoise(int size, uint64_t seed, int finest_cell = 2);

enum class SurfaceKind {
  kAsphalt,   // road: asphalt with lane markings along v (u across the road, 0..1 = 8 m)
  kSidewalk,  // paving stones
  kGrass,
  kSoil,    // terrain: patchy grass over soil with pebbles
  kFacade,  // building wall: one window per texture (one 3 m x 3 m module)
  kRoof,
  kCarBody,  // a car side/top with windows
  kBark,
  kFoliage,
  kRock,
  kSnowGround,  // (used by the weather)
};

// A 512 x 512 (256 for small objects) procedural texture of the given kind and variant.
cv::Mat MakeSurfaceImage(SurfaceKind kind, uint64_t seed);

}  // namespace optinav::sim
