#include "optinav/maploc/frame_synth.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/format.h>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/features/features.h"
#include "optinav/geometry/angles.h"
#include "optinav/util/error.h"

namespace optinav::maploc {

namespace {

// The frame seen through `map_from_frame` (frame px -> map px): the map window under the frame's
// corners `corners_map` (plus a margin) is read downsampled by `down` (anti-aliasing), then warped.
// Pixel conventions: frame pixels as camera::PinholeCamera has them (centres at integers, what
// warpPerspective evaluates); map pixels as GDAL (pixel i covers [i, i + 1)), so the window
// image's pixel k, covering the map from win.x + k * width / ow, has its centre half a pixel on.
cv::Mat WarpFromMap(const geo::GeoRaster& raster, const cv::Matx33d& map_from_frame,
                    const std::vector<cv::Point2f>& corners_map, double down, cv::Size size) {
  const cv::Rect box = cv::boundingRect(corners_map);
  constexpr int kMargin = 4;
  const cv::Rect win(box.x - kMargin, box.y - kMargin, box.width + 2 * kMargin,
                     box.height + 2 * kMargin);
  const int ow = std::max(1, static_cast<int>(win.width / down));
  const int oh = std::max(1, static_cast<int>(win.height / down));
  if (static_cast<double>(ow) * oh > 4.0e8) {
    throw Error("the view covers too much of the map to render", {.field = "attitude"});
  }
  const cv::Mat img = raster.ReadGray(win.x, win.y, win.width, win.height, ow, oh);
  const double kx = ow / static_cast<double>(win.width), ky = oh / static_cast<double>(win.height);
  const cv::Matx33d img_from_map(kx, 0, -win.x * kx - 0.5, 0, ky, -win.y * ky - 0.5, 0, 0, 1);
  cv::Mat out;
  cv::warpPerspective(img, out, img_from_map * map_from_frame, size,
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
  return out;
}

}  // namespace

cv::Mat SynthesizeFrame(const geo::GeoRaster& raster, double map_gsd_m, const FrameSpec& s,
                        cv::Matx33d* frame_to_map) {
  const double f = s.focal_px > 0 ? s.focal_px : s.width / (2.0 * std::tan(30.0 * M_PI / 180.0));
  const double scale = s.gsd_m / map_gsd_m;  // map px per frame px at the centre
  const double h = s.heading_deg * M_PI / 180.0;
  const cv::Matx22d rot(std::cos(h), -std::sin(h), std::sin(h), std::cos(h));
  // Ray of a frame pixel, tilted camera, intersected with the ground; in "centre frame pixels".
  const double t = s.tilt_deg * M_PI / 180.0, ta = s.tilt_azimuth_deg * M_PI / 180.0;
  const Eigen::Vector3d axis(std::cos(ta), std::sin(ta), 0);  // tilt about this frame axis
  const Eigen::Matrix3d r = Eigen::AngleAxisd(t, axis).toRotationMatrix();
  auto ground = [&](double u, double v) {
    const Eigen::Vector3d ray = r * Eigen::Vector3d(u - s.width / 2.0, v - s.height / 2.0, f);
    const Eigen::Vector3d c = r * Eigen::Vector3d(0, 0, f);
    // Scale so the centre ray lands at (0, 0) with unit gsd there.
    return cv::Point2d(f * (ray.x() / ray.z() - c.x() / c.z()),
                       f * (ray.y() / ray.z() - c.y() / c.z()));
  };
  std::vector<cv::Point2f> fpts, mpts;
  for (const cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(s.width, 0),
                              cv::Point2d(s.width, s.height), cv::Point2d(0, s.height)}) {
    const cv::Point2d g = ground(p.x, p.y);
    const cv::Vec2d m = rot * cv::Vec2d(g.x, g.y) * scale;
    fpts.emplace_back(p);
    mpts.emplace_back(static_cast<float>(s.centre_px.x() + m[0]),
                      static_cast<float>(s.centre_px.y() + m[1]));
  }
  const cv::Matx33d f2m(cv::getPerspectiveTransform(fpts, mpts));
  if (frame_to_map) *frame_to_map = f2m;
  // Downsample the window when the frame is much coarser than the map (anti-aliasing).
  return WarpFromMap(raster, f2m, mpts, std::max(1.0, scale), cv::Size(s.width, s.height));
}

cv::Mat RenderAerialFrame(const geo::GeoRaster& raster, double map_gsd_m, const AerialPose& pose,
                          const camera::PinholeCamera& camera, Eigen::Matrix3d* map_from_image) {
  camera.Validate();
  const Eigen::Matrix3d h = MapFromImage(pose, camera.K(), map_gsd_m);
  if (map_from_image) *map_from_image = h;
  std::vector<cv::Point2f> mpts;
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(camera.width, 0),
        Eigen::Vector2d(camera.width, camera.height), Eigen::Vector2d(0, camera.height)}) {
    const Eigen::Vector3d m = h * p.homogeneous();
    // A corner ray that meets the plane behind the camera (or at infinity) sees the sky.
    const Eigen::Vector3d ray =
        GroundFromCamera(pose, map_gsd_m).rotation * camera.K().inverse() * p.homogeneous();
    if (!(ray.z() > 1e-6) || std::abs(m.z()) < 1e-12) {
      throw Error("the camera sees the horizon: a frame corner does not look at the ground",
                  {.field = "attitude"});
    }
    mpts.emplace_back(static_cast<float>(m.x() / m.z()), static_cast<float>(m.y() / m.z()));
  }
  // Downsample the window by the scale at the principal point (anti-aliasing); the far side of
  // a tilted view is slightly softer than a real camera would give, the near side as sharp.
  cv::Matx33d map_from_frame;
  cv::eigen2cv(h, map_from_frame);
  const double centre_scale = features::HomographyScale(map_from_frame, {camera.cx, camera.cy});
  return WarpFromMap(raster, map_from_frame, mpts, std::max(1.0, 0.8 * centre_scale),
                     cv::Size(camera.width, camera.height));
}

