#include "optinav/maploc/map_db.h"

#include <filesystem>

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
  EXPECT_ERROR(LoadMapDatabase(broken), {.file = broken}, "tile 1 has inconsistent feature data");
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

}  // namespace
}  // namespace optinav::maploc
