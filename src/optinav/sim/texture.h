// Mip-mapped, repeating textures and the procedural texture generators of the synthetic worlds.
//
// Textures are BGR, square power-of-two sizes, addressed with wrap-around (u, v in texture
// repeats: 1.0 is one copy). Level k is level 0 reduced 2^k times by area averaging, so sampling
// at the level that matches the pixel footprint avoids aliasing on distant, grazing surfaces.
// Generators are deterministic functions of their seed: the same seed gives the same texels.
#pragma once

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
  // Bilinear sample at (u, v) from the level nearest `lod` (log2 of texels per pixel).
  void Sample(double u, double v, float lod, uint8_t bgr[3]) const;

 private:
  std::vector<cv::Mat> levels_;
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
