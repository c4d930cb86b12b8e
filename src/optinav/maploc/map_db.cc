#include "optinav/maploc/map_db.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>
#include <sqlite3.h>

#include "optinav/features/xfeat.h"
#include "optinav/geo/raster.h"
#include "optinav/util/progress.h"

namespace optinav::maploc {
namespace {

// RAII wrapper over a sqlite3 handle with error reporting that names the file.
class Db {
 public:
  Db(const std::string& path, int flags) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      db_ = nullptr;
      throw Error("cannot open map database: " + msg, {.file = path});
    }
  }
  ~Db() { sqlite3_close(db_); }
  void Exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string msg = err ? err : "?";
      sqlite3_free(err);
      throw Error("database error: " + msg, {.file = path_});
    }
  }
  sqlite3_stmt* Prepare(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      throw Error(std::string("not a valid optinav map database (") + sqlite3_errmsg(db_) + ")",
                  {.file = path_});
    }
    return st;
  }
  void Check(int rc, const char* what) {
    if (rc != SQLITE_OK && rc != SQLITE_DONE && rc != SQLITE_ROW) {
      throw Error(std::string(what) + ": " + sqlite3_errmsg(db_), {.file = path_});
    }
  }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

struct Stmt {
  sqlite3_stmt* st;
  ~Stmt() { sqlite3_finalize(st); }
};

// A tile's non-blob columns as the bytes its geometry checksum covers: id, row, col, padded and
// n_features as int64, the 16 REAL columns as float64, in column order, little-endian (the
// host's order on every platform optinav builds on). NaN is counted as 0: SQLite stores it as
// NULL, which reads back as 0.
class GeometryBytes {
 public:
  void Int(int64_t v) { Append(&v, sizeof v); }
  void Real(double v) {
    if (std::isnan(v)) v = 0;
    Append(&v, sizeof v);
  }
  uint32_t Crc() const { return Crc32(bytes_.data(), bytes_.size()); }

 private:
  void Append(const void* p, size_t n) { bytes_.append(static_cast<const char*>(p), n); }
  std::string bytes_;
};

// Metadata checksum: every row but `checksum` itself, in key order, as key NUL value NUL.
uint32_t MetaCrc(const std::map<std::string, std::string>& meta) {
  uint32_t crc = 0;
  for (const auto& [k, v] : meta) {
    if (k == "checksum") continue;
    crc = Crc32(k.c_str(), k.size() + 1, crc);
    crc = Crc32(v.c_str(), v.size() + 1, crc);
  }
  return crc;
}

// The database's stored integer for a CRC-32.
int64_t CrcValue(uint32_t crc) { return static_cast<int64_t>(crc); }

nlohmann::json OptionsToJson(const MapBuildOptions& o) {
  nlohmann::json j = {{"altitude_m", o.altitude_m},
                      {"hfov_deg", o.hfov_deg},
                      {"frame_width", o.frame_width},
                      {"frame_height", o.frame_height},
                      {"scale_factor", o.scale_factor},
                      {"overlap", o.overlap},
                      {"features", features::FeatureTypeName(o.feature_type)},
                      {"max_features", o.max_features}};
  // The resolved resampling (never 0 in a built map): frames must be resampled alike.
  if (o.feature_type == features::FeatureType::kXFeat) j["xfeat_scale"] = o.xfeat_scale;
  return j;
}

MapBuildOptions OptionsFromJson(const nlohmann::json& j) {
  MapBuildOptions o;
  o.altitude_m = j.at("altitude_m");
  o.hfov_deg = j.at("hfov_deg");
  o.frame_width = j.at("frame_width");
  o.frame_height = j.at("frame_height");
  o.scale_factor = j.at("scale_factor");
  o.overlap = j.at("overlap");
  const auto type = features::ParseFeatureType(j.at("features").get<std::string>());
  if (!type) throw std::invalid_argument("unknown feature type");
  o.feature_type = *type;
  o.max_features = j.at("max_features");
  if (o.feature_type == features::FeatureType::kXFeat) {
    o.xfeat_scale = j.at("xfeat_scale");
    if (!(o.xfeat_scale > 0 && o.xfeat_scale <= 8))
      throw std::invalid_argument("xfeat_scale out of range");
  }
  return o;
}

