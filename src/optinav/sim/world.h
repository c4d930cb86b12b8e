// Synthetic worlds: textured triangle meshes with a ground height function.
//
//  urban    a suburban block around the car route of the AirSim weather dataset (SEEDS.md
//           part 1): a road with lane markings and sidewalks along the route, box buildings with
//           windowed facades and roofs, parked cars, street lights, street trees, a park, and a
//           forest ring.
//  terrain  rough open ground: a height field with hills and valleys, patchy grass and soil,
//           rocks, a few trees, and a mountain ridge around it.
//  ortho    flat ground (z = 0) textured with a georeferenced orthophoto (GeoTIFF), placed in
//           the local ENU frame about the orthophoto's centre.
// Everything is a deterministic function of the seed (and the weather's surface effects,
// which change textures only: geometry never depends on the weather).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "optinav/geo/geo.h"
#include "optinav/sim/internal/texture.h"
#include "optinav/sim/trajectory.h"
#include "optinav/sim/weather.h"

namespace optinav::sim {

struct WorldTriangle {
  Eigen::Vector3f p[3];                            // world, metres
  Eigen::Vector2f uv[3];                           // texture coordinates (texture repeats)
  Eigen::Vector3f tint = Eigen::Vector3f::Ones();  // per-channel (BGR) factor incl. shading
  uint16_t texture = 0;
  bool two_sided = false;  // else only the side with counter-clockwise vertices is drawn
};

struct WorldChunk {
  Eigen::AlignedBox3f box;
  std::vector<WorldTriangle> triangles;
};

enum class WorldKind { kUrban, kTerrain, kOrtho };

struct World {
  WorldKind kind = WorldKind::kUrban;
  std::vector<Texture> textures;
  std::vector<WorldChunk> chunks;
  HeightFunction ground_height;  // world z of the ground
  Eigen::Vector2d area_min = Eigen::Vector2d::Zero(), area_max = Eigen::Vector2d::Zero();
  // Sky colours (BGR) at the horizon and the zenith.
  Eigen::Vector3f sky_horizon{235, 215, 195}, sky_zenith{210, 150, 90};
  // For ortho: the ENU origin (orthophoto centre) the world frame is anchored to.
  std::optional<geo::LatLon> origin;
  size_t TriangleCount() const;
};

struct WorldOptions {
  WorldKind kind = WorldKind::kUrban;
  std::string ortho_path;        // kOrtho: the GeoTIFF
  int ortho_max_texture = 4096;  // kOrtho: texture size cap (px)
  uint64_t seed = 1;
  WeatherSpec weather;  // only its surface effects are used here
  // Urban: the road's asphalt in 8 variants, one per 8 m of road, picked by a hash (`optinav sim
  // --asphalt varied`, the default since 2026-12-06), instead of one texture repeating every 8 m
  // (false: `--asphalt tiled`, the road of every sequence rendered before). Ignored elsewhere.
  bool varied_asphalt = true;
};

// "tiled" | "varied" (WorldOptions::varied_asphalt); throws Error naming `field` otherwise. And
// back: the name of a setting.
bool ParseAsphalt(const std::string& text, const std::string& field);
const char* AsphaltName(bool varied);

// "urban" | "terrain" | "ortho:PATH.tif". Throws Error (field "world") otherwise.
WorldOptions ParseWorld(const std::string& text);

// Builds the world. Throws Error for a road-* weather outside the urban world, and for an
// orthophoto that cannot be read or is not georeferenced.
World MakeWorld(const WorldOptions& options);

}  // namespace optinav::sim
