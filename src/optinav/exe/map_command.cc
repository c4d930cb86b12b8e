// optinav map build | info | locate: orthophoto feature databases and frame-to-map fixes.
#include <cstdio>
#include <fstream>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "optinav/exe/cli_common.h"
#include "optinav/exe/commands.h"
#include "optinav/io/text_parse.h"
#include "optinav/maploc/frame_synth.h"
#include "optinav/maploc/locator.h"
#include "optinav/util/logging.h"
#include "optinav/util/timer.h"

namespace optinav {
namespace {

using maploc::LocateResult;
using maploc::Prior;

nlohmann::json ResultJson(const LocateResult& r) {
  nlohmann::json j;
  j["localized"] = r.localized;
  j["reason"] = r.reason;
  j["method"] = r.method;
  j["lat"] = r.localized ? nlohmann::json(r.latlon.lat_deg) : nlohmann::json(nullptr);
  j["lon"] = r.localized ? nlohmann::json(r.latlon.lon_deg) : nlohmann::json(nullptr);
  j["x"] = r.localized ? nlohmann::json(r.crs_xy.x()) : nlohmann::json(nullptr);
  j["y"] = r.localized ? nlohmann::json(r.crs_xy.y()) : nlohmann::json(nullptr);
  j["map_px"] = {r.map_px.x(), r.map_px.y()};
  j["heading_deg"] = r.heading_deg;
  j["scale"] = r.scale;
  j["altitude_m"] = r.altitude_m;
  j["inliers"] = r.inliers;
  j["inlier_ratio"] = r.inlier_ratio;
  j["confidence"] = r.confidence;
  j["candidate_tiles"] = r.candidate_tiles.size();
  j["time_ms"] = r.times.total_ms;
  j["times_ms"] = {{"extraction", r.times.extraction_ms},
                   {"matching", r.times.matching_ms},
                   {"estimation", r.times.estimation_ms}};
  return j;
}

std::string ResultText(const LocateResult& r) {
  if (!r.localized) {
    return fmt::format("not localized ({}): {}\n  time {:.1f} ms\n", r.method, r.reason,
                       r.times.total_ms);
  }
  return fmt::format(
      "localized by {} (confidence {:.2f})\n"
      "  lat, lon   : {:.7f}, {:.7f}\n"
      "  map CRS    : {:.2f}, {:.2f}\n"
      "  map pixel  : {:.1f}, {:.1f}\n"
      "  heading    : {:.1f} deg\n"
      "  scale      : {:.3f} map px per frame px (altitude ~{:.0f} m)\n"
      "  inliers    : {} ({:.0f} %)\n"
      "  time       : {:.1f} ms (extraction {:.1f}, matching {:.1f}, estimation {:.1f})\n",
      r.method, r.confidence, r.latlon.lat_deg, r.latlon.lon_deg, r.crs_xy.x(), r.crs_xy.y(),
      r.map_px.x(), r.map_px.y(), r.heading_deg, r.scale, r.altitude_m, r.inliers,
      100 * r.inlier_ratio, r.times.total_ms, r.times.extraction_ms, r.times.matching_ms,
      r.times.estimation_ms);
}

// Throws Error when a prior centre is far outside the map extent.
void CheckPriorInsideMap(const maploc::Locator& loc, const maploc::MapDatabase& db,
                         const geo::LatLon& ll, double radius_m, const std::string& option) {
  const Eigen::Vector2d px = loc.LatLonToPixel(ll);
  const double r = radius_m / db.map_gsd_m;
  if (px.x() < -r || px.y() < -r || px.x() > db.width + r || px.y() > db.height + r) {
    throw Error(fmt::format("prior {:.6f},{:.6f} lies outside the map extent (more than the "
                            "radius {} m beyond its border)",
                            ll.lat_deg, ll.lon_deg, radius_m),
                {.field = option});
  }
}

cv::Mat ReadFrame(const std::string& path) {
  cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw Error("cannot read image (missing or not an image)", {.file = path});
  return img;
}

int RunBuild(const std::string& ortho, const maploc::MapBuildOptions& o, const std::string& out) {
  Timer t;
  const maploc::MapDatabase db = maploc::BuildMapDatabase(ortho, o, out);
  std::printf("built %s: %d x %d tiles, %zu features, %.1f s\n", out.c_str(), db.cols, db.rows,
              db.FeatureCount(), t.ElapsedSeconds());
  return 0;
}

int RunInfo(const std::string& path, bool json) {
  const maploc::MapDatabase db = maploc::LoadMapDatabase(path);
  const geo::CrsTransform crs(db.crs_wkt);
  const auto ul = crs.ToLatLon(db.transform.PixelToCrs({0, 0}));
  const auto lr = crs.ToLatLon(db.transform.PixelToCrs({double(db.width), double(db.height)}));
  size_t min_f = SIZE_MAX, max_f = 0, padded = 0;
  for (const auto& t : db.tiles) {
    min_f = std::min(min_f, t.keypoints.size());
    max_f = std::max(max_f, t.keypoints.size());
    padded += t.padded;
  }
  if (json) {
    nlohmann::json j = {{"format_version", db.format_version},
                        {"ortho", db.ortho_path},
                        {"crs", db.crs_name},
                        {"width_px", db.width},
                        {"height_px", db.height},
                        {"map_gsd_m", db.map_gsd_m},
                        {"extent_m", {db.width * db.map_gsd_m, db.height * db.map_gsd_m}},
                        {"upper_left", {ul.lat_deg, ul.lon_deg}},
                        {"lower_right", {lr.lat_deg, lr.lon_deg}},
                        {"tiles",
                         {{"cols", db.cols},
                          {"rows", db.rows},
                          {"count", db.tiles.size()},
                          {"padded", padded},
                          {"side_px", db.tile_px},
                          {"step_px", db.step_px}}},
                        {"features",
                         {{"type", features::FeatureTypeName(db.feature_type)},
                          {"total", db.FeatureCount()},
                          {"min_per_tile", min_f},
                          {"max_per_tile", max_f}}},
                        {"feature_gsd_m", db.feature_gsd_m}};
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf(
      "map database %s (format %d)\n"
      "  orthophoto : %s\n"
      "  CRS        : %s\n"
      "  size       : %d x %d px at %.3f m/px (%.0f x %.0f m)\n"
      "  extent     : UL %.6f, %.6f  LR %.6f, %.6f (lat, lon)\n"
      "  tiles      : %d cols x %d rows = %zu (%zu padded), side %.0f px, step %.0f px\n"
      "  features   : %s, %zu in total, %zu..%zu per tile, taken at %.3f m/px\n",
      path.c_str(), db.format_version, db.ortho_path.c_str(), db.crs_name.c_str(), db.width,
      db.height, db.map_gsd_m, db.width * db.map_gsd_m, db.height * db.map_gsd_m, ul.lat_deg,
      ul.lon_deg, lr.lat_deg, lr.lon_deg, db.cols, db.rows, db.tiles.size(), padded, db.tile_px,
      db.step_px, features::FeatureTypeName(db.feature_type).c_str(), db.FeatureCount(), min_f,
      max_f, db.feature_gsd_m);
  return 0;
}

struct LocateArgs {
  std::string map, image, list, prior, last_fix, ortho, method = "auto";
  double radius_m = 500, max_travel_m = 0, bearing_deg = 0, heading_sigma = 10;
  std::string deviations = "20,40";
  std::optional<double> heading, altitude;
  bool json = false;
};

LocateResult LocateOne(maploc::Locator& loc, const cv::Mat& frame, const Prior& prior,
                       const std::string& method) {
  if (method == "features") return loc.LocateByFeatures(frame, prior);
  if (method == "oc") return loc.LocateByOrientationCorrelation(frame, prior);
  return loc.Locate(frame, prior);
}

int RunLocate(const LocateArgs& a) {
  if (a.method != "auto" && a.method != "features" && a.method != "oc") {
    throw Error("unknown method '" + a.method + "' (auto|features|oc)", {.field = "--method"});
  }
  if (a.image.empty() == a.list.empty()) {
    throw Error("give exactly one of --image and --images-from", {.field = "--image"});
  }
  const maploc::MapDatabase db = maploc::LoadMapDatabase(a.map);
  maploc::LocateOptions lo;
  lo.ortho_path = a.ortho;
  maploc::Locator loc(db, lo);
  Prior base;
  base.radius_m = a.radius_m;
  base.heading_deg = a.heading;
  base.heading_sigma_deg = a.heading_sigma;
  base.altitude_m = a.altitude;
  if (!a.prior.empty()) {
    base.position = ParseLatLon(a.prior, "--prior");
    CheckPriorInsideMap(loc, db, *base.position, a.radius_m, "--prior");
  }
  if (!a.last_fix.empty()) {
    // The document's prediction: from the last fix along the bearing (to the target) and
    // deviated bearings, as far as the drone can have flown.
    const geo::LatLon fix = ParseLatLon(a.last_fix, "--last-fix");
    if (!(a.max_travel_m > 0))
      throw Error("needs a positive --max-travel", {.field = "--last-fix"});
    std::vector<double> devs = {0.0};
    std::vector<std::string_view> f;
    io::SplitFields(a.deviations, ',', &f);
    for (auto d : f) {
      if (d.empty()) continue;
      const double v = io::ParseFiniteDouble(d, {.field = "--deviations"});
      devs.push_back(v);
      devs.push_back(-v);
    }
    for (double d : devs) {
      base.extra_centres.push_back(geo::GeodesicDirect(fix, a.bearing_deg + d, a.max_travel_m));
    }
    if (!base.position) base.position = base.extra_centres.front();
    CheckPriorInsideMap(loc, db, *base.position, a.radius_m, "--last-fix");
  }
  if (!a.image.empty()) {
    const LocateResult r = LocateOne(loc, ReadFrame(a.image), base, a.method);
    if (a.json) {
      nlohmann::json j = ResultJson(r);
      j["image"] = a.image;
      std::printf("%s\n", j.dump(2).c_str());
    } else {
      std::fputs(ResultText(r).c_str(), stdout);
    }
    return 0;
  }
  // Many frames in one process: one JSON object per line.
  const std::string text = io::ReadFileToString(a.list);
  io::LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  bool header = true;
  while (cursor.Next(&line)) {
    if (io::IsCommentOrBlank(line)) continue;
    io::SplitFields(line, ',', &f);
    if (header) {
      header = false;
      if (f.empty() || f[0] != "image") {
        throw Error(
            "expected the header 'image,prior_lat,prior_lon,radius_m,heading_deg,"
            "heading_sigma_deg'",
            {.file = a.list, .line = cursor.line_number()});
      }
      continue;
    }
    nlohmann::json j;
    const ErrorContext ctx{.file = a.list, .line = cursor.line_number()};
    try {
      if (f.size() != 6) throw Error(fmt::format("expected 6 fields, found {}", f.size()), ctx);
      Prior p = base;
      auto number = [&](int k, const char* name) -> std::optional<double> {
        if (f[k].empty()) return std::nullopt;
        ErrorContext c = ctx;
        c.field = name;
        return io::ParseFiniteDouble(f[k], c);
      };
      const auto lat = number(1, "prior_lat"), lon = number(2, "prior_lon");
      if (lat.has_value() != lon.has_value())
        throw Error("give both prior_lat and prior_lon or neither", ctx);
      if (lat) p.position = geo::LatLon{*lat, *lon};
      if (auto r = number(3, "radius_m")) p.radius_m = *r;
      if (auto h = number(4, "heading_deg")) p.heading_deg = *h;
      if (auto s = number(5, "heading_sigma_deg")) p.heading_sigma_deg = *s;
      if (p.position) CheckPriorInsideMap(loc, db, *p.position, p.radius_m, "prior_lat,prior_lon");
      j = ResultJson(LocateOne(loc, ReadFrame(std::string(f[0])), p, a.method));
    } catch (const Error& e) {
      j = {{"localized", false}, {"reason", std::string("error: ") + e.what()}};
    }
    j["image"] = f.empty() ? "" : std::string(f[0]);
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  return 0;
}

struct RenderArgs {
  std::string ortho, at, out, frame_size = "640x480";
  double heading_deg = 0, gsd_m = 0, tilt_deg = 0, tilt_azimuth_deg = 0;
};

// Renders a synthetic camera frame from an orthophoto (for trying `locate`, tests, demos).
int RunRender(const RenderArgs& a) {
  const geo::GeoRaster raster = geo::GeoRaster::Open(a.ortho);
  const geo::CrsTransform crs(raster.crs_wkt());
  maploc::FrameSpec s;
  if (std::sscanf(a.frame_size.c_str(), "%dx%d", &s.width, &s.height) != 2 || s.width < 16 ||
      s.height < 16) {
    throw Error("expected WxH, e.g. 640x480, got '" + a.frame_size + "'",
                {.field = "--frame-size"});
  }
  const geo::LatLon at = ParseLatLon(a.at, "--at");
  s.centre_px = raster.transform().CrsToPixel(crs.FromLatLon(at));
  if (s.centre_px.x() < 0 || s.centre_px.y() < 0 || s.centre_px.x() > raster.width() ||
      s.centre_px.y() > raster.height()) {
    throw Error("position lies outside the orthophoto", {.field = "--at"});
  }
  const double map_gsd = raster.transform().UnitsPerPixel() *
                         crs.MetresPerUnit(raster.transform().PixelToCrs(s.centre_px));
  s.gsd_m = a.gsd_m > 0 ? a.gsd_m : map_gsd;
  s.heading_deg = a.heading_deg;
  s.tilt_deg = a.tilt_deg;
  s.tilt_azimuth_deg = a.tilt_azimuth_deg;
  const cv::Mat frame = maploc::SynthesizeFrame(raster, map_gsd, s);
  if (!cv::imwrite(a.out, frame)) throw Error("cannot write image", {.file = a.out});
  std::printf("rendered %s: %dx%d at %.3f m/px, heading %.1f deg, centre %.7f,%.7f\n",
              a.out.c_str(), s.width, s.height, s.gsd_m, s.heading_deg, at.lat_deg, at.lon_deg);
  return 0;
}

}  // namespace

int RunMap(int argc, char** argv) {
  CLI::App app{"Orthophoto feature databases and frame-to-map localization", "optinav map"};
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off");

  CLI::App* build = app.add_subcommand("build", "build a tile/feature database from a GeoTIFF");
  std::string ortho, out, frame_size = "640x480", feature_name = "orb";
  maploc::MapBuildOptions bo;
  build->add_option("--ortho", ortho, "georeferenced orthophoto (GeoTIFF)")->required();
  build->add_option("--altitude", bo.altitude_m, "flight altitude above ground (m)")->required();
  build->add_option("--hfov", bo.hfov_deg, "camera horizontal field of view (deg)")->required();
  build->add_option("--frame-size", frame_size, "camera frame size WxH (px)")->required();
  build->add_option("--scale-factor", bo.scale_factor, "tile side / frame footprint")
      ->capture_default_str();
  build->add_option("--overlap", bo.overlap, "fraction shared by neighbouring tiles")
      ->capture_default_str();
  build->add_option("--features", feature_name, "orb|sift|brisk")->capture_default_str();
  build->add_option("--max-features", bo.max_features, "features per tile")->capture_default_str();
  build->add_option("--threads", bo.threads, "worker threads (0: all cores)")
      ->capture_default_str();
  build->add_option("--out", out, "output database (SQLite)")->required();

  CLI::App* info = app.add_subcommand("info", "print a database's extent, CRS, tiles, features");
  std::string info_path;
  bool info_json = false;
  info->add_option("map", info_path, "map database")->required();
  info->add_flag("--json", info_json, "machine-readable output");

  CLI::App* locate = app.add_subcommand("locate", "localize camera frames on the map");
  LocateArgs la;
  locate->add_option("--map", la.map, "map database")->required();
  locate->add_option("--image", la.image, "frame to localize");
  locate->add_option("--images-from", la.list,
                     "csv 'image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg'");
  locate->add_option("--prior", la.prior, "approximate position LAT,LON");
  locate->add_option("--radius", la.radius_m, "prior radius (m)")->capture_default_str();
  locate->add_option("--last-fix", la.last_fix, "prediction: last fix LAT,LON");
  locate->add_option("--max-travel", la.max_travel_m, "prediction: distance flown since (m)");
  locate->add_option("--bearing", la.bearing_deg, "prediction: bearing to the target (deg)");
  locate->add_option("--deviations", la.deviations, "prediction: deviated bearings (deg)")
      ->capture_default_str();
  locate->add_option("--heading", la.heading,
                     "frame heading, deg clockwise from north of frame up");
  locate->add_option("--heading-sigma", la.heading_sigma, "heading uncertainty (deg)")
      ->capture_default_str();
  locate->add_option("--altitude", la.altitude, "approximate altitude above ground (m)");
  locate->add_option("--ortho", la.ortho, "orthophoto path if moved since the build (for oc)");
  locate->add_option("--method", la.method, "auto|features|oc")->capture_default_str();
  locate->add_flag("--json", la.json, "print the result as JSON");
  CLI::App* render = app.add_subcommand("render", "render a synthetic camera frame from a GeoTIFF");
  RenderArgs ra;
  render->add_option("--ortho", ra.ortho, "orthophoto (GeoTIFF)")->required();
  render->add_option("--at", ra.at, "ground point under the frame centre LAT,LON")->required();
  render->add_option("--heading", ra.heading_deg, "frame up direction, deg clockwise from north");
  render->add_option("--gsd", ra.gsd_m, "metres per frame pixel (default: the map's)");
  render->add_option("--frame-size", ra.frame_size, "WxH")->capture_default_str();
  render->add_option("--tilt", ra.tilt_deg, "camera tilt from nadir (deg)");
  render->add_option("--tilt-azimuth", ra.tilt_azimuth_deg, "tilt direction in the frame (deg)");
  render->add_option("--out", ra.out, "output image (PNG, JPEG)")->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    SetLogLevel(log_level);
    if (render->parsed()) return RunRender(ra);
    if (build->parsed()) {
      const auto ft = features::ParseFeatureType(feature_name);
      if (!ft)
        throw Error("unknown feature type '" + feature_name + "' (orb|sift|brisk)",
                    {.field = "--features"});
      bo.feature_type = *ft;
      if (std::sscanf(frame_size.c_str(), "%dx%d", &bo.frame_width, &bo.frame_height) != 2) {
        throw Error("expected WxH, e.g. 640x480, got '" + frame_size + "'",
                    {.field = "--frame-size"});
      }
      if (const std::string msg = bo.Check(); !msg.empty()) {
        spdlog::error("{}", msg);
        return 2;
      }
      return RunBuild(ortho, bo, out);
    }
    if (info->parsed()) return RunInfo(info_path, info_json);
    return RunLocate(la);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

}  // namespace optinav
