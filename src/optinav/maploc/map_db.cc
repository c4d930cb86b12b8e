#include "optinav/maploc/map_db.h"

#include <atomic>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>
#include <sqlite3.h>

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

nlohmann::json OptionsToJson(const MapBuildOptions& o) {
  return {{"altitude_m", o.altitude_m},
          {"hfov_deg", o.hfov_deg},
          {"frame_width", o.frame_width},
          {"frame_height", o.frame_height},
          {"scale_factor", o.scale_factor},
          {"overlap", o.overlap},
          {"features", features::FeatureTypeName(o.feature_type)},
          {"max_features", o.max_features}};
}

MapBuildOptions OptionsFromJson(const nlohmann::json& j) {
  MapBuildOptions o;
  o.altitude_m = j.at("altitude_m");
  o.hfov_deg = j.at("hfov_deg");
  o.frame_width = j.at("frame_width");
  o.frame_height = j.at("frame_height");
  o.scale_factor = j.at("scale_factor");
  o.overlap = j.at("overlap");
  o.feature_type = *features::ParseFeatureType(j.at("features").get<std::string>());
  o.max_features = j.at("max_features");
  return o;
}

void WriteDatabase(const MapDatabase& m, const std::string& out_path) {
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
        " n_features INTEGER, keypoints BLOB, descriptors BLOB);");
    db.Exec("BEGIN");
    {
      Stmt ins{db.Prepare("INSERT INTO meta VALUES(?, ?)")};
      nlohmann::json gt = m.transform.c;
      const std::vector<std::pair<std::string, std::string>> meta = {
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
      };
      for (const auto& [k, v] : meta) {
        sqlite3_bind_text(ins.st, 1, k.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(ins.st, 2, v.c_str(), -1, SQLITE_TRANSIENT);
        db.Check(sqlite3_step(ins.st), "insert meta");
        sqlite3_reset(ins.st);
      }
    }
    {
      Stmt ins{
          db.Prepare("INSERT INTO tiles VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)")};
      std::vector<float> kp;
      for (const MapTile& t : m.tiles) {
        int k = 1;
        sqlite3_bind_int(ins.st, k++, t.index);
        sqlite3_bind_int(ins.st, k++, t.row);
        sqlite3_bind_int(ins.st, k++, t.col);
        sqlite3_bind_double(ins.st, k++, t.px.x);
        sqlite3_bind_double(ins.st, k++, t.px.y);
        sqlite3_bind_double(ins.st, k++, t.px.x + t.px.width);
        sqlite3_bind_double(ins.st, k++, t.px.y + t.px.height);
        sqlite3_bind_double(ins.st, k++, t.centre_crs.x());
        sqlite3_bind_double(ins.st, k++, t.centre_crs.y());
        for (const geo::LatLon& c : t.corners) {
          sqlite3_bind_double(ins.st, k++, c.lat_deg);
          sqlite3_bind_double(ins.st, k++, c.lon_deg);
        }
        sqlite3_bind_double(ins.st, k++, t.centre.lat_deg);
        sqlite3_bind_double(ins.st, k++, t.centre.lon_deg);
        sqlite3_bind_int(ins.st, k++, t.padded);
        sqlite3_bind_int(ins.st, k++, static_cast<int>(t.keypoints.size()));
        kp.clear();
        for (size_t i = 0; i < t.keypoints.size(); ++i) {
          kp.insert(kp.end(),
                    {t.keypoints[i].x, t.keypoints[i].y, t.keypoint_size[i], t.keypoint_angle[i]});
        }
        sqlite3_bind_blob(ins.st, k++, kp.data(), static_cast<int>(kp.size() * sizeof(float)),
                          SQLITE_TRANSIENT);
        const cv::Mat d = t.descriptors.isContinuous() ? t.descriptors : t.descriptors.clone();
        sqlite3_bind_blob(ins.st, k++, d.data, static_cast<int>(d.total() * d.elemSize()),
                          SQLITE_TRANSIENT);
        db.Check(sqlite3_step(ins.st), "insert tile");
        sqlite3_reset(ins.st);
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

MapDatabase BuildMapDatabase(const std::string& ortho_path, const MapBuildOptions& o,
                             const std::string& out_path) {
  MapDatabase m = PlanMapDatabase(ortho_path, o);
  const double level_scale = m.map_gsd_m / m.feature_gsd_m;  // <= 1
  const int tile_img = std::max(16, static_cast<int>(std::lround(m.tile_px * level_scale)));
  const int n_threads =
      o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  spdlog::info(
      "map build: {} x {} px at {:.3f} m/px, {} x {} tiles of {:.0f} px ({:.0f} m), "
      "features at {:.3f} m/px on {} thread(s)",
      m.width, m.height, m.map_gsd_m, m.cols, m.rows, m.tile_px, m.tile_px * m.map_gsd_m,
      m.feature_gsd_m, n_threads);
  std::atomic<size_t> next{0};
  std::mutex error_mutex;
  std::string first_error;
  ProgressBar progress(m.tiles.size(), "map build");
  auto worker = [&] {
    try {
      // GDAL datasets are not thread-safe: one handle per worker.
      const geo::GeoRaster raster = geo::GeoRaster::Open(ortho_path);
      const auto extractor = features::CreateFeatureExtractor(
          {.type = o.feature_type, .max_features = o.max_features});
      for (size_t i = next++; i < m.tiles.size(); i = next++) {
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
        for (const auto& kp : f.keypoints) {
          t.keypoints.emplace_back(static_cast<float>(x + kp.pt.x * to_map),
                                   static_cast<float>(y + kp.pt.y * to_map));
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
  WriteDatabase(m, out_path);
  return m;
}

MapDatabase LoadMapDatabase(const std::string& path) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("map database not found", {.file = path});
  Db db(path, SQLITE_OPEN_READONLY);
  MapDatabase m;
  std::map<std::string, std::string> meta;
  {
    Stmt q{db.Prepare("SELECT key, value FROM meta")};
    int rc;
    while ((rc = sqlite3_step(q.st)) == SQLITE_ROW) {
      meta[reinterpret_cast<const char*>(sqlite3_column_text(q.st, 0))] =
          reinterpret_cast<const char*>(sqlite3_column_text(q.st, 1));
    }
    if (rc != SQLITE_DONE) throw Error("not a valid optinav map database", {.file = path});
  }
  auto get = [&](const std::string& key) -> const std::string& {
    auto it = meta.find(key);
    if (it == meta.end()) throw Error("map database lacks metadata", {.file = path, .field = key});
    return it->second;
  };
  const int version = std::stoi(get("format_version"));
  if (version != kMapFormatVersion) {
    throw Error(fmt::format("map database format version {} is not supported (this optinav "
                            "reads version {}); rebuild it with `optinav map build`",
                            version, kMapFormatVersion),
                {.file = path, .field = "format_version"});
  }
  if (meta.count("complete") == 0) {
    throw Error("map database is incomplete (interrupted build?)", {.file = path});
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
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(std::string("corrupt map metadata: ") + e.what(), {.file = path});
  }
  const auto extractor = features::CreateFeatureExtractor({.type = m.feature_type});
  const int desc_type = extractor->descriptor_type();
  const int desc_cols = extractor->descriptor_size();
  const size_t desc_bytes = desc_cols * (desc_type == CV_8U ? 1 : 4);
  Stmt q{db.Prepare(
      "SELECT id, row, col, px0, py0, px1, py1, crs_cx, crs_cy, lat_ul, lon_ul, lat_ur, lon_ur,"
      " lat_lr, lon_lr, lat_ll, lon_ll, lat_c, lon_c, padded, n_features, keypoints, descriptors"
      " FROM tiles ORDER BY id")};
  int rc;
  while ((rc = sqlite3_step(q.st)) == SQLITE_ROW) {
    MapTile t;
    int k = 0;
    t.index = sqlite3_column_int(q.st, k++);
    t.row = sqlite3_column_int(q.st, k++);
    t.col = sqlite3_column_int(q.st, k++);
    const double px0 = sqlite3_column_double(q.st, k++), py0 = sqlite3_column_double(q.st, k++);
    const double px1 = sqlite3_column_double(q.st, k++), py1 = sqlite3_column_double(q.st, k++);
    t.px = cv::Rect2d(px0, py0, px1 - px0, py1 - py0);
    t.centre_crs.x() = sqlite3_column_double(q.st, k++);
    t.centre_crs.y() = sqlite3_column_double(q.st, k++);
    for (auto& c : t.corners) {
      c.lat_deg = sqlite3_column_double(q.st, k++);
      c.lon_deg = sqlite3_column_double(q.st, k++);
    }
    t.centre.lat_deg = sqlite3_column_double(q.st, k++);
    t.centre.lon_deg = sqlite3_column_double(q.st, k++);
    t.padded = sqlite3_column_int(q.st, k++) != 0;
    const int n = sqlite3_column_int(q.st, k++);
    const void* kp = sqlite3_column_blob(q.st, k);
    const size_t kp_bytes = static_cast<size_t>(sqlite3_column_bytes(q.st, k++));
    const void* desc = sqlite3_column_blob(q.st, k);
    const size_t d_bytes = static_cast<size_t>(sqlite3_column_bytes(q.st, k++));
    if (n < 0 || kp_bytes != n * 4 * sizeof(float) || d_bytes != n * desc_bytes) {
      throw Error(fmt::format("tile {} has inconsistent feature data", t.index), {.file = path});
    }
    const float* f = static_cast<const float*>(kp);
    for (int i = 0; i < n; ++i) {
      t.keypoints.emplace_back(f[4 * i], f[4 * i + 1]);
      t.keypoint_size.push_back(f[4 * i + 2]);
      t.keypoint_angle.push_back(f[4 * i + 3]);
    }
    if (n > 0) t.descriptors = cv::Mat(n, desc_cols, desc_type, const_cast<void*>(desc)).clone();
    m.tiles.push_back(std::move(t));
  }
  db.Check(rc, "read tiles");
  if (static_cast<int>(m.tiles.size()) != m.rows * m.cols) {
    throw Error(
        fmt::format("map database has {} tiles, expected {} x {}", m.tiles.size(), m.cols, m.rows),
        {.file = path});
  }
  return m;
}

}  // namespace optinav::maploc
