#include "optinav/app/map_info.h"

#include <algorithm>
#include <cstdint>

#include <fmt/printf.h>

#include "optinav/geo/geo.h"

namespace optinav::app {
namespace {

struct Summary {
  geo::LatLon upper_left, lower_right;
  size_t min_features = SIZE_MAX, max_features = 0, padded = 0;
  std::string feature_type;
};

Summary Summarize(const maploc::MapDatabase& db) {
  Summary s;
  const geo::CrsTransform crs(db.crs_wkt);
  s.upper_left = crs.ToLatLon(db.transform.PixelToCrs({0, 0}));
  s.lower_right = crs.ToLatLon(db.transform.PixelToCrs({double(db.width), double(db.height)}));
  for (const auto& t : db.tiles) {
    s.min_features = std::min(s.min_features, t.keypoints.size());
    s.max_features = std::max(s.max_features, t.keypoints.size());
    s.padded += t.padded;
  }
  s.feature_type = features::FeatureTypeName(db.feature_type);
  return s;
}

}  // namespace

nlohmann::json MapInfoJson(const maploc::MapDatabase& db) {
  const Summary s = Summarize(db);
  return {{"format_version", db.format_version},
          {"ortho", db.ortho_path},
          {"crs", db.crs_name},
          {"width_px", db.width},
          {"height_px", db.height},
          {"map_gsd_m", db.map_gsd_m},
          {"extent_m", {db.width * db.map_gsd_m, db.height * db.map_gsd_m}},
          {"upper_left", {s.upper_left.lat_deg, s.upper_left.lon_deg}},
          {"lower_right", {s.lower_right.lat_deg, s.lower_right.lon_deg}},
          {"tiles",
           {{"cols", db.cols},
            {"rows", db.rows},
            {"count", db.tiles.size()},
            {"padded", s.padded},
            {"side_px", db.tile_px},
            {"step_px", db.step_px}}},
          {"features",
           {{"type", s.feature_type},
            {"total", db.FeatureCount()},
            {"min_per_tile", s.min_features},
            {"max_per_tile", s.max_features}}},
          {"feature_gsd_m", db.feature_gsd_m}};
}

std::string MapInfoText(const std::string& path, const maploc::MapDatabase& db) {
  const Summary s = Summarize(db);
  return fmt::sprintf(
      "map database %s (format %d)\n"
      "  orthophoto : %s\n"
      "  CRS        : %s\n"
      "  size       : %d x %d px at %.3f m/px (%.0f x %.0f m)\n"
      "  extent     : UL %.6f, %.6f  LR %.6f, %.6f (lat, lon)\n"
      "  tiles      : %d cols x %d rows = %zu (%zu padded), side %.0f px, step %.0f px\n"
      "  features   : %s, %zu in total, %zu..%zu per tile, taken at %.3f m/px\n",
      path.c_str(), db.format_version, db.ortho_path.c_str(), db.crs_name.c_str(), db.width,
      db.height, db.map_gsd_m, db.width * db.map_gsd_m, db.height * db.map_gsd_m,
      s.upper_left.lat_deg, s.upper_left.lon_deg, s.lower_right.lat_deg, s.lower_right.lon_deg,
      db.cols, db.rows, db.tiles.size(), s.padded, db.tile_px, db.step_px, s.feature_type.c_str(),
      db.FeatureCount(), s.min_features, s.max_features, db.feature_gsd_m);
}

std::string MapCheckText(const maploc::MapCheckReport& r) {
  return fmt::sprintf(
      "  check      : ok, SQLite integrity check passed; CRC-32 of the metadata and of all %zu "
      "tiles (%zu features, %zu blob bytes) match\n",
      r.tiles, r.features, r.checked_bytes);
}

nlohmann::json MapCheckJson(const maploc::MapCheckReport& r) {
  return {{"ok", true},
          {"sqlite_integrity", "ok"},
          {"checksum", "crc32"},
          {"tiles_verified", r.tiles},
          {"features", r.features},
          {"blob_bytes", r.checked_bytes}};
}

}  // namespace optinav::app
