// optinav.maploc: MapDatabase.locate() over app::MapLocateRun, the code of `optinav map locate`,
// and build_map() over maploc::BuildMapDatabase (`optinav map build`).
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "optinav/app/map_info.h"
#include "optinav/app/map_locate.h"
#include "optinav/app/map_render.h"
#include "optinav/features/features.h"
#include "optinav/maploc/map_db.h"
#include "optinav/python/convert.h"

namespace optinav::python {
namespace {

using LatLonPair = std::optional<std::pair<double, double>>;

std::optional<geo::LatLon> ToLatLon(const LatLonPair& p) {
  if (!p) return std::nullopt;
  return geo::LatLon{p->first, p->second};
}

// A frame array as an OpenCV image sharing its memory (grey, or BGR as the app expects); an RGB
// frame is converted to grey here with the same weights.
cv::Mat ToFrame(const py::handle& image, bool bgr,
                py::array_t<uint8_t, py::array::c_style>* keep_alive) {
  const py::array any = py::array::ensure(image);
  if (!any) throw py::type_error("image: expected a path or a numpy array");
  if (!py::isinstance<py::array_t<uint8_t>>(any)) {
    throw py::type_error("image: expected an 8-bit array (dtype uint8), got dtype " +
                         py::str(any.dtype()).cast<std::string>());
  }
  *keep_alive = py::array_t<uint8_t, py::array::c_style>::ensure(any);
  const auto& a = *keep_alive;
  const bool grey = a.ndim() == 2 || (a.ndim() == 3 && a.shape(2) == 1);
  const bool colour = a.ndim() == 3 && a.shape(2) == 3;
  if ((!grey && !colour) || a.size() == 0) {
    throw py::value_error("image: expected a H x W grey or H x W x 3 colour array");
  }
  cv::Mat frame(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)),
                grey ? CV_8UC1 : CV_8UC3, const_cast<uint8_t*>(a.data()));
  if (colour && !bgr) {
    cv::Mat g;
    cv::cvtColor(frame, g, cv::COLOR_RGB2GRAY);
    return g;
  }
  return frame;
}

// One map database opened for localization (the map and its index loaded once).
class MapDatabase {
 public:
  MapDatabase(const py::object& path, std::optional<double> hfov, const py::object& camera,
              const py::object& ortho, const std::string& method) {
    base_.map_path = ToPath(path);
    base_.hfov_deg = hfov.value_or(0);
    if (!camera.is_none()) base_.camera_path = ToPath(camera);
    if (!ortho.is_none()) base_.ortho_path = ToPath(ortho);
    const auto m = app::ParseLocateMethod(method);
    if (!m) throw py::value_error("method: unknown method '" + method + "' (auto|features|oc)");
    base_.method = *m;
    RaiseIfInvalid(base_.Check());
    py::gil_scoped_release release;
    run_ = std::make_unique<app::MapLocateRun>(base_);
  }

  py::dict Locate(const py::object& image, const LatLonPair& prior, double radius_m,
                  const LatLonPair& last_fix, double max_travel, double bearing,
                  const std::vector<double>& deviations, std::optional<double> heading,
                  double heading_sigma, std::optional<double> altitude, const LatLonPair& attitude,
                  double attitude_sigma, std::optional<double> hfov, bool bgr) {
    app::MapLocateOptions o = base_;
    o.prior = ToLatLon(prior);
    o.radius_m = radius_m;
    o.last_fix = ToLatLon(last_fix);
    o.max_travel_m = max_travel;
    o.bearing_deg = bearing;
    o.deviations_deg = deviations;
    o.heading_deg = heading;
    o.heading_sigma_deg = heading_sigma;
    o.altitude_m = altitude;
    if (attitude) {
      o.roll_deg = attitude->first;
      o.pitch_deg = attitude->second;
    }
    o.attitude_sigma_deg = attitude_sigma;
    if (hfov) o.hfov_deg = *hfov;
    RaiseIfInvalid(o.Check());
    maploc::LocateResult r;
    nlohmann::json j;
    if (IsPath(image)) {
      const std::string path = ToPath(image);
      {
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> lock(mutex_);
        r = run_->LocateImage(path, o);
      }
      j = app::LocateResultJson(r);
      j["image"] = path;
    } else {
      py::array_t<uint8_t, py::array::c_style> keep_alive;
      const cv::Mat frame = ToFrame(image, bgr, &keep_alive);
      {
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> lock(mutex_);
        r = run_->Locate(frame, o);
      }
      j = app::LocateResultJson(r);
    }
    return JsonToPython(j).cast<py::dict>();
  }

  py::dict Info() const {
    return JsonToPython(app::MapInfoJson(run_->database())).cast<py::dict>();
  }

  py::str path() const { return ToStr(base_.map_path); }

 private:
  app::MapLocateOptions base_;  // the map, camera and method; the per-frame fields per call
  std::unique_ptr<app::MapLocateRun> run_;
  std::mutex mutex_;  // one locate at a time (the run's locator is rebuilt for another hfov)
};

constexpr const char* kLocateDoc = R"(Localizes one frame on the map (`optinav map locate`).
image: a path (read as the CLI reads it: grey; the result then has "image") or a uint8 array,
  H x W grey or H x W x 3 colour (RGB, as imageio/PIL/matplotlib give it; bgr=True for an
  OpenCV array). A colour array is converted to grey here, so for a colour file the CLI's exact
  numbers come from passing the path.