namespace {

constexpr double kDeg = M_PI / 180.0;

uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

}  // namespace

cv::Mat ApplyCameraEffects(const cv::Mat& gray, const CameraEffects& e, uint64_t seed,
                           std::vector<uchar>* jpeg) {
  if (jpeg) jpeg->clear();
  if (gray.type() != CV_8UC1) throw Error("camera effects need an 8-bit grey frame");
  cv::Mat f;
  gray.convertTo(f, CV_32F, 1.0 / 255.0);
  if (e.blur_sigma_px > 0) cv::GaussianBlur(f, f, cv::Size(0, 0), e.blur_sigma_px);
  if (e.gain != 1.0 || e.gamma != 1.0) {
    f *= e.gain;
    cv::min(f, 1.0, f);
    cv::max(f, 0.0, f);
    cv::pow(f, e.gamma, f);
  }
  f *= 255.0;
  if (e.noise_sigma > 0) {
    cv::Mat noise(f.size(), CV_32F);
    cv::RNG rng(SplitMix64(seed));
    rng.fill(noise, cv::RNG::NORMAL, 0.0, e.noise_sigma);
    f += noise;
  }
  cv::Mat out;
  f.convertTo(out, CV_8U);  // rounds and saturates
  if (e.jpeg_quality > 0) {
    std::vector<uchar> buf;
    cv::imencode(".jpg", out, buf, {cv::IMWRITE_JPEG_QUALITY, std::clamp(e.jpeg_quality, 1, 100)});
    out = cv::imdecode(buf, cv::IMREAD_GRAYSCALE);
    if (jpeg) *jpeg = std::move(buf);
  }
  return out;
}

