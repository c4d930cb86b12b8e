#include "optinav/sim/camera_noise.h"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "optinav/sim/internal/hash.h"
#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

using internal::SplitMix;

// One standard normal sample from a 64-bit hash (Box-Muller on its two 32-bit halves).
float NormalFromHash(uint64_t h) {
  const double u1 = (static_cast<double>(h >> 32) + 0.5) * (1.0 / 4294967296.0);
  const double u2 = static_cast<double>(h & 0xffffffffull) * (1.0 / 4294967296.0);
  return static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2));
}

}  // namespace

std::string CameraNoiseOptions::Check() const {
  if (!enabled) return "";
  if (!(read_sigma >= 0 && read_sigma <= 20)) {
    return fmt::format("camera noise: read sigma {} not in [0, 20] grey levels", read_sigma);
  }
  if (!(shot_variance >= 0 && shot_variance <= 2)) {
    return fmt::format("camera noise: shot variance {} not in [0, 2] grey levels per level",
                       shot_variance);
  }
  return "";
}

std::string CameraNoiseOptions::ToString() const {
  return enabled ? fmt::format("{}:{}", read_sigma, shot_variance) : "off";
}

double CameraNoiseOptions::SigmaAt(double grey) const {
  if (!enabled) return 0;
  return std::sqrt(read_sigma * read_sigma + shot_variance * std::max(grey, 0.0));
}

CameraNoiseOptions ParseCameraNoise(const std::string& text, const std::string& field) {
  CameraNoiseOptions o;
  if (text == "on") return o;
  if (text == "off") {
    o.enabled = false;
    return o;
  }
  const size_t colon = text.find(':');
  auto number = [&](const std::string& s, double* v) {
    size_t used = 0;
    try {
      *v = std::stod(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    return used > 0 && used == s.size() && std::isfinite(*v);
  };
  if (colon == std::string::npos || !number(text.substr(0, colon), &o.read_sigma) ||
      !number(text.substr(colon + 1), &o.shot_variance)) {
    throw Error(fmt::format("'{}' is not on, off or READ:SHOT (e.g. 0.8:0.02)", text),
                {.field = field});
  }
  if (const std::string m = o.Check(); !m.empty()) throw Error(m, {.field = field});
  return o;
}

uint64_t CameraNoiseStream(uint64_t seed, int64_t t_ns, int camera) {
  return SplitMix(SplitMix(SplitMix(seed ^ 0x6e6f697365ull) ^ static_cast<uint64_t>(t_ns)) ^
                  static_cast<uint64_t>(camera));
}

cv::Mat ExposeToEightBits(const cv::Mat& light, const CameraNoiseOptions& noise, uint64_t stream) {
  if (light.type() != CV_32FC3) {
    throw Error(fmt::format("camera noise needs a CV_32FC3 image (got type {})", light.type()));
  }
  cv::Mat out;
  if (!noise.enabled) {  // the rounding alone (convertTo saturates and rounds as below)
    light.convertTo(out, CV_8UC3);
    return out;
  }
  out.create(light.size(), CV_8UC3);
  const float read2 = static_cast<float>(noise.read_sigma * noise.read_sigma);
  const float shot = static_cast<float>(noise.shot_variance);
  cv::parallel_for_(cv::Range(0, light.rows), [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      const float* in = light.ptr<float>(y);
      uint8_t* o = out.ptr<uint8_t>(y);
      for (int x = 0; x < light.cols; ++x) {
        const float n =
            NormalFromHash(SplitMix(stream ^ (static_cast<uint64_t>(y) * light.cols + x)));
        for (int c = 0; c < 3; ++c) {
          const float v = in[3 * x + c];
          const float sigma = std::sqrt(read2 + shot * std::max(v, 0.0f));
          o[3 * x + c] = cv::saturate_cast<uint8_t>(v + sigma * n);
        }
      }
    }
  });
  return out;
}

}  // namespace optinav::sim
