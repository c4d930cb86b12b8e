// Map databases with mutated rows and blobs whose checksums are made to match again: what the
// loader and the locator do with well-formed SQLite holding bad content (the checksums only
// catch accidental damage; a map written by a buggy or foreign tool passes them).
//
// Input: byte 0 = flags (bit 0: leave the checksums stale, bit 1: locate a frame with the loaded
// map), then edit records [op, tile, column, length, payload...] applied to a copy of a small map
// (fuzz_map.h): op % 8 = 0 blob, 1 int64, 2 double, 3 text, 4 NULL into tiles.<column>,
// 5 delete the tile, 6 set a metadata value (tile picks the key), 7 delete a metadata key.
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <sqlite3.h>

#include "fuzz/fuzz_map.h"
#include "fuzz/fuzz_target.h"
#include "optinav/maploc/locator.h"
#include "optinav/maploc/map_db.h"

using namespace optinav;

namespace {

const char* const kTileColumns[] = {
    "id",     "row",    "col",    "px0",    "py0",        "px1",       "py1",        "crs_cx",
    "crs_cy", "lat_ul", "lon_ul", "lat_ur", "lon_ur",     "lat_lr",    "lon_lr",     "lat_ll",
    "lon_ll", "lat_c",  "lon_c",  "padded", "n_features", "keypoints", "descriptors"};
const char* const kMetaKeys[] = {"format_version", "ortho_path",    "crs_wkt", "crs_name",
                                 "geotransform",   "width",         "height",  "map_gsd_m",
                                 "feature_gsd_m",  "tile_px",       "step_px", "rows",
                                 "cols",           "build_options", "complete"};

void Exec(sqlite3* db, const std::string& sql) {
  sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr);
}

// The checksums as map_db.cc computes them (docs/MAPDB.md, Integrity).
void FixChecksums(sqlite3* db) {
  sqlite3_stmt* q = nullptr;
  sqlite3_prepare_v2(db,
                     "SELECT id, row, col, px0, py0, px1, py1, crs_cx, crs_cy, lat_ul, lon_ul,"
                     " lat_ur, lon_ur, lat_lr, lon_lr, lat_ll, lon_ll, lat_c, lon_c, padded,"
                     " n_features, keypoints, descriptors, rowid FROM tiles",
                     -1, &q, nullptr);
  std::vector<std::array<int64_t, 4>> sums;  // rowid, geometry, keypoints, descriptors
  while (q && sqlite3_step(q) == SQLITE_ROW) {
    std::string g;
    for (int k = 0; k < 21; ++k) {
      if (k < 3 || k >= 19) {
        const int64_t v = sqlite3_column_int64(q, k);
        g.append(reinterpret_cast<const char*>(&v), sizeof v);
      } else {
        double v = sqlite3_column_double(q, k);
        if (std::isnan(v)) v = 0;
        g.append(reinterpret_cast<const char*>(&v), sizeof v);
      }
    }
    const void* kp = sqlite3_column_blob(q, 21);
    const size_t kp_n = static_cast<size_t>(sqlite3_column_bytes(q, 21));
    const void* d = sqlite3_column_blob(q, 22);
    const size_t d_n = static_cast<size_t>(sqlite3_column_bytes(q, 22));
    sums.push_back({sqlite3_column_int64(q, 23), maploc::Crc32(g.data(), g.size()),
                    maploc::Crc32(kp, kp_n), maploc::Crc32(d, d_n)});
  }
  sqlite3_finalize(q);
  for (const auto& s : sums) {
    Exec(db, "UPDATE tiles SET geometry_crc = " + std::to_string(s[1]) + ", keypoints_crc = " +
                 std::to_string(s[2]) + ", descriptors_crc = " + std::to_string(s[3]) +
                 " WHERE rowid = " + std::to_string(s[0]));
  }
  std::map<std::string, std::string> meta;
  sqlite3_prepare_v2(db, "SELECT key, value FROM meta", -1, &q, nullptr);
  while (q && sqlite3_step(q) == SQLITE_ROW) {
    const auto* k = reinterpret_cast<const char*>(sqlite3_column_text(q, 0));
    const auto* v = reinterpret_cast<const char*>(sqlite3_column_text(q, 1));
    if (k && v) meta[k] = v;
  }
  sqlite3_finalize(q);
  uint32_t crc = 0;
  for (const auto& [k, v] : meta) {
    if (k == "checksum") continue;
    crc = maploc::Crc32(k.c_str(), k.size() + 1, crc);
    crc = maploc::Crc32(v.c_str(), v.size() + 1, crc);
  }
  Exec(db, "UPDATE meta SET value = '" + std::to_string(crc) + "' WHERE key = 'checksum'");
}

