#include "optinav/app/map_locate.h"

#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/app/map_info.h"
#include "optinav/app/map_render.h"
#include "optinav/geo/raster.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/test_maps.h"
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

TEST_F(Aero1Locate, FrameInMemoryWithPerFrameOptionsEqualsTheFileRun) {
  MapLocateOptions o = Options();
  o.prior = geo::GeodesicDirect(Truth(), 70, 15);
  const maploc::LocateResult from_file = MapLocateRun(o).LocateImage(Frame());
  ASSERT_TRUE(from_file.localized) << from_file.reason;
  // One run without a prior; the frame's options bring it (as the Python module does).
  MapLocateRun run(Options());
  const cv::Mat grey = cv::imread(Frame(), cv::IMREAD_GRAYSCALE);
  const maploc::LocateResult r = run.Locate(grey, o);
  ASSERT_TRUE(r.localized) << r.reason;
  EXPECT_DOUBLE_EQ(r.latlon.lat_deg, from_file.latlon.lat_deg);
  EXPECT_DOUBLE_EQ(r.latlon.lon_deg, from_file.latlon.lon_deg);
  EXPECT_EQ(r.inliers, from_file.inliers);
  // A colour frame (BGR) is converted as imread converts it.
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  EXPECT_DOUBLE_EQ(run.Locate(bgr, o).latlon.lat_deg, from_file.latlon.lat_deg);
  // Another field of view rebuilds the locator; the map's own again gives the first result.
  MapLocateOptions wide = o;
  wide.hfov_deg = 90;
  EXPECT_NO_THROW(run.Locate(grey, wide));
  EXPECT_DOUBLE_EQ(run.Locate(grey, o).latlon.lat_deg, from_file.latlon.lat_deg);

  MapLocateOptions bad = o;
  bad.altitude_m = -1;
  EXPECT_ERROR(run.Locate(grey, bad), {}, "--altitude must be positive");
  bad = o;
  bad.prior = geo::LatLon{10, 10};
  EXPECT_ERROR(run.Locate(grey, bad), {.field = "--prior"}, "lies outside the map extent");
  EXPECT_ERROR(run.Locate(cv::Mat(), o), {}, "empty frame");
  EXPECT_ERROR(run.Locate(cv::Mat(8, 8, CV_32F), o), {}, "8-bit grey or BGR");
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
               {.file = "bad.csv", .line = 1, .field = "frame"},
               "unknown column 'frame' in the header (known: image,prior_lat,prior_lon,radius_m,"
               "heading_deg,heading_sigma_deg,altitude_m,roll_deg,pitch_deg)");
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

// A perspective frame (issue 18) of the NAIP 2017 image, localized on a map of the 2009 image
// (map build --altitude 640 --hfov 90 --frame-size 256x256): camera pitched 12 deg nose up and
// rolled 6 deg right wing up, so the image centre lies ~150 m ahead of the vehicle.
class NaipPerspective : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(testing::MakeTempDir("map_locate_naip"));
    maploc::MapBuildOptions o;
    o.frame_width = o.frame_height = 256;
    o.hfov_deg = 90;
    o.altitude_m = 640;
    maploc::BuildMapDatabase(maploc::testmaps::Naip("20090818"), o, Path("naip2009.db"));
    const geo::GeoRaster flight = geo::GeoRaster::Open(maploc::testmaps::Naip("20170827"));
    const maploc::AerialPose pose{.nadir_px = {450, 380},
                                  .altitude_m = 700,
                                  .attitude = {.roll_deg = -6, .pitch_deg = 12, .yaw_deg = 35}};
    Eigen::Matrix3d map_from_image;
    const cv::Mat frame = maploc::RenderAerialFrame(
        flight, maploc::RasterGsdMetres(flight), pose,
        camera::PinholeCamera::FromHorizontalFov(256, 256, M_PI / 2), &map_from_image);
    cv::imwrite(Path("frame.png"), frame);
    const geo::CrsTransform crs(flight.crs_wkt());
    vehicle_ = new geo::LatLon(crs.ToLatLon(flight.transform().PixelToCrs(pose.nadir_px)));
    const Eigen::Vector2d centre_px =
        (map_from_image * Eigen::Vector3d(127.5, 127.5, 1)).hnormalized();
    centre_ = new geo::LatLon(crs.ToLatLon(flight.transform().PixelToCrs(centre_px)));
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
    delete vehicle_;
    delete centre_;
  }
  static std::string Path(const std::string& name) { return (*dir_ / name).string(); }

  // A prior 150 m off, the heading 5 deg off; no attitude or altitude (the tests add them).
  static MapLocateOptions Options() {
    MapLocateOptions o;
    o.map_path = Path("naip2009.db");
    o.prior = geo::GeodesicDirect(*vehicle_, 200, 150);
    o.radius_m = 300;
    o.heading_deg = 40;
    return o;
  }
  static MapLocateOptions WithAttitude(MapLocateOptions o) {
    o.roll_deg = -6.5;  // the autopilot's attitude and altitude, with errors
    o.pitch_deg = 12.8;
    o.altitude_m = 660;
    return o;
  }
  static double Distance(const geo::LatLon& a, const geo::LatLon& b) {
    return geo::GeodesicInverse(a, b).distance_m;
  }

  static std::filesystem::path* dir_;
  static geo::LatLon* vehicle_;
  static geo::LatLon* centre_;
};
std::filesystem::path* NaipPerspective::dir_ = nullptr;
geo::LatLon* NaipPerspective::vehicle_ = nullptr;
geo::LatLon* NaipPerspective::centre_ = nullptr;

