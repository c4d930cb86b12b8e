#include "optinav/app/map_locate.h"

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/io/text_parse.h"

namespace optinav::app {

using maploc::LocateResult;
using maploc::Prior;

std::optional<LocateMethod> ParseLocateMethod(const std::string& name) {
  if (name == "auto") return LocateMethod::kAuto;
  if (name == "features") return LocateMethod::kFeatures;
  if (name == "oc") return LocateMethod::kOrientationCorrelation;
  return std::nullopt;
}

std::string MapLocateOptions::Check() const {
  if (last_fix && !(max_travel_m > 0)) return "--last-fix needs a positive --max-travel";
  return "";
}

MapLocateRun::MapLocateRun(const MapLocateOptions& options) : options_(options) {
  if (const std::string msg = options.Check(); !msg.empty()) throw Error(msg);
  db_ = std::make_unique<maploc::MapDatabase>(maploc::LoadMapDatabase(options.map_path));
  maploc::LocateOptions lo;
  lo.ortho_path = options.ortho_path;
  locator_ = std::make_unique<maploc::Locator>(*db_, lo);
  prior_.radius_m = options.radius_m;
  prior_.heading_deg = options.heading_deg;
  prior_.heading_sigma_deg = options.heading_sigma_deg;
  prior_.altitude_m = options.altitude_m;
  if (options.prior) {
    prior_.position = options.prior;
    CheckInsideMap(*prior_.position, options.radius_m, "--prior");
  }
  if (options.last_fix) {
    std::vector<double> bearings = {options.bearing_deg};
    for (double d : options.deviations_deg) {
      bearings.push_back(options.bearing_deg + d);
      bearings.push_back(options.bearing_deg - d);
    }
    for (double b : bearings) {
      prior_.extra_centres.push_back(
          geo::GeodesicDirect(*options.last_fix, b, options.max_travel_m));
    }
    if (!prior_.position) prior_.position = prior_.extra_centres.front();
    CheckInsideMap(*prior_.position, options.radius_m, "--last-fix");
  }
}

MapLocateRun::~MapLocateRun() = default;

void MapLocateRun::CheckInsideMap(const geo::LatLon& centre, double radius_m,
                                  const std::string& field) const {
  const Eigen::Vector2d px = locator_->LatLonToPixel(centre);
  const double r = radius_m / db_->map_gsd_m;
  if (px.x() < -r || px.y() < -r || px.x() > db_->width + r || px.y() > db_->height + r) {
    throw Error(fmt::format("prior {:.6f},{:.6f} lies outside the map extent (more than the "
                            "radius {} m beyond its border)",
                            centre.lat_deg, centre.lon_deg, radius_m),
                {.field = field});
  }
}

LocateResult MapLocateRun::LocateFrame(const std::string& image_path, const Prior& prior) {
  const cv::Mat frame = cv::imread(image_path, cv::IMREAD_GRAYSCALE);
  if (frame.empty())
    throw Error("cannot read image (missing or not an image)", {.file = image_path});
  switch (options_.method) {
    case LocateMethod::kFeatures:
      return locator_->LocateByFeatures(frame, prior);
    case LocateMethod::kOrientationCorrelation:
      return locator_->LocateByOrientationCorrelation(frame, prior);
    case LocateMethod::kAuto:
      break;
  }
  return locator_->Locate(frame, prior);
}

LocateResult MapLocateRun::LocateImage(const std::string& image_path) {
  return LocateFrame(image_path, prior_);
}

void MapLocateRun::LocateList(const std::string& list_path,
                              const std::function<void(const nlohmann::json&)>& emit) {
  const std::string text = io::ReadFileToString(list_path);
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
            {.file = list_path, .line = cursor.line_number()});
      }
      continue;
    }
    nlohmann::json j;
    const ErrorContext ctx{.file = list_path, .line = cursor.line_number()};
    try {
      if (f.size() != 6) throw Error(fmt::format("expected 6 fields, found {}", f.size()), ctx);
      Prior p = prior_;
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
      if (p.position) CheckInsideMap(*p.position, p.radius_m, "prior_lat,prior_lon");
      j = LocateResultJson(LocateFrame(std::string(f[0]), p));
    } catch (const Error& e) {
      j = {{"localized", false}, {"reason", std::string("error: ") + e.what()}};
    } catch (const std::exception& e) {  // OpenCV or the library: this frame fails, not the run
      j = {{"localized", false}, {"reason", std::string("internal error: ") + e.what()}};
    }
    j["image"] = f.empty() ? "" : std::string(f[0]);
    emit(j);
  }
}

nlohmann::json LocateResultJson(const LocateResult& r) {
  const auto if_localized = [&](double v) {
    return r.localized ? nlohmann::json(v) : nlohmann::json(nullptr);
  };
  nlohmann::json j;
  j["localized"] = r.localized;
  j["reason"] = r.reason;
  j["method"] = r.method;
  j["lat"] = if_localized(r.latlon.lat_deg);
  j["lon"] = if_localized(r.latlon.lon_deg);
  j["x"] = if_localized(r.crs_xy.x());
  j["y"] = if_localized(r.crs_xy.y());
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

std::string LocateResultText(const LocateResult& r) {
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

}  // namespace optinav::app