struct Seed {
  std::string db_bytes;
  cv::Mat frame;  // a crop of the orthophoto
};

const Seed& GetSeed() {
  static const Seed seed = [] {
    Seed s;
    const std::string db = fuzz::BuildSmallMap(fuzz::ScratchDir() + "/seed_map");
    std::ifstream in(db, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    s.db_bytes = ss.str();
    const cv::Mat ortho =
        cv::imread(fuzz::ScratchDir() + "/seed_map/fuzz_ortho.tif", cv::IMREAD_GRAYSCALE);
    s.frame = ortho(cv::Rect(60, 70, 160, 120)).clone();
    return s;
  }();
  return seed;
}

}  // namespace

OPTINAV_FUZZ_TARGET(map_db_rows) {
  fuzz::QuietLibraries();
  const Seed& seed = GetSeed();
  const std::string path = fuzz::WriteScratch("map_rows.db", seed.db_bytes);
  const uint8_t flags = size > 0 ? data[0] : 0;
  {
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
      sqlite3_close(db);
      return 0;
    }
    Exec(db, "PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF; BEGIN");
    size_t i = 1;
    while (i + 4 <= size) {
      const uint8_t op = data[i] % 8, tile = data[i + 1] % 20;
      const char* column = kTileColumns[data[i + 2] % std::size(kTileColumns)];
      const size_t len = std::min<size_t>(data[i + 3], size - i - 4);
      const uint8_t* payload = data + i + 4;
      i += 4 + len;
      sqlite3_stmt* st = nullptr;
      const std::string where =
          " WHERE rowid = (SELECT rowid FROM tiles ORDER BY rowid LIMIT 1 OFFSET " +
          std::to_string(tile) + ")";
      if (op <= 4) {
        sqlite3_prepare_v2(db, (std::string("UPDATE tiles SET ") + column + " = ?" + where).c_str(),
                           -1, &st, nullptr);
        if (st) {
          if (op == 0) sqlite3_bind_blob(st, 1, payload, static_cast<int>(len), SQLITE_TRANSIENT);
          if (op == 1 || op == 2) {
            uint8_t b[8] = {};
            std::memcpy(b, payload, std::min<size_t>(len, 8));
            int64_t iv;
            double dv;
            std::memcpy(&iv, b, 8);
            std::memcpy(&dv, b, 8);
            if (op == 1) sqlite3_bind_int64(st, 1, iv);
            if (op == 2) sqlite3_bind_double(st, 1, dv);
          }
          if (op == 3)
            sqlite3_bind_text(st, 1, reinterpret_cast<const char*>(payload), static_cast<int>(len),
                              SQLITE_TRANSIENT);
          if (op == 4) sqlite3_bind_null(st, 1);
        }
      } else if (op == 5) {
        sqlite3_prepare_v2(db, ("DELETE FROM tiles" + where).c_str(), -1, &st, nullptr);
      } else {
        const char* key = kMetaKeys[tile % std::size(kMetaKeys)];
        sqlite3_prepare_v2(db,
                           op == 6 ? "INSERT OR REPLACE INTO meta(key, value) VALUES(?, ?)"
                                   : "DELETE FROM meta WHERE key = ?",
                           -1, &st, nullptr);
        if (st) {
          sqlite3_bind_text(st, 1, key, -1, SQLITE_STATIC);
          if (op == 6)
            sqlite3_bind_text(st, 2, reinterpret_cast<const char*>(payload), static_cast<int>(len),
                              SQLITE_TRANSIENT);
        }
      }
      if (st) sqlite3_step(st);
      sqlite3_finalize(st);
    }
    if (!(flags & 1)) FixChecksums(db);
    Exec(db, "COMMIT");
    sqlite3_close(db);
  }
  try {
    const maploc::MapDatabase m = maploc::LoadMapDatabase(path);
    (void)m.FeatureCount();
    if (flags & 2) {  // a locator over the map (costly: only on request)
      maploc::Locator locator(m);
      // Features only, near the frame's true place: the tiles' keypoints and descriptors are
      // matched (orientation correlation reads the orthophoto, not the database).
      maploc::Prior prior;
      prior.position = locator.PixelToLatLon({140.0, 130.0});
      prior.radius_m = 60;
      const maploc::LocateResult r = locator.LocateByFeatures(seed.frame, prior);
      (void)r;
    }
  } catch (const Error&) {
  }
  return 0;
}
