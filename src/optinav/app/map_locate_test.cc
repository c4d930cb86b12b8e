#include "optinav/app/map_locate.h"

#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/app/map_info.h"
#include "optinav/app/map_render.h"
#include "optinav/geo/raster.h"
#include "optinav/util/testing.h"

namespace optinav::app {
namespace {

// A real aerial photograph (aero1.jpg, 640x480) as a GeoTIFF at 0.25 m/px in UTM 33N, on the
// central meridian (no grid convergence: map up is north), with a map database for 240x180
// frames of 60 m footprint.
class Aero1Locate : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(testing::MakeTempDir("map_locate"));
    const cv::Mat img = cv::imread((testing::SharedDataDir() / "images" / "aero1.jpg").string());
    geo::GeoTransform gt;
    gt.c = {500000.0, 0.25, 0.0, 5560000.0, 0.0, -0.25};
    geo::WriteGeoTiff(Path("aero1.tif"), img, gt, "EPSG:32633");
    maploc::MapBuildOptions o;
    o.frame_width = 240;
    o.frame_height = 180;
    o.hfov_deg = 60;
    o.altitude_m = 60.0 / (2 * std::tan(30 * M_PI / 180));
    maploc::BuildMapDatabase(Path("aero1.tif"), o, Path("aero1.db"));
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }
  static std::string Path(const std::string& name) { return (*dir_ / name).string(); }

  // The ground point under map pixel (320, 240) and a 240x180 frame of it, heading 40 deg.
  static geo::LatLon Truth() {
    return geo::CrsTransform("EPSG:32633")
        .ToLatLon({500000.0 + 320 * 0.25, 5560000.0 - 240 * 0.25});
  }
  static std::string Frame() {
    FrameRenderOptions r;
    r.ortho_path = Path("aero1.tif");
    r.out_path = Path("frame.png");
    r.at = Truth();
    r.width = 240;
    r.height = 180;
    r.heading_deg = 40;
    EXPECT_DOUBLE_EQ(RenderFrame(r).gsd_m, 0.25);  // the orthophoto's own resolution
    return r.out_path;
  }
  static MapLocateOptions Options() {
    MapLocateOptions o;
    o.map_path = Path("aero1.db");
    o.radius_m = 30;
    return o;
  }
  static double ErrorM(const maploc::LocateResult& r) {
    return geo::GeodesicInverse(Truth(), r.latlon).distance_m;
  }

  static std::filesystem::path* dir_;
};
std::filesystem::path* Aero1Locate::dir_ = nullptr;

TEST_F(Aero1Locate, RenderedFrameWithAPriorIsLocalizedWithinAMetre) {
  MapLocateOptions o = Options();
  o.prior = geo::GeodesicDirect(Truth(), 70, 15);  // 15 m off
  MapLocateRun run(o);
  const maploc::LocateResult r = run.LocateImage(Frame());
  ASSERT_TRUE(r.localized) << r.reason;
  EXPECT_EQ(r.method, "features");
  EXPECT_LT(ErrorM(r), 1.0);
  EXPECT_NEAR(r.heading_deg, 40, 1.0);
  EXPECT_NEAR(r.scale, 1.0, 0.02);
  const nlohmann::json j = LocateResultJson(r);
  EXPECT_EQ(j["localized"], true);
  EXPECT_NEAR(j["lat"].get<double>(), Truth().lat_deg, 1e-5);
  EXPECT_EQ(j["inliers"].get<int>(), r.inliers);
  EXPECT_EQ(j["times_ms"].size(), 3u);
  EXPECT_NE(LocateResultText(r).find("localized by features"), std::string::npos);
}

TEST_F(Aero1Locate, PredictionFromTheLastFixAlongTheBearing) {
  MapLocateOptions o = Options();
  // 100 m flown on bearing 120 deg since the fix; the +-20, 40 deg deviations are extra centres.
  o.last_fix = geo::GeodesicDirect(Truth(), 300, 100);
  o.bearing_deg = 120;
  o.max_travel_m = 100;
  o.radius_m = 20;
  MapLocateRun run(o);
  const maploc::LocateResult r = run.LocateImage(Frame());
  ASSERT_TRUE(r.localized) << r.reason;
  EXPECT_LT(ErrorM(r), 1.0);
}

TEST_F(Aero1Locate, BadOptionsNameTheFlag) {
  MapLocateOptions o = Options();
  o.last_fix = Truth();
  EXPECT_EQ(o.Check(), "--last-fix needs a positive --max-travel");
  EXPECT_ERROR(MapLocateRun{o}, {.file = "", .line = 0, .field = ""}, "positive --max-travel");
  o = Options();
  o.prior = geo::LatLon{10, 10};
  EXPECT_ERROR(MapLocateRun{o}, {.file = "", .field = "--prior"},
               "prior 10.000000,10.000000 lies outside the map extent (more than the radius 30 m");
  o = Options();
  o.map_path = Path("missing.db");
  EXPECT_ERROR(MapLocateRun{o}, {.file = "missing.db"}, "map database not found");
  MapLocateRun run(Options());
  EXPECT_ERROR(run.LocateImage(Path("none.png")), {.file = "none.png", .line = 0},
               "cannot read image (missing or not an image)");
  EXPECT_EQ(ParseLocateMethod("oc"), LocateMethod::kOrientationCorrelation);
  EXPECT_EQ(ParseLocateMethod("sift"), std::nullopt);
}

