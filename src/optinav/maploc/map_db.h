// The orthophoto feature database: a georeferenced orthophoto cut into overlapping square tiles,
// each with its bounds (map pixels, CRS, latitude/longitude) and local features.
//
// Stored as one SQLite file (docs/MAPDB.md): a real embedded database gives atomic writes,
// integrity checks, random access to tiles and a schema other tools can open. It is written to
// MAP.db.tmp and renamed into place only when complete, so a failed build never leaves a file
// that looks complete.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "optinav/features/features.h"
#include "optinav/geo/geo.h"

namespace optinav::maploc {

// 2: CRC-32 checksums on the metadata and on every tile's geometry, keypoints and descriptors.
constexpr int kMapFormatVersion = 2;

// Network px per map-feature px for XFeat tiles (see MapBuildOptions::xfeat_scale): XFeat finds
// its keypoints on 8x8 cells and was trained on photographs of a few hundred pixels across; the
// 5 m/px NAIP tiles of 256 px match best upsampled (docs/MAPDB.md, "XFeat").
constexpr double kXFeatTileScale = 2.0;

// CRC-32 (IEEE 802.3 / zlib polynomial, reflected), continuing from `crc` (0 to start): the
// checksum the database stores; Python's zlib.crc32 gives the same value.
uint32_t Crc32(const void* data, size_t size, uint32_t crc = 0);

struct MapBuildOptions {
  double altitude_m = 300.0;                  // flight altitude above ground
  double hfov_deg = 60.0;                     // horizontal field of view of the camera
  int frame_width = 640, frame_height = 480;  // camera frame size, pixels
  // Tile side = scale_factor x the frame's ground footprint width (the orthophoto-navigation
  // thesis, SEEDS.md part 3, reduces tiles so that altitude, zoom and view changes still overlap
  // one tile well).
  double scale_factor = 1.0;
  double overlap = 0.5;  // fraction of a tile shared with its neighbour, [0, 0.9]
  features::FeatureType feature_type = features::FeatureType::kOrb;
  int max_features = 1024;  // per tile
  // XFeat maps: the network file ("" = features::DefaultXFeatModelPath()) and the tile image's
  // resampling to the network (network px per tile px; 0 = automatic: kXFeatTileScale, or less
  // when the tile would not fit the 640 px input). Frames are resampled by the same factor at
  // locate time (stored in build_options), so map and frame features meet at one scale.
  std::string model_path;
  double xfeat_scale = 0;
  int threads = 2;            // 0: all hardware threads
  std::string Check() const;  // "" when valid, else names the field and value
};

struct MapTile {
  int index = 0, row = 0, col = 0;
  cv::Rect2d px;                       // bounds in map pixels (may extend past the raster)
  std::array<geo::LatLon, 4> corners;  // UL, UR, LR, LL
  geo::LatLon centre;
  Eigen::Vector2d centre_crs = Eigen::Vector2d::Zero();
  bool padded = false;                 // extends past the raster (filled with no-data)
  std::vector<cv::Point2f> keypoints;  // map pixels (full resolution)
  std::vector<float> keypoint_size, keypoint_angle;
  cv::Mat descriptors;
};

struct MapDatabase {
  int format_version = kMapFormatVersion;
  std::string ortho_path, crs_wkt, crs_name;
  geo::GeoTransform transform;
  int width = 0, height = 0;        // raster size, pixels
  double map_gsd_m = 0;             // metres per map pixel
  double feature_gsd_m = 0;         // metres per pixel of the images features were taken on
  double tile_px = 0, step_px = 0;  // tile side and spacing, map pixels
  int rows = 0, cols = 0;
  MapBuildOptions options;
  features::FeatureType feature_type = features::FeatureType::kOrb;
  std::vector<MapTile> tiles;

  size_t FeatureCount() const;
  // Map pixel <-> CRS <-> lat/lon helpers.
  Eigen::Vector2d PixelToCrs(const Eigen::Vector2d& px) const { return transform.PixelToCrs(px); }
};

// A sharded build (`map build --shard I/N`): shard `index` of `count` holds the tiles
// [total x index / count, total x (index + 1) / count) of the grid (contiguous rows, so a shard
// reads one band of the orthophoto). index is 0-based.
struct MapShard {
  int index = 0, count = 1;
  bool whole() const { return count == 1; }
  std::string ToString() const;  // "I/N"
  std::string Check() const;     // "" when valid
};
// "I/N" (0 <= I < N); throws Error (field: `flag`) otherwise.
MapShard ParseMapShard(const std::string& text, const std::string& flag = "--shard");
// The tile indices [first, last) of a shard of a grid of `total` tiles.
std::pair<int, int> ShardTileRange(int total, const MapShard& shard);

// Builds the database from an orthophoto (parallel over tiles, progress bar on a terminal) and
// writes it atomically to `out_path`. Throws Error on bad input (file, field) or I/O failure.
// With a shard other than the whole, only its tiles are built and written: a part (meta `shard`
// = "I/N", the same format and checksums), which LoadMapDatabase refuses and MergeMapParts joins;
// the returned database then holds only those tiles.
MapDatabase BuildMapDatabase(const std::string& ortho_path, const MapBuildOptions& options,
                             const std::string& out_path, const MapShard& shard = {});

// Joins the parts of a sharded build (every shard of one N exactly once, any order; each part
// verified as LoadMapDatabase verifies a map) into one database at `out_path`, written
// atomically with fresh checksums: the same tiles and features as the unsharded build (the same
// file, byte for byte, when the parts name the same orthophoto). Parts are streamed through one
// at a time: the merge holds one part's tiles in memory, not the map's. Throws Error naming the
// part at fault (missing shards, a shard twice, another build's or split's part).
struct MapMergeSummary {
  MapDatabase db;  // the merged map's metadata (no tiles)
  size_t tiles = 0, features = 0;
};
MapMergeSummary MergeMapParts(const std::vector<std::string>& part_paths,
                              const std::string& out_path);

// Loads a database, verifying the metadata's and every tile's checksums; throws Error naming the
// file if it is not one, is incomplete, has another format version, or is damaged (naming the
// first damaged tile and field, or the metadata). A damaged map is never returned.
MapDatabase LoadMapDatabase(const std::string& path);

// What CheckMapDatabase verified.
struct MapCheckReport {
  MapDatabase db;
  size_t tiles = 0, features = 0;
  size_t checked_bytes = 0;  // keypoint and descriptor blob bytes whose checksums matched
};

// Verifies the whole file: SQLite's own structure check (PRAGMA integrity_check, every page)
// and then LoadMapDatabase's checksums of the metadata and every tile. Throws Error as
// LoadMapDatabase does, naming the first damaged tile.
MapCheckReport CheckMapDatabase(const std::string& path);

// The tile grid BuildMapDatabase would use (no features): for tests and `map info`.
MapDatabase PlanMapDatabase(const std::string& ortho_path, const MapBuildOptions& options);

}  // namespace optinav::maploc