// Calls `emit` for every tile to write, in order.
using TileSource = std::function<void(const std::function<void(const MapTile&)>& emit)>;

// Writes m's metadata and the tiles `tiles` emits (default: m.tiles; all of the grid, or a
// shard's: then meta `shard` says which). A source lets a merge stream parts through.
void WriteDatabase(const MapDatabase& m, const std::string& out_path, const MapShard& shard,
                   const TileSource& tiles = {}) {
  const std::string tmp = out_path + ".tmp";
  std::filesystem::remove(tmp);
  {
    Db db(tmp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    db.Exec("PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF;");
    db.Exec(
        "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);"
        "CREATE TABLE tiles(id INTEGER PRIMARY KEY, row INTEGER, col INTEGER,"
        " px0 REAL, py0 REAL, px1 REAL, py1 REAL, crs_cx REAL, crs_cy REAL,"
        " lat_ul REAL, lon_ul REAL, lat_ur REAL, lon_ur REAL, lat_lr REAL, lon_lr REAL,"
        " lat_ll REAL, lon_ll REAL, lat_c REAL, lon_c REAL, padded INTEGER,"
        " n_features INTEGER, keypoints BLOB, descriptors BLOB,"
        " geometry_crc INTEGER, keypoints_crc INTEGER, descriptors_crc INTEGER);");
    db.Exec("BEGIN");
    {
      Stmt ins{db.Prepare("INSERT INTO meta VALUES(?, ?)")};
      nlohmann::json gt = m.transform.c;
      std::map<std::string, std::string> meta = {
          {"format_version", std::to_string(kMapFormatVersion)},
          {"ortho_path", m.ortho_path},
          {"crs_wkt", m.crs_wkt},
          {"crs_name", m.crs_name},
          {"geotransform", gt.dump()},
          {"width", std::to_string(m.width)},
          {"height", std::to_string(m.height)},
          {"map_gsd_m", fmt::format("{}", m.map_gsd_m)},
          {"feature_gsd_m", fmt::format("{}", m.feature_gsd_m)},
          {"tile_px", fmt::format("{}", m.tile_px)},
          {"step_px", fmt::format("{}", m.step_px)},
          {"rows", std::to_string(m.rows)},
          {"cols", std::to_string(m.cols)},
          {"build_options", OptionsToJson(m.options).dump()},
          {"complete", "1"},
      };
      if (!shard.whole()) meta["shard"] = shard.ToString();
      meta["checksum"] = std::to_string(MetaCrc(meta));
      // `complete` is written last, after every tile: a database without it is incomplete.
      meta.erase("complete");
      for (const auto& [k, v] : meta) {
        sqlite3_bind_text(ins.st, 1, k.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(ins.st, 2, v.c_str(), -1, SQLITE_TRANSIENT);
        db.Check(sqlite3_step(ins.st), "insert meta");
        sqlite3_reset(ins.st);
      }
    }
    {
      Stmt ins{db.Prepare(
          "INSERT INTO tiles VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)")};
      std::vector<float> kp;
      const auto write = [&](const MapTile& t) {
        int k = 1;
        GeometryBytes geometry;
        auto bind_int = [&](int64_t v) {
          sqlite3_bind_int64(ins.st, k++, v);
          geometry.Int(v);
        };
        auto bind_real = [&](double v) {
          sqlite3_bind_double(ins.st, k++, v);
          geometry.Real(v);
        };
        bind_int(t.index);
        bind_int(t.row);
        bind_int(t.col);
        bind_real(t.px.x);
        bind_real(t.px.y);
        bind_real(t.px.x + t.px.width);
        bind_real(t.px.y + t.px.height);
        bind_real(t.centre_crs.x());
        bind_real(t.centre_crs.y());
        for (const geo::LatLon& c : t.corners) {
          bind_real(c.lat_deg);
          bind_real(c.lon_deg);
        }
        bind_real(t.centre.lat_deg);
        bind_real(t.centre.lon_deg);
        bind_int(t.padded);
        bind_int(static_cast<int64_t>(t.keypoints.size()));
        kp.clear();
        for (size_t i = 0; i < t.keypoints.size(); ++i) {
          kp.insert(kp.end(),
                    {t.keypoints[i].x, t.keypoints[i].y, t.keypoint_size[i], t.keypoint_angle[i]});
        }
        const size_t kp_bytes = kp.size() * sizeof(float);
        sqlite3_bind_blob(ins.st, k++, kp.data(), static_cast<int>(kp_bytes), SQLITE_TRANSIENT);
        const cv::Mat d = t.descriptors.isContinuous() ? t.descriptors : t.descriptors.clone();
        const size_t d_bytes = d.total() * d.elemSize();
        sqlite3_bind_blob(ins.st, k++, d.data, static_cast<int>(d_bytes), SQLITE_TRANSIENT);
        sqlite3_bind_int64(ins.st, k++, CrcValue(geometry.Crc()));
        sqlite3_bind_int64(ins.st, k++, CrcValue(Crc32(kp.data(), kp_bytes)));
        sqlite3_bind_int64(ins.st, k++, CrcValue(Crc32(d.data, d_bytes)));
        db.Check(sqlite3_step(ins.st), "insert tile");
        sqlite3_reset(ins.st);
      };
      if (tiles) {
        tiles(write);
      } else {
        for (const MapTile& t : m.tiles) write(t);
      }
    }
    // Written last: a database without it is incomplete.
    db.Exec("INSERT INTO meta VALUES('complete', '1')");
    db.Exec("COMMIT");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out_path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw Error("cannot move the map database into place: " + ec.message(), {.file = out_path});
  }
}

}  // namespace

uint32_t Crc32(const void* data, size_t size, uint32_t crc) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ p[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

std::string MapBuildOptions::Check() const {
  if (!(altitude_m > 0 && altitude_m < 100000))
    return fmt::format("--altitude must be in (0, 100000) m, got {}", altitude_m);
  if (!(hfov_deg > 1 && hfov_deg < 179))
    return fmt::format("--hfov must be in (1, 179) deg, got {}", hfov_deg);
  if (frame_width < 16 || frame_height < 16) return "--frame-size must be at least 16x16";
  if (!(scale_factor > 0.05 && scale_factor <= 4))
    return fmt::format("--scale-factor must be in (0.05, 4], got {}", scale_factor);
  if (!(overlap >= 0 && overlap <= 0.9))
    return fmt::format("--overlap must be in [0, 0.9], got {}", overlap);
  if (max_features < 16 || max_features > 100000)
    return fmt::format("--max-features must be in [16, 100000], got {}", max_features);
  if (threads < 0) return "--threads must be >= 0";
  if (!(xfeat_scale >= 0 && xfeat_scale <= 8))
    return fmt::format("xfeat_scale must be in [0, 8], got {}", xfeat_scale);
  return "";
}

size_t MapDatabase::FeatureCount() const {
  size_t n = 0;
  for (const auto& t : tiles) n += t.keypoints.size();
  return n;
}

MapDatabase PlanMapDatabase(const std::string& ortho_path, const MapBuildOptions& o) {
  if (const std::string msg = o.Check(); !msg.empty()) throw Error(msg);
  const geo::GeoRaster raster = geo::GeoRaster::Open(ortho_path);
  const geo::CrsTransform crs(raster.crs_wkt());
  MapDatabase m;
  m.ortho_path = ortho_path;
  m.crs_wkt = raster.crs_wkt();
  m.crs_name = crs.name();
  m.transform = raster.transform();
  m.width = raster.width();
  m.height = raster.height();
  m.options = o;
  m.feature_type = o.feature_type;
  const Eigen::Vector2d centre_crs = m.transform.PixelToCrs({m.width / 2.0, m.height / 2.0});
  m.map_gsd_m = m.transform.UnitsPerPixel() * crs.MetresPerUnit(centre_crs);
  const double footprint_m = 2.0 * o.altitude_m * std::tan(o.hfov_deg * M_PI / 360.0);
  const double frame_gsd_m = footprint_m / o.frame_width;
  // Features are taken at the frame's ground resolution when the map is finer (never upsampled).
  m.feature_gsd_m = std::max(m.map_gsd_m, frame_gsd_m);
  m.tile_px = std::max(16.0, o.scale_factor * footprint_m / m.map_gsd_m);
  m.step_px = std::max(1.0, m.tile_px * (1.0 - o.overlap));
  auto count = [&](int size) {
    return size <= m.tile_px ? 1 : static_cast<int>(std::ceil((size - m.tile_px) / m.step_px)) + 1;
  };
  m.cols = count(m.width);
  m.rows = count(m.height);
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.cols; ++c) {
      MapTile t;
      t.index = static_cast<int>(m.tiles.size());
      t.row = r;
      t.col = c;
      t.px = cv::Rect2d(c * m.step_px, r * m.step_px, m.tile_px, m.tile_px);
      t.padded = t.px.x + t.px.width > m.width + 1e-6 || t.px.y + t.px.height > m.height + 1e-6;
      const Eigen::Vector2d corners_px[4] = {{t.px.x, t.px.y},
                                             {t.px.x + t.px.width, t.px.y},
                                             {t.px.x + t.px.width, t.px.y + t.px.height},
                                             {t.px.x, t.px.y + t.px.height}};
      for (int k = 0; k < 4; ++k)
        t.corners[k] = crs.ToLatLon(m.transform.PixelToCrs(corners_px[k]));
      t.centre_crs = m.transform.PixelToCrs({t.px.x + t.px.width / 2, t.px.y + t.px.height / 2});
      t.centre = crs.ToLatLon(t.centre_crs);
      m.tiles.push_back(std::move(t));
    }
  }
  return m;
}