TEST_F(NaipPerspective, AttitudeGivenGivesTheVehiclePositionAndTheCentre) {
  ASSERT_GT(Distance(*vehicle_, *centre_), 140);  // what a nadir assumption would get wrong
  MapLocateRun run(WithAttitude(Options()));
  const maploc::LocateResult r = run.LocateImage(Path("frame.png"));
  ASSERT_TRUE(r.localized) << r.reason;
  std::printf(
      "perspective frame: vehicle error %.2f m, centre error %.2f m, altitude %.1f m, "
      "roll %.2f pitch %.2f heading %.2f, sigma %.1f m, %s\n",
      Distance(r.latlon, *vehicle_), Distance(r.centre_latlon, *centre_), r.altitude_m, r.roll_deg,
      r.pitch_deg, r.heading_deg, r.position_sigma_m, r.method.c_str());
  EXPECT_LT(Distance(r.latlon, *vehicle_), 10.0);
  EXPECT_LT(Distance(r.centre_latlon, *centre_), 10.0);
  EXPECT_NEAR(r.altitude_m, 700, 35);  // 5 %
  EXPECT_NEAR(r.heading_deg, 35, 2.0);
  EXPECT_GT(r.position_sigma_m, 0);

  const nlohmann::json j = LocateResultJson(r);
  for (const char* key : {"lat", "lon", "x", "y", "center_lat", "center_lon", "altitude_m",
                          "roll_deg", "pitch_deg", "heading_deg", "position_sigma_m"}) {
    ASSERT_TRUE(j.contains(key) && j[key].is_number()) << key << ": " << j.dump();
  }
  EXPECT_DOUBLE_EQ(j["lat"].get<double>(), r.latlon.lat_deg);
  EXPECT_DOUBLE_EQ(j["x"].get<double>(), r.crs_xy.x());
  EXPECT_DOUBLE_EQ(j["center_lon"].get<double>(), r.centre_latlon.lon_deg);
  EXPECT_DOUBLE_EQ(j["position_sigma_m"].get<double>(), r.position_sigma_m);
  EXPECT_DOUBLE_EQ(j["pitch_deg"].get<double>(), r.pitch_deg);
  const std::string text = LocateResultText(r);
  EXPECT_NE(text.find(fmt::format("  vehicle    : {:.7f}, {:.7f} (+-", r.latlon.lat_deg,
                                  r.latlon.lon_deg)),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("  attitude   : roll "), std::string::npos) << text;
  EXPECT_NE(text.find("(image centre's ground point)"), std::string::npos) << text;

  // Not localized: the positions and the sigma are null, the attitude stays a number.
  const nlohmann::json none = LocateResultJson(maploc::LocateResult{});
  for (const char* key : {"lat", "lon", "x", "y", "center_lat", "center_lon", "position_sigma_m"})
    EXPECT_TRUE(none[key].is_null()) << key;
  EXPECT_TRUE(none["roll_deg"].is_number());
}

TEST_F(NaipPerspective, CameraFileOfAnotherSizeSameAsHfov) {
  // The same 90 deg camera at twice the resolution: scaled to the frame.
  const std::string yaml = testing::WriteFile(
      *dir_ / "sensor.yaml",
      "sensor_type: camera\n"
      "T_BS:\n  cols: 4\n  rows: 4\n  data: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n"
      "resolution: [512, 512]\ncamera_model: pinhole\n"
      "intrinsics: [256, 256, 255.5, 255.5]\ndistortion_model: none\n");
  MapLocateOptions o = WithAttitude(Options());
  o.camera_path = yaml;
  const maploc::LocateResult r = MapLocateRun(o).LocateImage(Path("frame.png"));
  ASSERT_TRUE(r.localized) << r.reason;
  EXPECT_LT(Distance(r.latlon, *vehicle_), 10.0);
  EXPECT_NEAR(r.altitude_m, 700, 35);

  o.camera_path = Path("missing.yaml");
  EXPECT_ERROR(MapLocateRun{o}, {.file = "missing.yaml"}, "cannot open file");
  const std::string bad = testing::WriteFile(
      *dir_ / "bad_sensor.yaml",
      "T_BS:\n  cols: 4\n  rows: 4\n  data: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n"
      "resolution: [512, 512]\nintrinsics: [256, 256, 255.5]\n");
  o.camera_path = bad;
  EXPECT_ERROR(MapLocateRun{o}, {.file = "bad_sensor.yaml", .field = "intrinsics"}, "");
}

