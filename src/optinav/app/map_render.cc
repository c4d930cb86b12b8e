#include "optinav/app/map_render.h"

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "optinav/geo/raster.h"
#include "optinav/geometry/angles.h"
#include "optinav/io/text_parse.h"
#include "optinav/maploc/aerial_camera.h"

namespace optinav::app {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kDefaultHfovDeg = 90.0;

// Encodes by the file's extension and writes through a temporary file and a rename: an
// interrupted or failed write (disk full) leaves the old file or none, never half an image.
void WriteImageAtomically(const std::string& path, const cv::Mat& image,
                          const std::vector<int>& params = {}) {
  std::vector<uchar> buf;
  const std::string ext = std::filesystem::path(path).extension().string();
  bool encoded = false;
  try {
    encoded = !ext.empty() && cv::imencode(ext, image, buf, params);
  } catch (const cv::Exception&) {  // no encoder for the extension
  }
  if (!encoded) {
    throw Error("cannot encode the image (use .png, .jpg or .tif)", {.file = path});
  }
  io::WriteFileAtomically(path, std::string(buf.begin(), buf.end()));
}

// The legacy model: a frame centred on `at` with the tilt of maploc::SynthesizeFrame.
RenderedFrame RenderLegacyTilt(const FrameRenderOptions& o, const geo::GeoRaster& raster,
                               const Eigen::Vector2d& at_px, double map_gsd) {
  maploc::FrameSpec s;
  s.width = o.width;
  s.height = o.height;
  s.centre_px = at_px;
  s.gsd_m = o.gsd_m > 0 ? o.gsd_m : map_gsd;
  s.heading_deg = o.heading_deg;
  s.tilt_deg = *o.tilt_deg;
  s.tilt_azimuth_deg = o.tilt_azimuth_deg;
  const cv::Mat frame = maploc::SynthesizeFrame(raster, map_gsd, s);
  WriteImageAtomically(o.out_path, frame);
  return {.gsd_m = s.gsd_m, .altitude_m = 0, .centre = o.at};
}

}  // namespace

std::string FrameRenderOptions::Check() const {
  if (width < 16 || height < 16) return "--frame-size must be at least 16x16";
  if (!std::isfinite(heading_deg)) return "--heading must be finite";
  if (!(gsd_m >= 0)) return "--gsd must be >= 0";
  if (tilt_deg) {
    if (altitude_m || hfov_deg || roll_deg != 0 || pitch_deg != 0) {
      return "--tilt cannot be combined with --altitude, --hfov, --roll or --pitch (the legacy "
             "tilt model has its own camera)";
    }
    if (!(*tilt_deg >= 0 && *tilt_deg < 80)) return "--tilt must be in [0, 80) deg";
    return "";
  }
  if (altitude_m && gsd_m > 0) return "--altitude and --gsd are alternatives: give one";
  if (altitude_m && !(*altitude_m > 0)) return "--altitude must be positive";
  if (hfov_deg && !(*hfov_deg > 1 && *hfov_deg < 170)) return "--hfov must be in (1, 170) deg";
  if (!(std::abs(roll_deg) < 80)) return "--roll must be within +-80 deg";
  if (!(std::abs(pitch_deg) < 80)) return "--pitch must be within +-80 deg";
  return "";
}

