#include "optinav/maploc/map_db.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "optinav/maploc/test_maps.h"
#include "optinav/util/testing.h"

namespace optinav::maploc {
namespace {

MapBuildOptions Aero1Options() {
  MapBuildOptions o;
  o.frame_width = 240;
  o.frame_height = 180;
  o.hfov_deg = 60;
  o.altitude_m = 60.0 / (2 * std::tan(30 * M_PI / 180));  // 60 m footprint = 240 px
  o.overlap = 0.5;
  return o;
}

TEST(MapDatabase, TileGridFromCameraFootprint) {
  const auto dir = testing::MakeTempDir("mapplan");
  const std::string tif = testmaps::Aero1GeoTiff(dir);
  const MapDatabase plan = PlanMapDatabase(tif, Aero1Options());
  EXPECT_NEAR(plan.map_gsd_m, 0.25, 1e-12);
  EXPECT_NEAR(plan.tile_px, 240.0, 1e-9);  // 60 m / 0.25 m
  EXPECT_NEAR(plan.step_px, 120.0, 1e-9);
  EXPECT_EQ(plan.cols, 5);  // ceil((640 - 240) / 120) + 1
  EXPECT_EQ(plan.rows, 3);  // ceil((480 - 240) / 120) + 1
  EXPECT_FALSE(plan.tiles[0].padded);
  EXPECT_TRUE(plan.tiles[4].padded);  // 4 * 120 + 240 = 720 > 640
  // Corners through the geotransform and PROJ: tile 0 UL is the map origin.
  const geo::CrsTransform crs("EPSG:32633");
  const geo::LatLon ul = crs.ToLatLon({500000.0, 5560000.0});
  EXPECT_NEAR(plan.tiles[0].corners[0].lat_deg, ul.lat_deg, 1e-12);
  EXPECT_NEAR(plan.tiles[0].centre_crs.x(), 500000.0 + 120 * 0.25, 1e-9);
  MapBuildOptions bad = Aero1Options();
  bad.overlap = 0.95;
  // Options come from flags: the message names the flag (no file or line to give).
  EXPECT_ERROR(PlanMapDatabase(tif, bad), {}, "--overlap must be in [0, 0.9], got 0.95");
}

TEST(MapDatabase, BuildSaveLoadRoundTrip) {
  const auto dir = testing::MakeTempDir("mapdb");
  const std::string tif = testmaps::Aero1GeoTiff(dir);
  const std::string db_path = (dir / "aero1.db").string();
  const MapDatabase built = BuildMapDatabase(tif, Aero1Options(), db_path);
  EXPECT_FALSE(std::filesystem::exists(db_path + ".tmp"));
  EXPECT_GT(built.FeatureCount(), 2000u);
  const MapDatabase loaded = LoadMapDatabase(db_path);
  ASSERT_EQ(loaded.tiles.size(), built.tiles.size());
  EXPECT_EQ(loaded.crs_name, "WGS 84 / UTM zone 33N");
  EXPECT_EQ(loaded.transform.c, built.transform.c);
  EXPECT_EQ(loaded.options.max_features, 1024);
  for (size_t i = 0; i < built.tiles.size(); ++i) {
    const MapTile &a = built.tiles[i], &b = loaded.tiles[i];
    ASSERT_EQ(a.keypoints.size(), b.keypoints.size());
    EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_INF), 0.0);
    if (!a.keypoints.empty()) {
      EXPECT_EQ(a.keypoints.back(), b.keypoints.back());
    }
    EXPECT_EQ(a.padded, b.padded);
    // Keypoints lie inside their tile, in map pixels.
    for (const auto& kp : b.keypoints) {
      EXPECT_TRUE(kp.x >= b.px.x - 1 && kp.x <= b.px.x + b.px.width + 1);
      EXPECT_LT(kp.x, 640.0f);  // never in the padding beyond the raster
    }
  }
}

void ExecSql(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

TEST(MapDatabase, BadDatabasesAndOrthophotos) {
  const auto dir = testing::MakeTempDir("mapbad");
  const std::string tif = testmaps::Aero1GeoTiff(dir);
  const std::string good = (dir / "good.db").string();
  BuildMapDatabase(tif, Aero1Options(), good);
  auto copy = [&](const std::string& name) {
    const std::string p = (dir / name).string();
    std::filesystem::copy_file(good, p);
    return p;
  };
  const std::string other_version = copy("v99.db");
  ExecSql(other_version, "UPDATE meta SET value='99' WHERE key='format_version'");
  try {
    LoadMapDatabase(other_version);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("version 99"), std::string::npos) << e.what();
  }
  const std::string incomplete = copy("incomplete.db");
  ExecSql(incomplete, "DELETE FROM meta WHERE key='complete'");
  EXPECT_ERROR(LoadMapDatabase(incomplete), {.file = incomplete},
               "map database is incomplete (interrupted build?)");
  const std::string broken = copy("broken.db");
  ExecSql(broken, "UPDATE tiles SET descriptors=x'00' WHERE id=1");
  EXPECT_ERROR(LoadMapDatabase(broken), {.file = broken, .field = "descriptors"},
               "tile 1 is damaged (descriptors checksum mismatch)");
  const std::string text = testing::WriteFile(dir / "text.db", "not sqlite");
  EXPECT_ERROR(LoadMapDatabase(text), {.file = text}, "not a valid optinav map database");
  EXPECT_ERROR(LoadMapDatabase((dir / "none.db").string()), {.file = (dir / "none.db").string()},
               "map database not found");

  // A failed build leaves an existing database untouched and no temporary file.
  const std::string plain = (dir / "plain.tif").string();
  cv::imwrite(plain, cv::Mat(64, 64, CV_8UC1, cv::Scalar(1)));
  const auto before = std::filesystem::file_size(good);
  EXPECT_ERROR(BuildMapDatabase(plain, Aero1Options(), good), {.file = plain},
               "raster has no georeference");
  EXPECT_EQ(std::filesystem::file_size(good), before);
  EXPECT_FALSE(std::filesystem::exists(good + ".tmp"));
  EXPECT_NO_THROW(LoadMapDatabase(good));
}