std::string MapShard::ToString() const { return fmt::format("{}/{}", index, count); }

std::string MapShard::Check() const {
  if (count < 1 || index < 0 || index >= count)
    return fmt::format("shard {}/{} is not I/N with 0 <= I < N", index, count);
  return "";
}

MapShard ParseMapShard(const std::string& text, const std::string& flag) {
  MapShard s;
  const size_t slash = text.find('/');
  size_t used_i = 0, used_n = 0;
  try {
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    s.index = std::stoi(text.substr(0, slash), &used_i);
    s.count = std::stoi(text.substr(slash + 1), &used_n);
  } catch (const std::exception&) {
    used_i = std::string::npos;
  }
  if (used_i != slash || slash + 1 + used_n != text.size() || !s.Check().empty())
    throw Error("'" + text + "' is not I/N with 0 <= I < N (shard I of N, from 0)",
                {.field = flag});
  return s;
}

std::pair<int, int> ShardTileRange(int total, const MapShard& shard) {
  const auto at = [&](int i) { return static_cast<int>(int64_t{total} * i / shard.count); };
  return {at(shard.index), at(shard.index + 1)};
}

MapDatabase BuildMapDatabase(const std::string& ortho_path, const MapBuildOptions& o,
                             const std::string& out_path, const MapShard& shard) {
  if (const std::string msg = shard.Check(); !msg.empty()) throw Error(msg, {.field = "--shard"});
  MapDatabase m = PlanMapDatabase(ortho_path, o);
  // Plain variables, not a structured binding: the workers' lambda uses them (clang 14 cannot
  // capture structured bindings).
  const std::pair<int, int> tile_range = ShardTileRange(static_cast<int>(m.tiles.size()), shard);
  const int first_tile = tile_range.first;
  const int last_tile = tile_range.second;
  const double level_scale = m.map_gsd_m / m.feature_gsd_m;  // <= 1
  const int tile_img = std::max(16, static_cast<int>(std::lround(m.tile_px * level_scale)));
  const int n_threads =
      o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  if (o.feature_type == features::FeatureType::kXFeat) {
    // Checked here, so that a missing or wrong network is named as such (not as a tile's
    // failure); every worker then shares the one loaded net.
    features::CheckXFeatModel(o.model_path.empty() ? features::DefaultXFeatModelPath()
                                                   : o.model_path);
    if (m.options.xfeat_scale == 0) {
      m.options.xfeat_scale =
          std::min(kXFeatTileScale, static_cast<double>(features::kXFeatInputSize) / tile_img);
    }
  }
  spdlog::info(
      "map build: {} x {} px at {:.3f} m/px, {} x {} tiles of {:.0f} px ({:.0f} m), "
      "features at {:.3f} m/px on {} thread(s)",
      m.width, m.height, m.map_gsd_m, m.cols, m.rows, m.tile_px, m.tile_px * m.map_gsd_m,
      m.feature_gsd_m, n_threads);
  std::atomic<size_t> next{static_cast<size_t>(first_tile)};
  std::mutex error_mutex;
  std::string first_error;
  ProgressBar progress(last_tile - first_tile, "map build");
  auto worker = [&] {
    try {
      // GDAL datasets are not thread-safe: one handle per worker.
      const geo::GeoRaster raster = geo::GeoRaster::Open(ortho_path);
      const auto extractor =
          features::CreateFeatureExtractor({.type = o.feature_type,
                                            .max_features = o.max_features,
                                            .model_path = o.model_path,
                                            .xfeat_scale = m.options.xfeat_scale});
      for (size_t i = next++; i < static_cast<size_t>(last_tile); i = next++) {
        {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (!first_error.empty()) return;
        }
        MapTile& t = m.tiles[i];
        cv::Mat valid;
        const int x = static_cast<int>(std::floor(t.px.x)),
                  y = static_cast<int>(std::floor(t.px.y));
        const int side = static_cast<int>(std::ceil(t.px.width));
        const cv::Mat img = raster.ReadGray(x, y, side, side, tile_img, tile_img, &valid);
        // Keep detections away from no-data borders, where the edge itself looks like a corner.
        cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 8);
        const features::Features f = extractor->Extract(img, valid);
        const double to_map = static_cast<double>(side) / tile_img;
        t.keypoints.reserve(f.size());
        // Map pixels as GDAL has them (pixel i covers [i, i + 1)): the centre of tile-image
        // pixel k, where the detector's integer coordinate lies, is at (k + 0.5) x to_map.
        // (Databases built before 2026-11-25 hold the index, half a pixel off.)
        for (const auto& kp : f.keypoints) {
          t.keypoints.emplace_back(static_cast<float>(x + (kp.pt.x + 0.5) * to_map),
                                   static_cast<float>(y + (kp.pt.y + 0.5) * to_map));
          t.keypoint_size.push_back(static_cast<float>(kp.size * to_map));
          t.keypoint_angle.push_back(kp.angle);
        }
        t.descriptors = f.descriptors;
        progress.Advance();
      }
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (first_error.empty()) first_error = e.what();
    }
  };
  std::vector<std::thread> pool;
  for (int k = 0; k < n_threads; ++k) pool.emplace_back(worker);
  for (auto& th : pool) th.join();
  progress.Finish();
  if (!first_error.empty()) throw Error("map build failed: " + first_error, {.file = ortho_path});
  if (!shard.whole()) {
    m.tiles.erase(m.tiles.begin() + last_tile, m.tiles.end());
    m.tiles.erase(m.tiles.begin(), m.tiles.begin() + first_tile);
  }
  WriteDatabase(m, out_path, shard);
  return m;
}

