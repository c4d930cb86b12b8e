#include "optinav/app/map_locate.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/io/euroc_dataset.h"
#include "optinav/io/text_parse.h"

namespace optinav::app {

using maploc::LocateResult;
using maploc::Prior;

namespace {

// The columns of an --images-from list, found by its header in any order.
enum Column {
  kImage,
  kPriorLat,
  kPriorLon,
  kRadius,
  kHeading,
  kHeadingSigma,
  kAltitude,
  kRoll,
  kPitch,
  kColumnCount
};
constexpr std::array<const char*, kColumnCount> kColumnNames = {
    "image",      "prior_lat", "prior_lon", "radius_m", "heading_deg", "heading_sigma_deg",
    "altitude_m", "roll_deg",  "pitch_deg"};
using ColumnIndex = std::array<int, kColumnCount>;  // field of each column, -1 when absent

ColumnIndex ParseHeader(const std::vector<std::string_view>& f, const ErrorContext& ctx) {
  ColumnIndex index;
  index.fill(-1);
  for (size_t k = 0; k < f.size(); ++k) {
    ErrorContext c = ctx;
    c.field = std::string(f[k]);
    const auto it = std::find(kColumnNames.begin(), kColumnNames.end(), f[k]);
    if (it == kColumnNames.end()) {
      throw Error(fmt::format("unknown column '{}' in the header (known: {})", f[k],
                              fmt::join(kColumnNames, ",")),
                  c);
    }
    int& slot = index[it - kColumnNames.begin()];
    if (slot >= 0) throw Error(fmt::format("column '{}' appears twice", f[k]), c);
    slot = static_cast<int>(k);
  }
  if (index[kImage] < 0) {
    ErrorContext c = ctx;
    c.field = "image";
    throw Error("the header has no 'image' column", c);
  }
  return index;
}

// The camera of a EuRoC sensor.yaml; every error names the file (and the field at fault).
camera::PinholeCamera LoadCamera(const std::string& path) {
  const io::CameraCalibration calibration = io::ReadCameraCalibration(path);
  try {
    return io::ToPinholeCamera(calibration);
  } catch (const Error& e) {
    ErrorContext c = e.context();
    c.file = path;
    throw Error(e.message(), c);
  }
}

cv::Mat ReadGreyFrame(const std::string& path) {
  cv::Mat frame = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (frame.empty()) throw Error("cannot read image (missing or not an image)", {.file = path});
  return frame;
}

}  // namespace

std::optional<LocateMethod> ParseLocateMethod(const std::string& name) {
  if (name == "auto") return LocateMethod::kAuto;
  if (name == "features") return LocateMethod::kFeatures;
  if (name == "oc") return LocateMethod::kOrientationCorrelation;
  return std::nullopt;
}

std::string MapLocateOptions::Check() const {
  if (last_fix && !(max_travel_m > 0)) return "--last-fix needs a positive --max-travel";
  if (altitude_m && !(*altitude_m > 0)) return "--altitude must be positive";
  for (const std::optional<double>& a : {roll_deg, pitch_deg}) {
    if (a && !(std::abs(*a) < 80)) return "--attitude roll and pitch must be within +-80 deg";
  }
  if (!(attitude_sigma_deg > 0 && attitude_sigma_deg < 90))
    return "--attitude-sigma must be in (0, 90) deg";
  if (hfov_deg != 0 && !(hfov_deg > 0 && hfov_deg < 180)) return "--hfov must be in (0, 180) deg";
  if (hfov_deg != 0 && !camera_path.empty()) return "--camera and --hfov exclude each other";
  return "";
}

MapLocateRun::MapLocateRun(const MapLocateOptions& options) : options_(options) {
  if (const std::string msg = options.Check(); !msg.empty()) throw Error(msg);
  db_ = std::make_unique<maploc::MapDatabase>(maploc::LoadMapDatabase(options.map_path));
  if (!options.model_path.empty() && db_->feature_type != features::FeatureType::kXFeat) {
    throw Error("--model is for maps built with --features xfeat; this map has " +
                    features::FeatureTypeName(db_->feature_type) + " features",
                {.field = "--model"});
  }
  MakeLocator(options.hfov_deg);
  prior_ = PriorOf(options);
}

void MapLocateRun::MakeLocator(double hfov_deg) {
  maploc::LocateOptions lo;
  lo.ortho_path = options_.ortho_path;
  lo.model_path = options_.model_path;
  lo.hfov_deg = hfov_deg;
  if (!options_.camera_path.empty()) lo.camera = LoadCamera(options_.camera_path);
  locator_.reset();  // it refers to db_; the new one replaces it
  locator_ = std::make_unique<maploc::Locator>(*db_, lo);
  options_.hfov_deg = hfov_deg;
}

Prior MapLocateRun::PriorOf(const MapLocateOptions& options) const {
  Prior prior;
  prior.radius_m = options.radius_m;
  prior.heading_deg = options.heading_deg;
  prior.heading_sigma_deg = options.heading_sigma_deg;
  prior.altitude_m = options.altitude_m;
  prior.roll_deg = options.roll_deg;
  prior.pitch_deg = options.pitch_deg;
  prior.attitude_sigma_deg = options.attitude_sigma_deg;
  if (options.prior) {
    prior.position = options.prior;
    CheckInsideMap(*prior.position, options.radius_m, "--prior");
  }
  if (options.last_fix) {
    std::vector<double> bearings = {options.bearing_deg};
    for (double d : options.deviations_deg) {
      bearings.push_back(options.bearing_deg + d);
      bearings.push_back(options.bearing_deg - d);
    }
    for (double b : bearings) {
      prior.extra_centres.push_back(
          geo::GeodesicDirect(*options.last_fix, b, options.max_travel_m));
    }
    if (!prior.position) prior.position = prior.extra_centres.front();
    CheckInsideMap(*prior.position, options.radius_m, "--last-fix");
  }
  return prior;
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

LocateResult MapLocateRun::LocatePath(const std::string& image_path, const Prior& prior) {
  return LocateGrey(ReadGreyFrame(image_path), prior);
}

LocateResult MapLocateRun::LocateGrey(const cv::Mat& frame, const Prior& prior) {
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
  return LocatePath(image_path, prior_);
}

LocateResult MapLocateRun::LocateImage(const std::string& image_path,
                                       const MapLocateOptions& frame_options) {
  return Locate(ReadGreyFrame(image_path), frame_options);
}

LocateResult MapLocateRun::Locate(const cv::Mat& frame, const MapLocateOptions& frame_options) {
  MapLocateOptions o = frame_options;
  o.map_path = options_.map_path;
  o.ortho_path = options_.ortho_path;
  o.camera_path = options_.camera_path;
  o.method = options_.method;
  if (const std::string msg = o.Check(); !msg.empty()) throw Error(msg);
  if (frame.empty()) throw Error("empty frame");
  if (frame.depth() != CV_8U || (frame.channels() != 1 && frame.channels() != 3)) {
    throw Error(fmt::format("frame must be 8-bit grey or BGR, got depth {} with {} channels",
                            frame.depth(), frame.channels()));
  }
  const Prior prior = PriorOf(o);
  if (o.hfov_deg != options_.hfov_deg) MakeLocator(o.hfov_deg);
  cv::Mat grey = frame;
  if (frame.channels() == 3) cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  return LocateGrey(grey, prior);
}

namespace {

// Applies the row's fields (`f`, columns by `index`) to the options' prior `p`; throws Error
// naming the row and the field at fault.
void ApplyRow(const std::vector<std::string_view>& f, const ColumnIndex& index,
              const ErrorContext& ctx, Prior* p) {
  auto number = [&](Column col) -> std::optional<double> {
    if (index[col] < 0 || f[index[col]].empty()) return std::nullopt;
    ErrorContext c = ctx;
    c.field = kColumnNames[col];
    return io::ParseFiniteDouble(f[index[col]], c);
  };
  auto fail = [&](Column col, const std::string& message) {
    ErrorContext c = ctx;
    c.field = kColumnNames[col];
    throw Error(message, c);
  };
  const auto lat = number(kPriorLat), lon = number(kPriorLon);
  if (lat.has_value() != lon.has_value())
    throw Error("give both prior_lat and prior_lon or neither", ctx);
  if (lat) p->position = geo::LatLon{*lat, *lon};
  if (auto r = number(kRadius)) {
    if (!(*r > 0)) fail(kRadius, "must be positive");
    p->radius_m = *r;
  }
  if (auto h = number(kHeading)) p->heading_deg = *h;
  if (auto s = number(kHeadingSigma)) {
    if (!(*s > 0)) fail(kHeadingSigma, "must be positive");
    p->heading_sigma_deg = *s;
  }
  if (auto a = number(kAltitude)) {
    if (!(*a > 0)) fail(kAltitude, "must be positive");
    p->altitude_m = *a;
  }
  for (const Column col : {kRoll, kPitch}) {
    if (auto a = number(col)) {
      if (!(std::abs(*a) < 80)) fail(col, "must be within +-80 deg");
      (col == kRoll ? p->roll_deg : p->pitch_deg) = *a;
    }
  }
}

}  // namespace

void MapLocateRun::LocateList(const std::string& list_path,
                              const std::function<void(const nlohmann::json&)>& emit) {
  const std::string file = io::ReadFileToString(list_path);
  std::string_view text = file;
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 BOM (spreadsheets)
  io::LineCursor cursor(text);
  std::string_view line;
  std::vector<std::string_view> f;
  std::optional<ColumnIndex> index;
  size_t columns = 0;
  while (cursor.Next(&line)) {
    if (io::IsCommentOrBlank(line)) continue;
    io::SplitFields(line, ',', &f);
    const ErrorContext ctx{.file = list_path, .line = cursor.line_number()};
    if (!index) {
      index = ParseHeader(f, ctx);
      columns = f.size();
      continue;
    }
    const int image_field = (*index)[kImage];
    const std::string image =
        image_field < static_cast<int>(f.size()) ? std::string(f[image_field]) : "";
    nlohmann::json j;
    try {
      if (f.size() != columns)
        throw Error(fmt::format("expected {} fields, found {}", columns, f.size()), ctx);
      if (image.empty())
        throw Error("no image", {.file = ctx.file, .line = ctx.line, .field = "image"});
      Prior p = prior_;
      ApplyRow(f, *index, ctx, &p);
      if (p.position) CheckInsideMap(*p.position, p.radius_m, "prior_lat,prior_lon");
      j = LocateResultJson(LocatePath(image, p));
    } catch (const Error& e) {
      j = {{"localized", false}, {"reason", std::string("error: ") + e.what()}};
    } catch (const std::exception& e) {  // OpenCV or the library: this frame fails, not the run
      j = {{"localized", false}, {"reason", std::string("internal error: ") + e.what()}};
    }
    j["image"] = image;
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
  j["center_lat"] = if_localized(r.centre_latlon.lat_deg);
  j["center_lon"] = if_localized(r.centre_latlon.lon_deg);
  j["position_sigma_m"] = if_localized(r.position_sigma_m);
  j["map_px"] = {r.map_px.x(), r.map_px.y()};
  j["center_px"] = {r.centre_px.x(), r.centre_px.y()};
  j["heading_deg"] = r.heading_deg;
  j["roll_deg"] = r.roll_deg;
  j["pitch_deg"] = r.pitch_deg;
  j["altitude_m"] = r.altitude_m;
  j["scale"] = r.scale;
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
      "  vehicle    : {:.7f}, {:.7f} (+-{:.1f} m, 1 sigma)\n"
      "  map CRS    : {:.2f}, {:.2f}\n"
      "  map pixel  : {:.1f}, {:.1f}\n"
      "  centre     : {:.7f}, {:.7f} (image centre's ground point)\n"
      "  attitude   : roll {:.1f}, pitch {:.1f}, heading {:.1f} deg\n"
      "  altitude   : {:.0f} m (scale {:.3f} map px per frame px)\n"
      "  inliers    : {} ({:.0f} %)\n"
      "  time       : {:.1f} ms (extraction {:.1f}, matching {:.1f}, estimation {:.1f})\n",
      r.method, r.confidence, r.latlon.lat_deg, r.latlon.lon_deg, r.position_sigma_m, r.crs_xy.x(),
      r.crs_xy.y(), r.map_px.x(), r.map_px.y(), r.centre_latlon.lat_deg, r.centre_latlon.lon_deg,
      r.roll_deg, r.pitch_deg, r.heading_deg, r.altitude_m, r.scale, r.inliers,
      100 * r.inlier_ratio, r.times.total_ms, r.times.extraction_ms, r.times.matching_ms,
      r.times.estimation_ms);
}

}  // namespace optinav::app