TEST(MapDatabase, Crc32KnownValues) {
  EXPECT_EQ(Crc32("", 0), 0u);
  EXPECT_EQ(Crc32("123456789", 9), 0xCBF43926u);  // the CRC-32/IEEE check value
  // Continuing a checksum equals one pass over the concatenation.
  EXPECT_EQ(Crc32("6789", 4, Crc32("12345", 5)), 0xCBF43926u);
}

// Small map (few features per tile) for the integrity tests: fast to build, load and mutate.
std::string SmallMap(const std::filesystem::path& dir) {
  MapBuildOptions o = Aero1Options();
  o.max_features = 64;
  const std::string path = (dir / "small.db").string();
  BuildMapDatabase(testmaps::Aero1GeoTiff(dir), o, path);
  return path;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Changes one byte of a blob in place through SQLite's incremental blob I/O (the row and its
// length stay as they are; only the checksum can tell).
void FlipBlobByte(const std::string& path, const char* column, int64_t row, int offset) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_blob* blob = nullptr;
  ASSERT_EQ(sqlite3_blob_open(db, "main", "tiles", column, row, 1, &blob), SQLITE_OK);
  ASSERT_GT(sqlite3_blob_bytes(blob), offset);
  unsigned char b = 0;
  ASSERT_EQ(sqlite3_blob_read(blob, &b, 1, offset), SQLITE_OK);
  b ^= 0x10;
  ASSERT_EQ(sqlite3_blob_write(blob, &b, 1, offset), SQLITE_OK);
  sqlite3_blob_close(blob);
  sqlite3_close(db);
}

TEST(MapDatabase, DamagedTilesAndMetadataAreRefused) {
  const auto dir = testing::MakeTempDir("mapcrc");
  const std::string good = SmallMap(dir);
  EXPECT_NO_THROW(CheckMapDatabase(good));
  auto copy = [&](const std::string& name) {
    const std::string p = (dir / name).string();
    std::filesystem::copy_file(good, p);
    return p;
  };
  const std::string desc = copy("desc.db");
  FlipBlobByte(desc, "descriptors", 3, 17);
  EXPECT_ERROR(LoadMapDatabase(desc), {.file = desc, .field = "descriptors"},
               "tile 3 is damaged (descriptors checksum mismatch); rebuild the map with "
               "`optinav map build`");
  EXPECT_ERROR(CheckMapDatabase(desc), {.file = desc, .field = "descriptors"}, "tile 3 is damaged");
  const std::string kp = copy("kp.db");
  FlipBlobByte(kp, "keypoints", 5, 2);
  EXPECT_ERROR(LoadMapDatabase(kp), {.file = kp, .field = "keypoints"},
               "tile 5 is damaged (keypoints checksum mismatch)");
  const std::string truncated = copy("truncated.db");
  ExecSql(truncated,
          "UPDATE tiles SET keypoints=substr(keypoints, 1, length(keypoints) - 16) "
          "WHERE id=7");
  EXPECT_ERROR(LoadMapDatabase(truncated), {.file = truncated, .field = "keypoints"},
               "tile 7 is damaged (keypoints checksum mismatch)");
  const std::string moved = copy("moved.db");
  ExecSql(moved, "UPDATE tiles SET px0=px0+1 WHERE id=2");
  EXPECT_ERROR(LoadMapDatabase(moved), {.file = moved, .field = "geometry"},
               "tile 2 is damaged (geometry checksum mismatch)");
  const std::string meta = copy("meta.db");
  ExecSql(meta, "UPDATE meta SET value='0.5' WHERE key='map_gsd_m'");
  EXPECT_ERROR(LoadMapDatabase(meta), {.file = meta, .field = "meta"},
               "map database metadata is damaged (checksum mismatch)");
  const std::string no_sum = copy("nosum.db");
  ExecSql(no_sum, "DELETE FROM meta WHERE key='checksum'");
  EXPECT_ERROR(LoadMapDatabase(no_sum), {.file = no_sum, .field = "checksum"},
               "map database lacks metadata");
  // A format-1 database (no checksums): the message names the file, both versions and the fix.
  const std::string v1 = copy("v1.db");
  ExecSql(v1, "UPDATE meta SET value='1' WHERE key='format_version'");
  EXPECT_ERROR(LoadMapDatabase(v1), {.file = v1, .field = "format_version"},
               "map database format version 1 is not supported (this optinav reads version 2); "
               "rebuild it with `optinav map build`");
}