std::string PerspectiveFrameOptions::Check() const {
  if (width < 16 || height < 16)
    return fmt::format("frame size {}x{} is below 16x16", width, height);
  if (!(hfov_deg > 1 && hfov_deg < 170)) return "hfov must be in (1, 170) deg";
  if (!(altitude_m > 0)) return "altitude must be positive";
  if (!(altitude_min_factor > 0 && altitude_max_factor >= altitude_min_factor)) {
    return "altitude factors must satisfy 0 < min <= max";
  }
  if (!(max_pitch_deg >= 0 && max_pitch_deg < 60 && max_roll_deg >= 0 && max_roll_deg < 60)) {
    return "pitch and roll limits must be in [0, 60) deg";
  }
  if (!(gain_min > 0 && gain_max >= gain_min && gamma_min > 0 && gamma_max >= gamma_min)) {
    return "gain and gamma ranges must satisfy 0 < min <= max";
  }
  if (!(max_blur_sigma_px >= 0 && max_noise_sigma >= 0)) return "blur and noise must be >= 0";
  if (jpeg_quality_min < 0 || jpeg_quality_max > 100 || jpeg_quality_min > jpeg_quality_max ||
      (jpeg_quality_min == 0 && jpeg_quality_max != 0)) {
    return "JPEG quality range must be within 1-100 (or 0, 0 for none)";
  }
  if (!(altitude_error_rel >= 0 && altitude_error_rel < 1 && attitude_error_deg >= 0 &&
        heading_error_deg >= 0 && heading_error_deg <= 180 && prior_offset_m >= 0 &&
        prior_radius_m > 0)) {
    return "given-value errors must be >= 0 (altitude error < 1, heading error <= 180) and the "
           "prior radius positive";
  }
  return "";
}

double RasterUpBearingDeg(const geo::GeoRaster& raster, const Eigen::Vector2d& px) {
  const geo::CrsTransform crs(raster.crs_wkt());
  auto latlon = [&](const Eigen::Vector2d& p) {
    return crs.ToLatLon(raster.transform().PixelToCrs(p));
  };
  return geo::GeodesicInverse(latlon(px), latlon(px + Eigen::Vector2d(0, -20))).azimuth1_deg;
}

double RasterGsdMetres(const geo::GeoRaster& raster) {
  const geo::CrsTransform crs(raster.crs_wkt());
  const Eigen::Vector2d mid =
      raster.transform().PixelToCrs(Eigen::Vector2d(0.5 * raster.width(), 0.5 * raster.height()));
  return raster.transform().UnitsPerPixel() * crs.MetresPerUnit(mid);
}

