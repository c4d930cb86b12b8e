#include "optinav/nav/frame_effects.h"

#include <cmath>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "optinav/camera/camera.h"
#include "optinav/geometry/lie.h"
#include "optinav/maploc/aerial_camera.h"

namespace optinav::nav {

std::string FrameEffectOptions::Check() const {
  auto bad = [](const char* name, double v, const char* range) {
    return fmt::format("{} must be in {}, got {}", name, range, v);
  };
  if (!(altitude_variation >= 0 && altitude_variation <= 0.3)) {
    return bad("altitude variation", altitude_variation, "[0, 0.3]");
  }
  if (!(max_tilt_deg >= 0 && max_tilt_deg <= 20))
    return bad("max tilt", max_tilt_deg, "[0, 20] deg");
  if (!(yaw_jitter_deg >= 0 && yaw_jitter_deg <= 20)) {
    return bad("yaw jitter", yaw_jitter_deg, "[0, 20] deg");
  }
  if (!(motion_blur_px >= 0 && motion_blur_px <= 30)) {
    return bad("motion blur", motion_blur_px, "[0, 30] px");
  }
  if (!(exposure_variation >= 0 && exposure_variation <= 0.8)) {
    return bad("exposure variation", exposure_variation, "[0, 0.8]");
  }
  if (!(noise_sigma >= 0 && noise_sigma <= 50)) return bad("noise sigma", noise_sigma, "[0, 50]");
  return "";
}

AltitudeProfile::AltitudeProfile(double variation, uint64_t seed) : variation_(variation) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    amp_[i] = 0.3 + u(rng);
    freq_[i] = 2 * M_PI / (40 + 200 * u(rng));  // periods of 40-240 s
    phase_[i] = 2 * M_PI * u(rng);
    sum += amp_[i];
  }
  for (double& a : amp_) a /= sum;  // |sum of sinusoids| <= 1
}

double AltitudeProfile::Factor(double t_s) const {
  double v = 0;
  for (int i = 0; i < 3; ++i) v += amp_[i] * std::sin(freq_[i] * t_s + phase_[i]);
  return 1.0 + variation_ * v;
}

void ApplyPhotometricEffects(cv::Mat& gray, const FrameEffectOptions& o, double direction_rad,
                             std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const double blur = o.motion_blur_px * u(rng);
  const double gain = 1.0 + o.exposure_variation * (2 * u(rng) - 1);
  const double gamma = 1.0 + 0.5 * o.exposure_variation * (2 * u(rng) - 1);
  if (blur >= 1.0) {
    // Line kernel of length `blur` along the flight direction (frame up rotated clockwise).
    const int k = 2 * static_cast<int>(std::ceil(blur / 2)) + 1;
    cv::Mat kernel = cv::Mat::zeros(k, k, CV_32F);
    const cv::Point2d d(std::sin(direction_rad), -std::cos(direction_rad));
    const cv::Point2d c(k / 2, k / 2);
    cv::line(kernel, c - d * (blur / 2), c + d * (blur / 2), cv::Scalar(1.0), 1, cv::LINE_AA);
    kernel /= cv::sum(kernel)[0];
    cv::filter2D(gray, gray, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
  }
  if (gain != 1.0 || gamma != 1.0) {
    cv::Mat lut(1, 256, CV_8U);
    for (int i = 0; i < 256; ++i) {
      lut.at<uint8_t>(i) = cv::saturate_cast<uint8_t>(255.0 * gain * std::pow(i / 255.0, gamma));
    }
    lut.at<uint8_t>(0) = 0;  // keep "outside the map" black
    cv::LUT(gray, lut, gray);
  }
  if (o.noise_sigma > 0) {
    cv::Mat noise(gray.size(), CV_16S);
    cv::RNG cvrng(rng());
    cvrng.fill(noise, cv::RNG::NORMAL, 0, o.noise_sigma);
    cv::Mat g16;
    gray.convertTo(g16, CV_16S);
    g16 += noise;
    g16.convertTo(gray, CV_8U);
  }
}

FrameHook MakeWeatherHook(sim::WeatherSpec spec, uint64_t seed) {
  if (spec.IsClear()) return {};
  return [spec, seed](cv::Mat& gray, const FrameView& v) {
    camera::PinholeCamera cam;
    cam.width = v.width;
    cam.height = v.height;
    cam.fx = cam.fy = v.focal_px;
    cam.cx = 0.5 * v.width - 0.5;
    cam.cy = 0.5 * v.height - 0.5;
    // The mapping camera of a vehicle with this attitude, in ENU (z up).
    Eigen::Matrix3d enu_from_ned;
    enu_from_ned << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    const Eigen::Matrix3d enu_from_cam =
        enu_from_ned *
        maploc::NedFromBody(
            {.roll_deg = v.roll_deg, .pitch_deg = v.pitch_deg, .yaw_deg = v.heading_deg}) *
        maploc::BodyFromCamera();
    Rigid3d world_from_cam;
    world_from_cam.rotation = Eigen::Quaterniond(enu_from_cam);
    world_from_cam.translation = v.position_enu;
    // The ray (xn, yn, 1) reaches the ground at depth altitude / down, where down, the ray's
    // downward world component, is linear in xn and yn: -(R.row(2) . ray).
    const Eigen::Vector3d up_row = world_from_cam.rotation.toRotationMatrix().row(2);
    const double altitude = v.position_enu.z();
    cv::Mat depth(gray.size(), CV_32F);
    for (int y = 0; y < depth.rows; ++y) {
      float* row = depth.ptr<float>(y);
      const double down_y = -(up_row.y() * (y - cam.cy) / cam.fy + up_row.z());
      for (int x = 0; x < depth.cols; ++x) {
        const double down = down_y - up_row.x() * (x - cam.cx) / cam.fx;
        row[x] = down > 1e-6 ? static_cast<float>(altitude / down) : 0.0f;  // 0: sky
      }
    }
    sim::WeatherSpec s = spec;
    if (s.distance_scale <= 0) s.distance_scale = altitude / 50.0;
    cv::Mat bgr;
    cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
    sim::ApplyWeather(bgr, depth, cam, world_from_cam, v.t_ns, s, seed);
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  };
}

}  // namespace optinav::nav