bool SameMap(const MapDatabase& a, const MapDatabase& b) {
  if (a.ortho_path != b.ortho_path || a.crs_wkt != b.crs_wkt || a.crs_name != b.crs_name ||
      a.transform.c != b.transform.c || a.width != b.width || a.height != b.height ||
      a.map_gsd_m != b.map_gsd_m || a.feature_gsd_m != b.feature_gsd_m || a.tile_px != b.tile_px ||
      a.step_px != b.step_px || a.rows != b.rows || a.cols != b.cols ||
      a.feature_type != b.feature_type || a.options.max_features != b.options.max_features ||
      a.tiles.size() != b.tiles.size()) {
    return false;
  }
  for (size_t i = 0; i < a.tiles.size(); ++i) {
    const MapTile &s = a.tiles[i], &t = b.tiles[i];
    if (s.index != t.index || s.row != t.row || s.col != t.col || s.px != t.px ||
        s.padded != t.padded || s.centre_crs != t.centre_crs ||
        s.centre.lat_deg != t.centre.lat_deg || s.keypoints != t.keypoints ||
        s.keypoint_size != t.keypoint_size || s.keypoint_angle != t.keypoint_angle ||
        s.descriptors.size() != t.descriptors.size() ||
        (!s.descriptors.empty() &&
         std::memcmp(s.descriptors.data, t.descriptors.data,
                     s.descriptors.total() * s.descriptors.elemSize()) != 0)) {
      return false;
    }
    for (int k = 0; k < 4; ++k) {
      if (s.corners[k].lat_deg != t.corners[k].lat_deg ||
          s.corners[k].lon_deg != t.corners[k].lon_deg)
        return false;
    }
  }
  return true;
}

// Seeded mutations of a whole database file (random bytes changed, zeroed runs, truncation):
// every copy either loads with exactly the original content or is refused with an Error; none
// crashes, throws anything else, or loads different content. `map info --check` is at least as
// strict as loading.
TEST(MapDatabase, MutatedFilesLoadIdenticalOrAreRefused) {
  const auto dir = testing::MakeTempDir("mapmut");
  const std::string good = SmallMap(dir);
  const MapDatabase original = LoadMapDatabase(good);
  const std::string bytes = ReadBytes(good);
  ASSERT_GT(bytes.size(), 4096u);
  std::mt19937_64 rng(20240522);
  auto uniform = [&](size_t lo, size_t hi) {  // [lo, hi]
    return std::uniform_int_distribution<size_t>(lo, hi)(rng);
  };
  const std::string path = (dir / "mutated.db").string();
  int identical = 0, refused = 0, checked_ok = 0;
  constexpr int kCopies = 200;
  for (int copy = 0; copy < kCopies; ++copy) {
    std::string m = bytes;
    const int kind = copy % 4;
    if (kind == 0 || kind == 1) {  // 1 to 8 random bytes changed anywhere (kind 1: one byte)
      const size_t n = kind == 1 ? 1 : uniform(1, 8);
      for (size_t i = 0; i < n; ++i) {
        m[uniform(0, m.size() - 1)] ^= static_cast<char>(uniform(1, 255));
      }
    } else if (kind == 2) {  // a run of up to 64 bytes zeroed
      const size_t at = uniform(0, m.size() - 1), len = std::min(uniform(1, 64), m.size() - at);
      std::fill_n(m.begin() + static_cast<std::ptrdiff_t>(at), len, '\0');
    } else {  // cut short, or a piece cut out of the middle
      const size_t at = uniform(0, m.size() - 1);
      if (copy % 8 == 3) {
        m.resize(at);
      } else {
        m.erase(at, std::min(uniform(1, 512), m.size() - at));
      }
    }
    WriteBytes(path, m);
    std::string what = "loaded";
    try {
      const MapDatabase loaded = LoadMapDatabase(path);
      EXPECT_TRUE(SameMap(loaded, original)) << "copy " << copy << " loaded with other content";
      ++identical;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      what = "refused";
      ++refused;
    }
    try {
      CheckMapDatabase(path);
      EXPECT_EQ(what, "loaded") << "copy " << copy << ": --check passed a refused file";
      ++checked_ok;
    } catch (const Error&) {
    }
  }
  std::printf("mutated map databases: %d loaded identical, %d refused, %d passed --check\n",
              identical, refused, checked_ok);
  EXPECT_EQ(identical + refused, kCopies);
  EXPECT_GT(refused, kCopies / 2);
}

}  // namespace
}  // namespace optinav::maploc