std::vector<PerspectiveFrame> MakePerspectiveFrames(const geo::GeoRaster& raster, int count,
                                                    const PerspectiveFrameOptions& o,
                                                    uint64_t seed) {
  if (const std::string e = o.Check(); !e.empty()) throw Error(e, {.field = "frames"});
  const geo::CrsTransform crs(raster.crs_wkt());
  const double gsd = RasterGsdMetres(raster);
  const camera::PinholeCamera cam =
      camera::PinholeCamera::FromHorizontalFov(o.width, o.height, o.hfov_deg * kDeg);
  const Eigen::Matrix3d k_inv = cam.K().inverse();
  auto latlon = [&](const Eigen::Vector2d& px) {
    return crs.ToLatLon(raster.transform().PixelToCrs(px));
  };
  // The outer edges of the corner pixels (pixel centres at integers).
  const double r = o.width - 0.5, b = o.height - 0.5;
  const std::array<Eigen::Vector2d, 4> corners = {Eigen::Vector2d(-0.5, -0.5),
                                                  Eigen::Vector2d(r, -0.5), Eigen::Vector2d(r, b),
                                                  Eigen::Vector2d(-0.5, b)};
  // True when every frame corner looks at the ground inside the raster.
  auto sees_raster = [&](const AerialPose& pose) {
    const Eigen::Matrix3d h = MapFromImage(pose, cam.K(), gsd);
    const Eigen::Matrix3d r_gc = GroundFromCamera(pose, gsd).rotation.toRotationMatrix();
    for (const Eigen::Vector2d& c : corners) {
      if (!((r_gc * k_inv * c.homogeneous()).z() > 1e-3)) return false;
      const Eigen::Vector2d m = (h * c.homogeneous()).hnormalized();
      if (!(m.x() >= 0 && m.y() >= 0 && m.x() <= raster.width() && m.y() <= raster.height())) {
        return false;
      }
    }
    return true;
  };

  std::vector<PerspectiveFrame> frames;
  frames.reserve(std::max(0, count));
  for (int i = 0; i < count; ++i) {
    std::mt19937_64 rng(SplitMix64(seed ^ SplitMix64(static_cast<uint64_t>(i) + 1)));
    std::uniform_real_distribution<double> u01(0, 1);
    auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u01(rng); };
    auto sym = [&](double half) { return half * (2 * u01(rng) - 1); };
    PerspectiveFrame f;
    f.camera = cam;
    AerialPose& pose = f.pose;
    bool placed = false;
    for (int attempt = 0; attempt < 1000 && !placed; ++attempt) {
      pose.nadir_px = {uniform(0, raster.width()), uniform(0, raster.height())};
      pose.altitude_m = o.altitude_m * uniform(o.altitude_min_factor, o.altitude_max_factor);
      pose.attitude.yaw_deg = uniform(0, 360);
      pose.attitude.pitch_deg = sym(o.max_pitch_deg);
      pose.attitude.roll_deg = sym(o.max_roll_deg);
      placed = sees_raster(pose);
    }
    if (!placed) {
      throw Error(fmt::format("the raster ({}x{} px at {:.2f} m) is too small for a {}x{} frame "
                              "at {:.0f} m with a {} deg field of view",
                              raster.width(), raster.height(), gsd, o.width, o.height,
                              o.altitude_m * o.altitude_max_factor, o.hfov_deg),
                  {.file = raster.path()});
    }
    f.effects.gain = uniform(o.gain_min, o.gain_max);
    f.effects.gamma = uniform(o.gamma_min, o.gamma_max);
    f.effects.blur_sigma_px = uniform(0, o.max_blur_sigma_px);
    f.effects.noise_sigma = uniform(0, o.max_noise_sigma);
    f.effects.jpeg_quality =
        static_cast<int>(std::floor(uniform(o.jpeg_quality_min, o.jpeg_quality_max + 1 - 1e-9)));
    const uint64_t effects_seed = rng();

    f.image = ApplyCameraEffects(RenderAerialFrame(raster, gsd, pose, cam, &f.map_from_image),
                                 f.effects, effects_seed, &f.jpeg);
    f.latlon = latlon(pose.nadir_px);
    f.centre_px = (f.map_from_image * Eigen::Vector3d(cam.cx, cam.cy, 1.0)).hnormalized();
    f.centre_latlon = latlon(f.centre_px);
    // The yaw is relative to the raster's up direction; its true bearing at the vehicle turns it
    // into a heading from true north (meridian convergence, or a rotated raster).
    f.heading_deg = WrapDeg360(pose.attitude.yaw_deg + RasterUpBearingDeg(raster, pose.nadir_px));

    // What locate is given.
    const double offset = o.prior_offset_m * std::sqrt(u01(rng));
    f.prior = geo::GeodesicDirect(f.latlon, uniform(0, 360), offset);
    f.prior_radius_m = o.prior_radius_m;
    f.given_heading_deg = WrapDeg360(f.heading_deg + sym(o.heading_error_deg));
    f.heading_sigma_deg = o.heading_error_deg;
    f.given_altitude_m = pose.altitude_m * (1 + sym(o.altitude_error_rel));
    f.given_roll_deg = pose.attitude.roll_deg + sym(o.attitude_error_deg);
    f.given_pitch_deg = pose.attitude.pitch_deg + sym(o.attitude_error_deg);
    frames.push_back(std::move(f));
  }
  return frames;
}

}  // namespace optinav::maploc