namespace {

// Reads and verifies a database; a part of a sharded build only when `part` is given (its shard
// returned there), else refused.
MapDatabase ReadDatabase(const std::string& path, MapShard* part) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("map database not found", {.file = path});
  Db db(path, SQLITE_OPEN_READONLY);
  MapDatabase m;
  std::map<std::string, std::string> meta;
  {
    Stmt q{db.Prepare("SELECT key, value FROM meta")};
    int rc;
    while ((rc = sqlite3_step(q.st)) == SQLITE_ROW) {
      const auto* key = reinterpret_cast<const char*>(sqlite3_column_text(q.st, 0));
      const auto* value = reinterpret_cast<const char*>(sqlite3_column_text(q.st, 1));
      if (key == nullptr || value == nullptr) {
        throw Error(
            "map database metadata is damaged (a NULL key or value); rebuild it with "
            "`optinav map build`",
            {.file = path, .field = "meta"});
      }
      meta[key] = value;
    }
    if (rc != SQLITE_DONE) throw Error("not a valid optinav map database", {.file = path});
  }
  auto get = [&](const std::string& key) -> const std::string& {
    auto it = meta.find(key);
    if (it == meta.end()) throw Error("map database lacks metadata", {.file = path, .field = key});
    return it->second;
  };
  const std::string& version = get("format_version");
  if (version != std::to_string(kMapFormatVersion)) {
    throw Error(fmt::format("map database format version {} is not supported (this optinav "
                            "reads version {}); rebuild it with `optinav map build`",
                            version, kMapFormatVersion),
                {.file = path, .field = "format_version"});
  }
  if (meta.count("complete") == 0) {
    throw Error("map database is incomplete (interrupted build?)", {.file = path});
  }
  if (get("checksum") != std::to_string(MetaCrc(meta))) {
    throw Error(
        "map database metadata is damaged (checksum mismatch); rebuild it with "
        "`optinav map build`",
        {.file = path, .field = "meta"});
  }
  try {
    m.ortho_path = get("ortho_path");
    m.crs_wkt = get("crs_wkt");
    m.crs_name = get("crs_name");
    const auto gt = nlohmann::json::parse(get("geotransform"));
    for (int i = 0; i < 6; ++i) m.transform.c[i] = gt.at(i);
    m.width = std::stoi(get("width"));
    m.height = std::stoi(get("height"));
    m.map_gsd_m = std::stod(get("map_gsd_m"));
    m.feature_gsd_m = std::stod(get("feature_gsd_m"));
    m.tile_px = std::stod(get("tile_px"));
    m.step_px = std::stod(get("step_px"));
    m.rows = std::stoi(get("rows"));
    m.cols = std::stoi(get("cols"));
    m.options = OptionsFromJson(nlohmann::json::parse(get("build_options")));
    m.feature_type = m.options.feature_type;
    // The locator divides by these and turns positions into grid cells with them (fuzz).
    for (const double v : {m.map_gsd_m, m.feature_gsd_m, m.tile_px, m.step_px}) {
      if (!(v > 0) || !std::isfinite(v))
        throw std::invalid_argument(fmt::format("bad scale value {} (gsd, tile or step)", v));
    }
    if (m.rows <= 0 || m.cols <= 0 || int64_t{m.rows} * m.cols > 10'000'000)
      throw std::invalid_argument(fmt::format("bad tile grid {} x {}", m.cols, m.rows));
    if (meta.count("shard")) {
      const MapShard shard = ParseMapShard(meta.at("shard"), "shard");
      if (!part) {
        throw Error(fmt::format("is part {} of a sharded build, not a map; join the parts with "
                                "`optinav map merge`",
                                shard.ToString()),
                    {.file = path, .field = "shard"});
      }
      *part = shard;
    } else if (part) {
      *part = MapShard{};
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(std::string("corrupt map metadata: ") + e.what(), {.file = path});
  }
  const features::DescriptorFormat format = features::DescriptorFormatOf(m.feature_type);
  const int desc_type = format.type;
  const int desc_cols = format.size;
  const size_t desc_bytes = desc_cols * (desc_type == CV_8U ? 1 : 4);
  const auto [first_tile, last_tile] = ShardTileRange(m.rows * m.cols, part ? *part : MapShard{});
  Stmt q{db.Prepare(
      "SELECT id, row, col, px0, py0, px1, py1, crs_cx, crs_cy, lat_ul, lon_ul, lat_ur, lon_ur,"
      " lat_lr, lon_lr, lat_ll, lon_ll, lat_c, lon_c, padded, n_features, keypoints, descriptors,"
      " geometry_crc, keypoints_crc, descriptors_crc FROM tiles ORDER BY id")};
  int rc;
  while ((rc = sqlite3_step(q.st)) == SQLITE_ROW) {
    const int position = first_tile + static_cast<int>(m.tiles.size());
    MapTile t;
    int k = 0;
    GeometryBytes geometry;
    auto get_int = [&] {
      const int64_t v = sqlite3_column_int64(q.st, k++);
      geometry.Int(v);
      return v;
    };
    auto get_real = [&] {
      const double v = sqlite3_column_double(q.st, k++);
      geometry.Real(v);
      return v;
    };
    const int64_t id = get_int(), row = get_int(), col = get_int();
    const double px0 = get_real(), py0 = get_real();
    const double px1 = get_real(), py1 = get_real();
    t.px = cv::Rect2d(px0, py0, px1 - px0, py1 - py0);
    t.centre_crs.x() = get_real();
    t.centre_crs.y() = get_real();
    for (auto& c : t.corners) {
      c.lat_deg = get_real();
      c.lon_deg = get_real();
    }
    t.centre.lat_deg = get_real();
    t.centre.lon_deg = get_real();
    t.padded = get_int() != 0;
    const int64_t n = get_int();
    const void* kp = sqlite3_column_blob(q.st, k);
    const size_t kp_bytes = static_cast<size_t>(sqlite3_column_bytes(q.st, k++));
    const void* desc = sqlite3_column_blob(q.st, k);
    const size_t d_bytes = static_cast<size_t>(sqlite3_column_bytes(q.st, k++));
    // Name the tile by its place in the file when its own id may be what is damaged.
    const std::string name = id == position ? fmt::format("tile {}", position)
                                            : fmt::format("tile {} (stored id {})", position, id);
    auto damaged = [&](const std::string& what, const char* field) {
      return Error(
          fmt::format("{} is damaged ({}); rebuild the map with `optinav map build`", name, what),
          {.file = path, .field = field});
    };
    const struct {
      uint32_t actual;
      const char* field;
    } sums[3] = {{geometry.Crc(), "geometry"},
                 {Crc32(kp, kp_bytes), "keypoints"},
                 {Crc32(desc, d_bytes), "descriptors"}};
    for (const auto& sum : sums) {
      if (sqlite3_column_type(q.st, k) != SQLITE_INTEGER ||
          sqlite3_column_int64(q.st, k) != CrcValue(sum.actual)) {
        throw damaged(std::string(sum.field) + " checksum mismatch", sum.field);
      }
      ++k;
    }
    if (id != position || row != position / m.cols || col != position % m.cols) {
      throw damaged(fmt::format("row {}, col {} out of place", row, col), "geometry");
    }
    if (n < 0 || kp_bytes != static_cast<size_t>(n) * 4 * sizeof(float) ||
        d_bytes != static_cast<size_t>(n) * desc_bytes) {
      throw Error(fmt::format("tile {} has inconsistent feature data", position),
                  {.file = path, .field = "n_features"});
    }
    t.index = position;
    t.row = static_cast<int>(row);
    t.col = static_cast<int>(col);
    std::vector<float> f(static_cast<size_t>(n) * 4);
    if (kp_bytes > 0) std::memcpy(f.data(), kp, kp_bytes);  // blobs need not be float-aligned
    for (int64_t i = 0; i < n; ++i) {
      // A keypoint must be finite: the locator turns positions into grid cells (an infinite one
      // is undefined behaviour there; found by fuzz/map_db_rows with the checksums recomputed).
      if (!std::isfinite(f[4 * i]) || !std::isfinite(f[4 * i + 1]) ||
          !std::isfinite(f[4 * i + 2]) || !std::isfinite(f[4 * i + 3])) {
        throw Error(fmt::format("tile {} has a non-finite keypoint ({})", position, i),
                    {.file = path, .field = "keypoints"});
      }
      t.keypoints.emplace_back(f[4 * i], f[4 * i + 1]);
      t.keypoint_size.push_back(f[4 * i + 2]);
      t.keypoint_angle.push_back(f[4 * i + 3]);
    }
    if (n > 0) {
      t.descriptors.create(static_cast<int>(n), desc_cols, desc_type);
      std::memcpy(t.descriptors.data, desc, d_bytes);
    }
    m.tiles.push_back(std::move(t));
    if (static_cast<int64_t>(m.tiles.size()) > last_tile - first_tile) break;
  }
  db.Check(rc, "read tiles");
  if (static_cast<int>(m.tiles.size()) != last_tile - first_tile) {
    throw Error(part && !part->whole()
                    ? fmt::format("part {} has {} tiles, expected {} ({} - {})", part->ToString(),
                                  m.tiles.size(), last_tile - first_tile, first_tile, last_tile - 1)
                    : fmt::format("map database has {} tiles, expected {} x {}", m.tiles.size(),
                                  m.cols, m.rows),
                {.file = path});
  }
  return m;
}

}  // namespace