RenderedFrame RenderFrame(const FrameRenderOptions& o) {
  if (const std::string e = o.Check(); !e.empty()) throw Error(e);
  const geo::GeoRaster raster = geo::GeoRaster::Open(o.ortho_path);
  const geo::CrsTransform crs(raster.crs_wkt());
  const Eigen::Vector2d at_px = raster.transform().CrsToPixel(crs.FromLatLon(o.at));
  if (at_px.x() < 0 || at_px.y() < 0 || at_px.x() > raster.width() || at_px.y() > raster.height()) {
    throw Error("position lies outside the orthophoto", {.field = "--at"});
  }
  const double map_gsd =
      raster.transform().UnitsPerPixel() * crs.MetresPerUnit(raster.transform().PixelToCrs(at_px));
  if (o.tilt_deg) return RenderLegacyTilt(o, raster, at_px, map_gsd);

  const camera::PinholeCamera cam = camera::PinholeCamera::FromHorizontalFov(
      o.width, o.height, o.hfov_deg.value_or(kDefaultHfovDeg) * kDeg);
  const double altitude = o.altitude_m ? *o.altitude_m : (o.gsd_m > 0 ? o.gsd_m : map_gsd) * cam.fx;
  auto latlon = [&](const Eigen::Vector2d& px) {
    return crs.ToLatLon(raster.transform().PixelToCrs(px));
  };
  // The yaw of the pose is relative to the raster's up direction.
  const double up_bearing = maploc::RasterUpBearingDeg(raster, at_px);
  maploc::AerialPose pose{.nadir_px = at_px,
                          .altitude_m = altitude,
                          .attitude = {.roll_deg = o.roll_deg,
                                       .pitch_deg = o.pitch_deg,
                                       .yaw_deg = WrapDeg360(o.heading_deg - up_bearing)}};
  Eigen::Matrix3d map_from_image;
  const cv::Mat frame = maploc::RenderAerialFrame(raster, map_gsd, pose, cam, &map_from_image);
  WriteImageAtomically(o.out_path, frame);
  const Eigen::Vector2d centre =
      (map_from_image * Eigen::Vector3d(cam.cx, cam.cy, 1)).hnormalized();
  return {.gsd_m = altitude / cam.fx, .altitude_m = altitude, .centre = latlon(centre)};
}

std::string FrameSetOptions::Check() const {
  if (count < 1 || count > 100000) return "--set must be in [1, 100000]";
  if (out_dir.empty()) return "--out-dir is required with --set";
  return frames.Check();
}

FrameSetSummary RenderFrameSet(const FrameSetOptions& o) {
  if (const std::string e = o.Check(); !e.empty()) throw Error(e);
  const geo::GeoRaster raster = geo::GeoRaster::Open(o.ortho_path);
  const std::vector<maploc::PerspectiveFrame> frames =
      maploc::MakePerspectiveFrames(raster, o.count, o.frames, o.seed);
  const std::filesystem::path dir = std::filesystem::absolute(o.out_dir).lexically_normal();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error("cannot create the output folder: " + ec.message(), {.file = dir.string()});
  FrameSetSummary summary;
  summary.frames_csv = (dir / "frames.csv").string();
  summary.truth_csv = (dir / "truth.csv").string();
  std::string given =
      "image,prior_lat,prior_lon,radius_m,heading_deg,heading_sigma_deg,altitude_m,roll_deg,"
      "pitch_deg\n";
  std::string truth =
      "image,lat,lon,center_lat,center_lon,altitude_m,roll_deg,pitch_deg,heading_deg\n";
  const int digits = o.count > 1000 ? static_cast<int>(std::to_string(o.count - 1).size()) : 3;
  for (size_t i = 0; i < frames.size(); ++i) {
    const maploc::PerspectiveFrame& f = frames[i];
    const std::string image = (dir / fmt::format("frame_{:0{}d}.jpg", i, digits)).string();
    if (!f.jpeg.empty()) {
      io::WriteFileAtomically(image, std::string(f.jpeg.begin(), f.jpeg.end()));
    } else {
      WriteImageAtomically(image, f.image, {cv::IMWRITE_JPEG_QUALITY, 100});
    }
    given +=
        fmt::format("{},{:.8f},{:.8f},{:.1f},{:.3f},{:.1f},{:.2f},{:.3f},{:.3f}\n", image,
                    f.prior.lat_deg, f.prior.lon_deg, f.prior_radius_m, f.given_heading_deg,
                    f.heading_sigma_deg, f.given_altitude_m, f.given_roll_deg, f.given_pitch_deg);
    truth += fmt::format("{},{:.8f},{:.8f},{:.8f},{:.8f},{:.2f},{:.3f},{:.3f},{:.3f}\n", image,
                         f.latlon.lat_deg, f.latlon.lon_deg, f.centre_latlon.lat_deg,
                         f.centre_latlon.lon_deg, f.pose.altitude_m, f.pose.attitude.roll_deg,
                         f.pose.attitude.pitch_deg, f.heading_deg);
  }
  io::WriteFileAtomically(summary.frames_csv, given);
  io::WriteFileAtomically(summary.truth_csv, truth);
  summary.count = static_cast<int>(frames.size());
  return summary;
}

}  // namespace optinav::app