TEST_F(NaipPerspective, OptionsCheckNamesTheFlag) {
  MapLocateOptions o = Options();
  EXPECT_EQ(o.Check(), "");
  o.pitch_deg = 85;
  EXPECT_EQ(o.Check(), "--attitude roll and pitch must be within +-80 deg");
  o = Options();
  o.altitude_m = 0;
  EXPECT_EQ(o.Check(), "--altitude must be positive");
  o = Options();
  o.attitude_sigma_deg = 0;
  EXPECT_EQ(o.Check(), "--attitude-sigma must be in (0, 90) deg");
  o = Options();
  o.hfov_deg = 180;
  EXPECT_EQ(o.Check(), "--hfov must be in (0, 180) deg");
  o.hfov_deg = 60;
  EXPECT_EQ(o.Check(), "");
  o.camera_path = "sensor.yaml";
  EXPECT_EQ(o.Check(), "--camera and --hfov exclude each other");
}

// --images-from: columns by the header in any order (after a UTF-8 BOM, as spreadsheets save
// it), the three optional ones, empty fields falling back to the options, row errors naming the
// field, header errors naming the column.
TEST_F(NaipPerspective, ListColumnsByTheHeader) {
  const MapLocateOptions with = WithAttitude(Options());
  const maploc::LocateResult direct = MapLocateRun(with).LocateImage(Path("frame.png"));
  ASSERT_TRUE(direct.localized) << direct.reason;
  const geo::LatLon p = *with.prior;
  const std::string frame = Path("frame.png");
  const std::string list = testing::WriteFile(
      *dir_ / "list.csv",
      "\xEF\xBB\xBFpitch_deg,image,roll_deg,heading_sigma_deg,prior_lon,altitude_m,prior_lat,"
      "heading_deg,"
      "radius_m\n" +
          fmt::format("12.8,{},-6.5,10,{:.9f},660,{:.9f},40,300\n", frame, p.lon_deg, p.lat_deg) +
          fmt::format(",{},,,{:.9f},,{:.9f},40,300\n", frame, p.lon_deg, p.lat_deg) +
          fmt::format("abc,{},,,,,,,\n", frame) + fmt::format("85,{},,,,,,,\n", frame) +
          fmt::format(",{},,,,-5,,,\n", frame) + fmt::format(",{},1,2\n", frame));
  std::vector<nlohmann::json> out;
  const auto collect = [&](const nlohmann::json& j) { out.push_back(j); };
  MapLocateRun(Options()).LocateList(list, collect);  // no attitude or altitude in the options
  ASSERT_EQ(out.size(), 6u);
  // Row 2 gives what `with` gives: the same fix.
  ASSERT_EQ(out[0]["localized"], true) << out[0].dump();
  EXPECT_DOUBLE_EQ(out[0]["lat"].get<double>(), direct.latlon.lat_deg);
  EXPECT_DOUBLE_EQ(out[0]["lon"].get<double>(), direct.latlon.lon_deg);
  EXPECT_DOUBLE_EQ(out[0]["altitude_m"].get<double>(), direct.altitude_m);
  // Row 3 leaves them empty: unknown here (the fix differs) ...
  ASSERT_EQ(out[1]["localized"], true) << out[1].dump();
  EXPECT_NE(out[1]["altitude_m"].get<double>(), direct.altitude_m);
  const auto reason = [&](int k) { return out[k]["reason"].get<std::string>(); };
  EXPECT_EQ(reason(2), "error: " + list + ":4: field 'pitch_deg': not a number: 'abc'");
  EXPECT_EQ(reason(3), "error: " + list + ":5: field 'pitch_deg': must be within +-80 deg");
  EXPECT_EQ(reason(4), "error: " + list + ":6: field 'altitude_m': must be positive");
  EXPECT_EQ(reason(5), "error: " + list + ":7: expected 9 fields, found 4");
  for (int k = 2; k < 6; ++k) EXPECT_EQ(out[k]["image"], frame);
  // ... and the options' values when they have them.
  out.clear();
  MapLocateRun(with).LocateList(list, collect);
  ASSERT_EQ(out.size(), 6u);
  ASSERT_EQ(out[1]["localized"], true) << out[1].dump();
  EXPECT_DOUBLE_EQ(out[1]["lat"].get<double>(), direct.latlon.lat_deg);
  EXPECT_DOUBLE_EQ(out[1]["altitude_m"].get<double>(), direct.altitude_m);

  MapLocateRun run(Options());
  const auto header_error = [&](const std::string& header) {
    return run.LocateList(testing::WriteFile(*dir_ / "h.csv", header + "\n" + frame + "\n"),
                          collect);
  };
  EXPECT_ERROR(header_error("image,yaw_deg"), {.file = "h.csv", .line = 1, .field = "yaw_deg"},
               "unknown column 'yaw_deg' in the header");
  EXPECT_ERROR(header_error("prior_lat,prior_lon"), {.file = "h.csv", .line = 1, .field = "image"},
               "the header has no 'image' column");
  EXPECT_ERROR(header_error("image,roll_deg,roll_deg"),
               {.file = "h.csv", .line = 1, .field = "roll_deg"},
               "column 'roll_deg' appears twice");
}

}  // namespace
}  // namespace optinav::app