MapDatabase LoadMapDatabase(const std::string& path) { return ReadDatabase(path, nullptr); }

MapMergeSummary MergeMapParts(const std::vector<std::string>& parts, const std::string& out_path) {
  if (parts.empty()) throw Error("no parts to merge", {.field = "PARTS"});
  // Pass 1: every part verified (checksums), its metadata kept; the tiles are read again in pass
  // 2, one part at a time, so the merge holds one part in memory, not the map.
  std::vector<std::pair<MapShard, MapDatabase>> read;
  for (const std::string& path : parts) {
    MapShard shard;
    MapDatabase m = ReadDatabase(path, &shard);
    m.tiles.clear();
    m.tiles.shrink_to_fit();
    read.emplace_back(shard, std::move(m));
  }
  const int count = read[0].first.count;
  std::vector<int> by_index(count, -1);  // shard -> position in parts
  const MapDatabase& ref = read[0].second;
  const std::string ref_options = OptionsToJson(ref.options).dump();
  for (size_t k = 0; k < read.size(); ++k) {
    const auto& [shard, m] = read[k];
    if (shard.count != count) {
      throw Error(fmt::format("is shard {} of another split than {} (shard {})", shard.ToString(),
                              parts[0], read[0].first.ToString()),
                  {.file = parts[k], .field = "shard"});
    }
    // Parts of one build: the same raster, grid and options (the orthophoto's path may differ, a
    // mosaic written beside each part; the first part's is kept).
    const char* differs = m.crs_wkt != ref.crs_wkt                               ? "crs_wkt"
                          : m.transform.c != ref.transform.c                     ? "geotransform"
                          : m.width != ref.width || m.height != ref.height       ? "width"
                          : m.rows != ref.rows || m.cols != ref.cols             ? "rows"
                          : m.tile_px != ref.tile_px || m.step_px != ref.step_px ? "tile_px"
                          : m.map_gsd_m != ref.map_gsd_m || m.feature_gsd_m != ref.feature_gsd_m
                              ? "map_gsd_m"
                          : OptionsToJson(m.options).dump() != ref_options ? "build_options"
                                                                           : nullptr;
    if (differs) {
      throw Error("is a part of another build than " + parts[0] + " (" + differs + " differs)",
                  {.file = parts[k], .field = differs});
    }
    if (m.ortho_path != ref.ortho_path)
      spdlog::warn("map merge: {} was built from {}, {} from {}; the merged map names the first",
                   parts[0], ref.ortho_path, parts[k], m.ortho_path);
    if (by_index[shard.index] >= 0) {
      throw Error(fmt::format("shard {} is given twice (also {})", shard.ToString(),
                              parts[by_index[shard.index]]),
                  {.file = parts[k], .field = "shard"});
    }
    by_index[shard.index] = static_cast<int>(k);
  }
  std::string missing;
  for (int i = 0; i < count; ++i)
    if (by_index[i] < 0) missing += (missing.empty() ? "" : ", ") + fmt::format("{}/{}", i, count);
  if (!missing.empty())
    throw Error("shards missing: " + missing + " (every shard of the build is needed)",
                {.field = "PARTS"});
  MapMergeSummary summary;
  summary.db = ref;
  WriteDatabase(ref, out_path, MapShard{}, [&](const std::function<void(const MapTile&)>& emit) {
    for (int i = 0; i < count; ++i) {
      MapShard shard;
      const MapDatabase part = ReadDatabase(parts[by_index[i]], &shard);
      if (shard.index != i)  // changed since pass 1
        throw Error("changed while merging", {.file = parts[by_index[i]]});
      for (const MapTile& t : part.tiles) {
        emit(t);
        ++summary.tiles;
        summary.features += t.keypoints.size();
      }
    }
  });
  return summary;
}