Keywords are the flags of `optinav map locate` (docs/MAPDB.md), with its defaults: prior
  (lat, lon), radius_m (--radius), last_fix (lat, lon), max_travel, bearing, deviations,
  heading (deg clockwise from north of frame up), heading_sigma, altitude (m above ground),
  attitude (roll, pitch; deg, roll right wing down, pitch nose up), attitude_sigma, hfov (deg;
  None: the database's; another value rebuilds the locator).
Returns the dict of --json: localized, reason, method, lat, lon, x, y, center_lat, center_lon,
  position_sigma_m (None unless localized), map_px, center_px, heading_deg, roll_deg, pitch_deg,
  altitude_m, scale, inliers, inlier_ratio, confidence, candidate_tiles, time_ms, times_ms.
An unlocalized frame is a result (localized False, with the reason), not an exception.)";

}  // namespace

void DefineMaploc(py::module_& m) {
  py::class_<MapDatabase>(m, "MapDatabase",
                          "A map database (`optinav map build` output) opened for localization.")
      .def(py::init<const py::object&, std::optional<double>, const py::object&, const py::object&,
                    const std::string&>(),
           py::arg("path"), py::kw_only(), py::arg("hfov") = py::none(),
           py::arg("camera") = py::none(), py::arg("ortho") = py::none(),
           py::arg("method") = "auto",
           "Opens the database at path. hfov (deg; None: the build's), camera (a EuRoC "
           "sensor.yaml), ortho (the orthophoto if moved since the build) and method "
           "(auto|features|oc) as the flags of `optinav map locate`. Raises optinav.Error when "
           "the file is missing or not a map database.")
      .def("locate", &MapDatabase::Locate, py::arg("image"), py::kw_only(),
           py::arg("prior") = py::none(), py::arg("radius_m") = 500.0,
           py::arg("last_fix") = py::none(), py::arg("max_travel") = 0.0, py::arg("bearing") = 0.0,
           py::arg("deviations") = std::vector<double>{20, 40}, py::arg("heading") = py::none(),
           py::arg("heading_sigma") = 10.0, py::arg("altitude") = py::none(),
           py::arg("attitude") = py::none(), py::arg("attitude_sigma") = 1.5,
           py::arg("hfov") = py::none(), py::arg("bgr") = false, kLocateDoc)
      .def("info", &MapDatabase::Info, "The dict of `optinav map info --json`.")
      .def_property_readonly("path", &MapDatabase::path);

  m.def(
      "build_map",
      [](const py::object& ortho, const py::object& out, double altitude, double hfov,
         std::pair<int, int> frame_size, double scale_factor, double overlap,
         const std::string& features, int max_features, int threads) {
        maploc::MapBuildOptions o;
        o.altitude_m = altitude;
        o.hfov_deg = hfov;
        o.frame_width = frame_size.first;
        o.frame_height = frame_size.second;
        o.scale_factor = scale_factor;
        o.overlap = overlap;
        const auto type = features::ParseFeatureType(features);
        if (!type) {
          throw py::value_error("features: unknown feature type '" + features +
                                "' (orb|sift|brisk)");
        }
        o.feature_type = *type;
        o.max_features = max_features;
        o.threads = threads;
        RaiseIfInvalid(o.Check());
        const std::string ortho_path = ToPath(ortho), out_path = ToPath(out);
        {
          py::gil_scoped_release release;
          maploc::BuildMapDatabase(ortho_path, o, out_path);
        }
        return std::make_unique<MapDatabase>(out, std::nullopt, py::none(), py::none(), "auto");
      },
      py::arg("ortho"), py::arg("out"), py::kw_only(), py::arg("altitude"), py::arg("hfov"),
      py::arg("frame_size"), py::arg("scale_factor") = 1.0, py::arg("overlap") = 0.5,
      py::arg("features") = "orb", py::arg("max_features") = 1024, py::arg("threads") = 2,
      "Builds a map database from a GeoTIFF orthophoto (`optinav map build`; frame_size is "
      "(width, height) in pixels) and opens it.");

  m.def(
      "render_frame",
      [](const py::object& ortho, const py::object& out, std::pair<double, double> at,
         double heading, std::pair<int, int> frame_size, double gsd, std::optional<double> altitude,
         double roll, double pitch, std::optional<double> hfov) {
        app::FrameRenderOptions o;
        o.ortho_path = ToPath(ortho);
        o.out_path = ToPath(out);
        o.at = {at.first, at.second};
        o.heading_deg = heading;
        o.width = frame_size.first;
        o.height = frame_size.second;
        o.gsd_m = gsd;
        o.altitude_m = altitude;
        o.roll_deg = roll;
        o.pitch_deg = pitch;
        o.hfov_deg = hfov;
        RaiseIfInvalid(o.Check());
        app::RenderedFrame r;
        {
          py::gil_scoped_release release;
          r = app::RenderFrame(o);
        }
        py::dict d;
        d["gsd_m"] = r.gsd_m;
        d["altitude_m"] = r.altitude_m;
        d["center_lat"] = r.centre.lat_deg;
        d["center_lon"] = r.centre.lon_deg;
        return d;
      },
      py::arg("ortho"), py::arg("out"), py::kw_only(), py::arg("at"), py::arg("heading") = 0.0,
      py::arg("frame_size") = std::pair<int, int>{640, 480}, py::arg("gsd") = 0.0,
      py::arg("altitude") = py::none(), py::arg("roll") = 0.0, py::arg("pitch") = 0.0,
      py::arg("hfov") = py::none(),
      "Writes a perspective frame of the orthophoto seen from the vehicle at `at` (lat, lon) "
      "(`optinav map render`; the image format by the extension of out: png, jpg, pgm, ...). "
      "Returns gsd_m, altitude_m and the image centre's ground point center_lat/center_lon.");
}

}  // namespace optinav::python