TEST_F(Aero1Locate, ListGivesOneObjectPerFrameAndBadRowsAReason) {
  const std::string frame = Frame();
  const geo::LatLon t = Truth();
  const std::string list = testing::WriteFile(
      *dir_ / "list.csv",
      "image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg\n" +
          fmt::format("{},{:.7f},{:.7f},25,38,5\n", frame, t.lat_deg + 1e-4, t.lon_deg) +
          "# a comment line\n" + Path("missing.png") + ",,,,,\n" + frame + ",10,10,,,\n" + frame +
          ",47.0\n" + frame + ",47.0,,,,\n");
  MapLocateRun run(Options());
  std::vector<nlohmann::json> out;
  run.LocateList(list, [&](const nlohmann::json& j) { out.push_back(j); });
  ASSERT_EQ(out.size(), 5u);
  for (const nlohmann::json& j : out) EXPECT_TRUE(j.contains("image")) << j.dump();
  ASSERT_EQ(out[0]["localized"], true) << out[0].dump();
  EXPECT_LT(geo::GeodesicInverse(t, {out[0]["lat"], out[0]["lon"]}).distance_m, 1.0);
  EXPECT_EQ(out[1]["image"], Path("missing.png"));
  const auto reason = [&](int k) { return out[k]["reason"].get<std::string>(); };
  EXPECT_EQ(reason(1),
            "error: " + Path("missing.png") + ": cannot read image (missing or not an image)");
  // The map check names the columns, not the row (as before the move to app).
  EXPECT_EQ(reason(2),
            "error: field 'prior_lat,prior_lon': prior 10.000000,10.000000 lies outside the map "
            "extent (more than the radius 30 m beyond its border)");
  EXPECT_EQ(reason(3), "error: " + list + ":6: expected 6 fields, found 2");
  EXPECT_EQ(reason(4), "error: " + list + ":7: give both prior_lat and prior_lon or neither");
  for (int k = 1; k < 5; ++k) EXPECT_EQ(out[k]["localized"], false);

  const std::string bad = testing::WriteFile(*dir_ / "bad.csv", "frame,lat\nx,1\n");
  EXPECT_ERROR(run.LocateList(bad, [](const nlohmann::json&) {}),
               {.file = "bad.csv", .line = 1, .field = ""}, "expected the header 'image,");
}

TEST_F(Aero1Locate, MapInfoSummarizesTheDatabase) {
  const maploc::MapDatabase db = maploc::LoadMapDatabase(Path("aero1.db"));
  const nlohmann::json j = MapInfoJson(db);
  EXPECT_EQ(j["width_px"], 640);
  EXPECT_EQ(j["height_px"], 480);
  EXPECT_EQ(j["extent_m"], nlohmann::json({160.0, 120.0}));
  EXPECT_EQ(j["crs"], "WGS 84 / UTM zone 33N");
  EXPECT_EQ(j["tiles"]["count"], db.tiles.size());
  EXPECT_EQ(j["tiles"]["count"], db.cols * db.rows);
  EXPECT_EQ(j["features"]["type"], "orb");
  EXPECT_EQ(j["features"]["total"], db.FeatureCount());
  EXPECT_LE(j["features"]["min_per_tile"], j["features"]["max_per_tile"]);
  EXPECT_NEAR(j["upper_left"][0].get<double>(), 50.19219, 1e-5);  // cs2cs EPSG:32633 EPSG:4326
  EXPECT_NEAR(j["upper_left"][1].get<double>(), 15.0, 1e-9);      // on the central meridian
  const std::string text = MapInfoText("aero1.db", db);
  EXPECT_EQ(text.rfind("map database aero1.db (format ", 0), 0u) << text;
  EXPECT_NE(text.find("\n  size       : 640 x 480 px at 0.250 m/px (160 x 120 m)\n"),
            std::string::npos)
      << text;
}

TEST_F(Aero1Locate, RenderOutsideTheOrthophotoNamesAt) {
  FrameRenderOptions r;
  r.ortho_path = Path("aero1.tif");
  r.out_path = Path("outside.png");
  r.at = {10, 10};
  EXPECT_ERROR(RenderFrame(r), {.file = "", .field = "--at"},
               "position lies outside the orthophoto");
  EXPECT_FALSE(std::filesystem::exists(r.out_path));
}

}  // namespace
}  // namespace optinav::app