MapCheckReport CheckMapDatabase(const std::string& path) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("map database not found", {.file = path});
  {
    Db db(path, SQLITE_OPEN_READONLY);
    Stmt q{db.Prepare("PRAGMA integrity_check")};
    std::string problems;
    int rc, n_problems = 0;
    while ((rc = sqlite3_step(q.st)) == SQLITE_ROW) {
      const auto* line = reinterpret_cast<const char*>(sqlite3_column_text(q.st, 0));
      const std::string s = line ? line : "?";
      if (s == "ok") continue;
      if (++n_problems <= 3) problems += (problems.empty() ? "" : "; ") + s;
    }
    if (n_problems > 3) problems += fmt::format("; {} more", n_problems - 3);
    db.Check(rc, "integrity check");
    if (!problems.empty()) {
      throw Error("map database is damaged (SQLite integrity check: " + problems +
                      "); rebuild it with `optinav map build`",
                  {.file = path});
    }
  }
  MapCheckReport r;
  r.db = LoadMapDatabase(path);
  r.tiles = r.db.tiles.size();
  for (const MapTile& t : r.db.tiles) {
    r.features += t.keypoints.size();
    r.checked_bytes +=
        t.keypoints.size() * 4 * sizeof(float) + t.descriptors.total() * t.descriptors.elemSize();
  }
  return r;
}

}  // namespace optinav::maploc
