// Frame-to-map localization runs (`optinav map locate`): one frame with a prior, or a csv list of
// frames with their own priors in one process (the map and its index are loaded once).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "optinav/geo/geo.h"
#include "optinav/maploc/locator.h"

namespace optinav::app {

enum class LocateMethod { kAuto, kFeatures, kOrientationCorrelation };

// "auto" | "features" | "oc"; nullopt for anything else.
std::optional<LocateMethod> ParseLocateMethod(const std::string& name);

struct MapLocateOptions {
  std::string map_path;    // map database (SQLite)
  std::string ortho_path;  // orthophoto, if moved since the build (orientation correlation)
  std::string model_path;  // XFeat network of an xfeat map ("" = the default beside the data)
  LocateMethod method = LocateMethod::kAuto;
  std::optional<geo::LatLon> prior;  // approximate position
  double radius_m = 500;             // prior radius, also around each predicted position
  // Predicted positions (no prior needed): the last fix moved max_travel_m along bearing_deg and
  // along bearing_deg +- each deviation, as far as the drone can have flown since that fix.
  std::optional<geo::LatLon> last_fix;
  double max_travel_m = 0;
  double bearing_deg = 0;  // bearing to the target
  std::vector<double> deviations_deg = {20, 40};
  std::optional<double> heading_deg;  // frame up, clockwise from north
  double heading_sigma_deg = 10;
  std::optional<double> altitude_m;  // above ground
  // Camera attitude from the autopilot (--attitude ROLL,PITCH; convention in docs/MAPDB.md:
  // roll right wing down, pitch nose up, degrees) and its 1-sigma error.
  std::optional<double> roll_deg, pitch_deg;
  double attitude_sigma_deg = 1.5;
  // The camera: --hfov (0: the map's build value; principal point at the frame centre) or
  // --camera, a EuRoC sensor.yaml (intrinsics and distortion). Not both.
  double hfov_deg = 0;
  std::string camera_path;

  // "" when valid, else a message naming the flag at fault.
  std::string Check() const;
};

// One locate run: the map loaded once, the prior from the options checked against its extent.
class MapLocateRun {
 public:
  // Throws Error on invalid options, an unreadable map or camera file (naming the file and the
  // field), or a prior centre far outside the map (field "--prior" or "--last-fix").
  explicit MapLocateRun(const MapLocateOptions& options);
  ~MapLocateRun();

  // Localizes the frame in `image_path` (any format OpenCV reads; read as grey) with the prior of
  // the options. Throws Error when the image cannot be read; an unlocalized frame is a result.
  maploc::LocateResult LocateImage(const std::string& image_path);

  // Localizes a frame held in memory (8-bit grey, or BGR) with the per-frame fields of
  // `frame_options` in place of the run's: prior, radius, last fix and prediction, heading,
  // altitude, attitude and hfov_deg (a different field of view rebuilds the locator); the map,
  // orthophoto, camera file and method stay the run's. For callers that hold frames as arrays
  // (the Python module). Throws Error on invalid options (Check()) or a prior outside the map.
  maploc::LocateResult Locate(const cv::Mat& frame, const MapLocateOptions& frame_options);
  // The same for the frame in `image_path`, read as LocateImage reads it.
  maploc::LocateResult LocateImage(const std::string& image_path,
                                   const MapLocateOptions& frame_options);

  const maploc::MapDatabase& database() const { return *db_; }

  // Localizes each frame listed in the csv `list_path` and hands `emit` one JSON object per frame,
  // in order: the LocateResultJson plus "image", or {localized: false, reason: "error: ..."}
  // when that row or its frame is bad. Columns are found by the header, in any order: `image`
  // (required), prior_lat, prior_lon, radius_m, heading_deg, heading_sigma_deg, altitude_m,
  // roll_deg, pitch_deg; an empty field (or a missing column) keeps the options' value. Throws
  // Error (file, line, field) only for an unreadable list or a bad header (an unknown or
  // repeated column is named in the field).
  void LocateList(const std::string& list_path,
                  const std::function<void(const nlohmann::json&)>& emit);

 private:
  maploc::LocateResult LocatePath(const std::string& image_path, const maploc::Prior& prior);
  maploc::LocateResult LocateGrey(const cv::Mat& frame, const maploc::Prior& prior);
  // The prior of the per-frame fields of `o`, its centres checked against the map extent.
  maploc::Prior PriorOf(const MapLocateOptions& o) const;
  void MakeLocator(double hfov_deg);
  void CheckInsideMap(const geo::LatLon& centre, double radius_m, const std::string& field) const;

  MapLocateOptions options_;
  std::unique_ptr<maploc::MapDatabase> db_;
  std::unique_ptr<maploc::Locator> locator_;
  maploc::Prior prior_;
};

// The result as JSON: localized, reason, method, lat/lon/x/y (the vehicle's position: the
// camera's nadir point), center_lat/center_lon (the image centre's ground point),
// position_sigma_m (all null unless localized), map_px, center_px, heading_deg, roll_deg,
// pitch_deg, altitude_m, scale, inliers, inlier_ratio, confidence, candidate_tiles, time_ms,
// times_ms {extraction, matching, estimation}.
nlohmann::json LocateResultJson(const maploc::LocateResult& r);

// The result as a few human-readable lines.
std::string LocateResultText(const maploc::LocateResult& r);

}  // namespace optinav::app
