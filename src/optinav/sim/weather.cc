#include "optinav/sim/weather.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "optinav/sim/internal/hash.h"
#include "optinav/sim/internal/texture.h"
#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

struct KindName {
  WeatherKind kind;
  const char* name;
};
constexpr KindName kKinds[] = {{WeatherKind::kNone, "none"},
                               {WeatherKind::kRain, "rain"},
                               {WeatherKind::kSnow, "snow"},
                               {WeatherKind::kLeaves, "leaves"},
                               {WeatherKind::kFog, "fog"},
                               {WeatherKind::kDust, "dust"},
                               {WeatherKind::kRoadWetness, "road-wetness"},
                               {WeatherKind::kRoadSnow, "road-snow"},
                               {WeatherKind::kRoadLeaves, "road-leaves"}};

using internal::SplitMix;

// A tiny deterministic generator seeded from a hash (std::mt19937 is too slow to seed per cell).
struct HashRng {
  uint64_t s;
  double Uniform() { return (SplitMix(s++) >> 11) * (1.0 / 9007199254740992.0); }
  // Poisson by inversion; exp_minus_mean = exp(-mean), fine for the small means used here.
  int Poisson(double exp_minus_mean) {
    const double l = exp_minus_mean;
    double p = Uniform();
    int k = 0;
    while (p > l && k < 1000) {
      p *= Uniform();
      ++k;
    }
    return k;
  }
};

enum class Shape { kDisc, kStreak, kLeaf };

struct ParticleModel {
  Shape shape;
  double density;  // per m^3 at 100 %
  double cell_m, reach_m;
  Eigen::Vector3d velocity;  // m/s (world; z up)
  double sway_m, sway_hz;
  double radius_min, radius_max;  // m
  double alpha;
  cv::Vec3f colours[4];
  double exposure_s;  // streak length = |velocity| * exposure
};

const ParticleModel* ModelFor(WeatherKind kind) {
  static const ParticleModel kRain{
      Shape::kStreak,
      0.8,
      2,
      10,
      {0.8, 0.3, -7.5},
      0,
      0,
      0.0007,
      0.0012,
      0.32,
      {{210, 210, 205}, {200, 200, 200}, {220, 220, 215}, {190, 195, 195}},
      1.0 / 60};
  static const ParticleModel kSnow{
      Shape::kDisc,
      2.0,
      2,
      12,
      {0.6, 0.2, -1.0},
      0.3,
      0.4,
      0.008,
      0.016,
      0.9,
      {{250, 250, 250}, {240, 242, 245}, {235, 238, 240}, {255, 255, 255}},
      0};
  static const ParticleModel kLeaves{Shape::kLeaf,
                                     0.25,
                                     4,
                                     20,
                                     {0.8, 0.4, -1.2},
                                     0.6,
                                     0.3,
                                     0.05,
                                     0.09,
                                     0.95,
                                     {{20, 90, 200}, {15, 50, 160}, {30, 140, 220}, {25, 60, 110}},
                                     0};
  static const ParticleModel kDust{
      Shape::kDisc,
      4.0,
      1.5,
      6,
      {6.0, 2.0, -0.2},
      0.1,
      1.0,
      0.001,
      0.0025,
      0.6,
      {{90, 140, 185}, {80, 125, 170}, {100, 150, 190}, {70, 110, 150}},
      0};
  switch (kind) {
    case WeatherKind::kRain:
      return &kRain;
    case WeatherKind::kSnow:
      return &kSnow;
    case WeatherKind::kLeaves:
      return &kLeaves;
    case WeatherKind::kDust:
      return &kDust;
    default:
      return nullptr;
  }
}

// On an 8-bit image (rounded) or on the unrounded light of a CV_32FC3 one.
inline void BlendPixel(cv::Mat& img, int x, int y, const cv::Vec3f& colour, float a) {
  if (a <= 0) return;
  a = std::min(a, 1.0f);
  if (img.depth() == CV_32F) {
    auto& px = img.at<cv::Vec3f>(y, x);
    for (int c = 0; c < 3; ++c) px[c] = px[c] * (1 - a) + colour[c] * a;
    return;
  }
  auto& px = img.at<cv::Vec3b>(y, x);
  for (int c = 0; c < 3; ++c) {
    px[c] = static_cast<uint8_t>(std::lround(px[c] * (1 - a) + colour[c] * a));
  }
}

inline bool Occluded(const cv::Mat& depth, int x, int y, double z) {
  const float d = depth.at<float>(y, x);
  return d > 0 && std::isfinite(d) && d < z;
}

void DrawParticles(cv::Mat& bgr, const cv::Mat& depth, const camera::PinholeCamera& cam,
                   const Rigid3d& world_from_cam, double t_s, const ParticleModel& m,
                   double intensity, uint64_t seed, WeatherKind kind) {
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Eigen::Vector3d centre = world_from_cam.translation;
  // Particles live in a lattice frame that moves with their mean velocity.
  const Eigen::Vector3d offset = m.velocity * t_s;
  const Eigen::Vector3d c_lattice = centre - offset;
  const int reach_cells = static_cast<int>(std::ceil(m.reach_m / m.cell_m));
  const int64_t cx = static_cast<int64_t>(std::floor(c_lattice.x() / m.cell_m));
  const int64_t cy = static_cast<int64_t>(std::floor(c_lattice.y() / m.cell_m));
  const int64_t cz = static_cast<int64_t>(std::floor(c_lattice.z() / m.cell_m));
  const double mean = m.density * intensity * m.cell_m * m.cell_m * m.cell_m;
  const double f = 0.5 * (cam.fx + cam.fy);
  const int w = bgr.cols, h = bgr.rows;
  const double exp_minus_mean = std::exp(-mean);
  // Cells wholly behind the camera, outside the field of view or out of reach are skipped: the
  // half-angles of the view from the image border (distortion included), with a margin.
  double tan_x = 0, tan_y = 0;
  for (const Eigen::Vector2d& b :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(w - 1, 0), Eigen::Vector2d(0, h - 1),
        Eigen::Vector2d(w - 1, h - 1), Eigen::Vector2d((w - 1) / 2.0, 0),
        Eigen::Vector2d((w - 1) / 2.0, h - 1), Eigen::Vector2d(0, (h - 1) / 2.0),
        Eigen::Vector2d(w - 1, (h - 1) / 2.0)}) {
    const Eigen::Vector2d n = cam.PixelToNormalized(b);
    tan_x = std::max(tan_x, std::abs(n.x()));
    tan_y = std::max(tan_y, std::abs(n.y()));
  }
  tan_x *= 1.1;
  tan_y *= 1.1;
  const double cell_radius =
      0.87 * m.cell_m + m.sway_m + m.velocity.norm() * m.exposure_s + m.radius_max + 0.05;
  const Eigen::Matrix3d r_cw = cam_from_world.rotation.toRotationMatrix();
  auto cell_visible = [&](int64_t ix, int64_t iy, int64_t iz) {
    const Eigen::Vector3d centre_w =
        Eigen::Vector3d(ix + 0.5, iy + 0.5, iz + 0.5) * m.cell_m + offset - centre;
    if (centre_w.norm() > m.reach_m + cell_radius) return false;
    const Eigen::Vector3d pc = r_cw * centre_w;
    if (pc.z() < -cell_radius) return false;
    if (std::abs(pc.x()) - tan_x * pc.z() > cell_radius * std::sqrt(1 + tan_x * tan_x))
      return false;
    if (std::abs(pc.y()) - tan_y * pc.z() > cell_radius * std::sqrt(1 + tan_y * tan_y))
      return false;
    return true;
  };
  for (int64_t ix = cx - reach_cells; ix <= cx + reach_cells; ++ix) {
    for (int64_t iy = cy - reach_cells; iy <= cy + reach_cells; ++iy) {
      for (int64_t iz = cz - reach_cells; iz <= cz + reach_cells; ++iz) {
        if (!cell_visible(ix, iy, iz)) continue;
        HashRng rng{
            SplitMix(SplitMix(SplitMix(static_cast<uint64_t>(ix) ^ (seed * 0x2545F4914F6CDD1Dull)) +
                              static_cast<uint64_t>(iy)) +
                     static_cast<uint64_t>(iz) * 0x9E3779B1ull + static_cast<uint64_t>(kind))};
        const int count = rng.Poisson(exp_minus_mean);
        for (int k = 0; k < count; ++k) {
          const Eigen::Vector3d q((ix + rng.Uniform()) * m.cell_m, (iy + rng.Uniform()) * m.cell_m,
                                  (iz + rng.Uniform()) * m.cell_m);
          const double phase = 2 * M_PI * rng.Uniform();
          const double radius = m.radius_min + (m.radius_max - m.radius_min) * rng.Uniform();
          const cv::Vec3f colour = m.colours[static_cast<int>(rng.Uniform() * 4) & 3];
          const double tumble_rate = 0.5 + 1.5 * rng.Uniform();
          // An explicit return type: `auto` would return an Eigen expression that refers to the
          // temporary Vector3d below after it died (found by AddressSanitizer).
          auto position = [&](double t) -> Eigen::Vector3d {
            const double a = 2 * M_PI * m.sway_hz * t + phase;
            return q + m.velocity * t +
                   m.sway_m * Eigen::Vector3d(std::sin(a), std::cos(1.3 * a), 0);
          };
          const Eigen::Vector3d p_world = position(t_s);
          if ((p_world - centre).squaredNorm() > m.reach_m * m.reach_m) continue;
          const Eigen::Vector3d p = cam_from_world * p_world;
          if (p.z() < 0.15) continue;
          const auto px = cam.Project(p);
          if (!px) continue;
          const double r_px = f * radius / p.z();
          if (px->x() < -r_px - 2 || px->y() < -r_px - 2 || px->x() > w + r_px + 1 ||
              px->y() > h + r_px + 1) {
            continue;
          }
          // Very close particles are out of focus: fainter.
          const double near_fade = std::min(1.0, p.z() / 0.6);
          if (m.shape == Shape::kStreak) {
            const Eigen::Vector3d p2 = cam_from_world * position(t_s - m.exposure_s);
            if (p2.z() < 0.15) continue;
            const auto px2 = cam.Project(p2);
            if (!px2) continue;
            const Eigen::Vector2d d = *px2 - *px;
            const int steps = std::max(1, static_cast<int>(std::ceil(d.cwiseAbs().maxCoeff())));
            const float a = static_cast<float>(m.alpha * near_fade * std::min(1.0, 0.5 + r_px));
            for (int s = 0; s <= steps; ++s) {
              const Eigen::Vector2d at = *px + d * (static_cast<double>(s) / steps);
              const int x = static_cast<int>(std::lround(at.x())),
                        y = static_cast<int>(std::lround(at.y()));
              if (x < 0 || y < 0 || x >= w || y >= h || Occluded(depth, x, y, p.z())) continue;
              BlendPixel(bgr, x, y, colour, a);
            }
            continue;
          }
          const int x0 = static_cast<int>(std::lround(px->x())),
                    y0 = static_cast<int>(std::lround(px->y()));
          if (x0 >= 0 && y0 >= 0 && x0 < w && y0 < h && Occluded(depth, x0, y0, p.z())) continue;
          double ra = std::max(r_px, 0.5), rb = ra, ang = 0;
          double alpha = m.alpha * near_fade;
          if (r_px < 0.5) alpha *= (r_px / 0.5) * (r_px / 0.5);
          if (m.shape == Shape::kLeaf) {
            const double tumble = std::cos(2 * M_PI * tumble_rate * t_s + phase);
            rb = std::max(0.5, ra * (0.25 + 0.6 * std::abs(tumble)));
            ang = phase + 0.7 * std::sin(2 * M_PI * 0.2 * t_s + phase);
          }
          ra = std::min(ra, 60.0);
          rb = std::min(rb, 60.0);
          const double ca = std::cos(ang), sa = std::sin(ang);
          const int reach = static_cast<int>(std::ceil(ra)) + 1;
          for (int y = std::max(0, y0 - reach); y <= std::min(h - 1, y0 + reach); ++y) {
            for (int x = std::max(0, x0 - reach); x <= std::min(w - 1, x0 + reach); ++x) {
              const double dx = x - px->x(), dy = y - px->y();
              const double u = (ca * dx + sa * dy) / ra, v = (-sa * dx + ca * dy) / rb;
              const double r = std::sqrt(u * u + v * v);
              // Soft edge about one pixel wide.
              const double cover = std::clamp((1.0 - r) * std::min(ra, rb) + 0.5, 0.0, 1.0);
              if (cover <= 0) continue;
              BlendPixel(bgr, x, y, colour, static_cast<float>(alpha * cover));
            }
          }
        }
      }
    }
  }
}

struct Haze {
  double visibility_m;     // +inf: none
  cv::Vec3i airlight_int;  // BGR
  double contrast_loss;    // extra blend towards the airlight, [0, 1)
  double dimming;          // multiplies the image (overcast), [0, 1)
};

Haze HazeFor(const WeatherSpec& s) {
  const double i = std::clamp(s.intensity, 0.0, 1.0), k = s.distance_scale;
  const double inf = std::numeric_limits<double>::infinity();
  switch (s.kind) {
    case WeatherKind::kFog:
      return {k * 40 * std::pow(25.0, 1 - i), {205, 205, 200}, 0, 0};
    case WeatherKind::kDust:
      return {k * 30 * std::pow(20.0, 1 - i), {95, 150, 195}, 0.3 * i, 0};
    case WeatherKind::kRain:
      return {k * 2000 * std::pow(0.15, i), {190, 185, 180}, 0, 0.15 * i};
    case WeatherKind::kSnow:
      return {k * 1500 * std::pow(0.1, i), {235, 232, 230}, 0, 0};
    default:
      return {inf, {0, 0, 0}, 0, 0};
  }
}

void ApplyHaze(cv::Mat& bgr, const cv::Mat& depth, const camera::PinholeCamera& cam,
               const Haze& hz) {
  const bool has_fog = std::isfinite(hz.visibility_m);
  const float beta = has_fog ? static_cast<float>(3.912 / hz.visibility_m) : 0.0f;
  const float loss = static_cast<float>(hz.contrast_loss);
  const int dim = static_cast<int>(std::lround(256 * (1 - hz.dimming)));  // 8.8 fixed point
  const float dimf = static_cast<float>(1 - hz.dimming);
  // Squared normalised x of every column: the ray length is sqrt(1 + xn^2 + yn^2) times the
  // depth along the optical axis.
  std::vector<float> xn2(bgr.cols);
  for (int x = 0; x < bgr.cols; ++x) {
    const float xn = static_cast<float>((x - cam.cx) / cam.fx);
    xn2[x] = xn * xn;
  }
  cv::parallel_for_(cv::Range(0, bgr.rows), [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      const bool is_float = bgr.depth() == CV_32F;
      auto* row = is_float ? nullptr : bgr.ptr<uint8_t>(y);
      float* light = is_float ? bgr.ptr<float>(y) : nullptr;
      const float* drow = depth.ptr<float>(y);
      const float yn = static_cast<float>((y - cam.cy) / cam.fy);
      const float one_yn2 = 1 + yn * yn;
      for (int x = 0; x < bgr.cols; ++x) {
        const float z = drow[x];
        float tau = 1.0f;
        if (has_fog) {
          tau = (z > 0 && z < 1e30f) ? std::exp(-beta * z * std::sqrt(one_yn2 + xn2[x])) : 0.0f;
        }
        if (light) {  // unrounded: the camera's noise and rounding come later
          const float keep = tau * (1 - loss);
          float* p = light + 3 * x;
          for (int c = 0; c < 3; ++c) {
            p[c] = p[c] * dimf * keep + static_cast<float>(hz.airlight_int[c]) * (1 - keep);
          }
          continue;
        }
        // Fraction of the scene kept, 0..256 (8-bit blending is all an 8-bit image needs).
        const int keep = static_cast<int>(tau * (1 - loss) * 256 + 0.5f);
        uint8_t* p = row + 3 * x;
        for (int c = 0; c < 3; ++c) {
          const int scene = (p[c] * dim) >> 8;
          p[c] =
              static_cast<uint8_t>((scene * keep + hz.airlight_int[c] * (256 - keep) + 128) >> 8);
        }
      }
    }
  });
}

cv::Mat Fractal(int size, uint64_t seed) { return FractalNoise(size, seed, 4); }

}  // namespace

bool WeatherSpec::HasParticles() const { return !IsClear() && ModelFor(kind) != nullptr; }
bool WeatherSpec::HasHaze() const {
  return !IsClear() && std::isfinite(HazeFor(*this).visibility_m);
}

std::string WeatherKindName(WeatherKind kind) {
  for (const KindName& k : kKinds) {
    if (k.kind == kind) return k.name;
  }
  return "?";
}

std::string WeatherSpec::ToString() const {
  if (kind == WeatherKind::kNone) return "none";
  return fmt::format("{}:{}", WeatherKindName(kind),
                     static_cast<int>(std::lround(intensity * 100)));
}

WeatherSpec ParseWeather(const std::string& text) {
  const size_t colon = text.find(':');
  const std::string name = text.substr(0, colon);
  WeatherSpec spec;
  bool found = false;
  for (const KindName& k : kKinds) {
    if (name == k.name) {
      spec.kind = k.kind;
      found = true;
    }
  }
  if (!found) {
    std::string valid;
    for (const KindName& k : kKinds) valid += (valid.empty() ? "" : ", ") + std::string(k.name);
    throw Error(fmt::format("unknown weather '{}' (one of: {}; optionally :PERCENT)", name, valid),
                {.field = "weather"});
  }
  if (spec.kind == WeatherKind::kNone) {
    if (colon != std::string::npos) throw Error("'none' takes no intensity", {.field = "weather"});
    return spec;
  }
  double percent = 50;
  if (colon != std::string::npos) {
    const std::string num = text.substr(colon + 1);
    size_t used = 0;
    try {
      percent = std::stod(num, &used);
    } catch (const std::logic_error&) {
      used = 0;
    }
    if (num.empty() || used != num.size() || !std::isfinite(percent)) {
      throw Error(fmt::format("weather intensity '{}' is not a number (percent, 0-100)", num),
                  {.field = "weather"});
    }
    if (percent < 0 || percent > 100) {
      throw Error(fmt::format("weather intensity {} % is outside 0-100", num),
                  {.field = "weather"});
    }
  }
  spec.intensity = percent / 100.0;
  return spec;
}

double WeatherVisibilityM(const WeatherSpec& spec) {
  if (spec.IsClear()) return std::numeric_limits<double>::infinity();
  return HazeFor(spec).visibility_m;
}

namespace {

void CheckInputs(const cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera) {
  if ((bgr.type() != CV_8UC3 && bgr.type() != CV_32FC3) || depth_m.type() != CV_32F ||
      bgr.size() != depth_m.size()) {
    throw Error(
        fmt::format("weather needs a CV_8UC3 (or CV_32FC3) image and a CV_32F depth of the same "
                    "size (got {}x{} type {}, {}x{} type {})",
                    bgr.cols, bgr.rows, bgr.type(), depth_m.cols, depth_m.rows, depth_m.type()),
        {.field = "weather"});
  }
  if (bgr.cols != camera.width || bgr.rows != camera.height) {
    throw Error(fmt::format("image {}x{} does not match the camera {}x{}", bgr.cols, bgr.rows,
                            camera.width, camera.height),
                {.field = "weather"});
  }
}

}  // namespace

void ApplyWeatherHaze(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                      const WeatherSpec& spec) {
  CheckInputs(bgr, depth_m, camera);
  if (spec.IsClear()) return;
  const Haze hz = HazeFor(spec);
  if (std::isfinite(hz.visibility_m) || hz.contrast_loss > 0 || hz.dimming > 0) {
    ApplyHaze(bgr, depth_m, camera, hz);
  }
}

void DrawWeatherParticles(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                          const Rigid3d& world_from_cam, int64_t t_ns, const WeatherSpec& spec,
                          uint64_t seed) {
  CheckInputs(bgr, depth_m, camera);
  if (spec.IsClear()) return;
  if (const ParticleModel* m = ModelFor(spec.kind)) {
    DrawParticles(bgr, depth_m, camera, world_from_cam, spec.particles_still ? 0.0 : t_ns * 1e-9,
                  *m, std::clamp(spec.intensity, 0.0, 1.0), seed, spec.kind);
  }
}

void ApplyWeather(cv::Mat& bgr, const cv::Mat& depth_m, const camera::PinholeCamera& camera,
                  const Rigid3d& world_from_cam, int64_t t_ns, const WeatherSpec& spec,
                  uint64_t seed) {
  ApplyWeatherHaze(bgr, depth_m, camera, spec);
  DrawWeatherParticles(bgr, depth_m, camera, world_from_cam, t_ns, spec, seed);
}

void ApplySurfaceWeather(cv::Mat& tex, SurfaceRole role, const WeatherSpec& spec, uint64_t seed) {
  OPTINAV_CHECK(tex.type() == CV_8UC3 && tex.rows == tex.cols);
  if (spec.IsClear()) return;
  const double i = std::clamp(spec.intensity, 0.0, 1.0);
  const bool road = role == SurfaceRole::kRoad, ground = role == SurfaceRole::kGround;
  const WeatherKind k = spec.kind;
  const int n = tex.rows;
  if ((k == WeatherKind::kRain && (road || ground)) || (k == WeatherKind::kRoadWetness && road)) {
    // Wet surfaces are darker and more saturated; on roads, puddles are darker still, smooth,
    // and mirror a little of the sky.
    const cv::Mat puddles = Fractal(n, seed + 11);
    const double dark = (road ? 0.45 : 0.3) * i;
    cv::Mat smooth;
    cv::GaussianBlur(tex, smooth, {0, 0}, 3, 3, cv::BORDER_WRAP);
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        auto& px = tex.at<cv::Vec3b>(y, x);
        const float p =
            road ? std::clamp((puddles.at<float>(y, x) - (1.0f - 0.45f * float(i))) * 8.0f, 0.0f,
                              1.0f)
                 : 0.0f;
        const cv::Vec3b sm = smooth.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) {
          const double wet = px[c] * (1 - dark);
          const double puddle = sm[c] * 0.45 + (c == 0 ? 150 : 120) * 0.25;
          px[c] = cv::saturate_cast<uint8_t>(wet * (1 - p) + puddle * p);
        }
      }
    }
  } else if ((k == WeatherKind::kSnow && (road || ground || role == SurfaceRole::kRoof)) ||
             (k == WeatherKind::kRoadSnow && road)) {
    const cv::Mat cover = Fractal(n, seed + 23);
    const cv::Mat snow = MakeSurfaceImage(SurfaceKind::kSnowGround, seed + 5);
    cv::Mat snow_n;
    cv::resize(snow, snow_n, tex.size(), 0, 0, cv::INTER_AREA);
    // Coverage: the fraction of the surface under snow grows with the intensity.
    const float level = static_cast<float>(1.15 * i);
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const float a = std::clamp((level - cover.at<float>(y, x)) * 6.0f, 0.0f, 1.0f);
        auto& px = tex.at<cv::Vec3b>(y, x);
        const cv::Vec3b s = snow_n.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) px[c] = cv::saturate_cast<uint8_t>(px[c] * (1 - a) + s[c] * a);
      }
    }
  } else if ((k == WeatherKind::kLeaves && (road || ground)) ||
             (k == WeatherKind::kRoadLeaves && road)) {
    std::mt19937_64 rng(seed + 31);
    std::uniform_real_distribution<double> u(0, 1);
    const cv::Scalar palette[] = {
        {20, 90, 200}, {15, 50, 160}, {30, 140, 220}, {25, 60, 110}, {40, 120, 170}};
    const int count = static_cast<int>(900 * i * (n / 512.0) * (n / 512.0));
    for (int l = 0; l < count; ++l) {
      const cv::Point2d c(u(rng) * n, u(rng) * n);
      const cv::Size axes(static_cast<int>(4 + 6 * u(rng)), static_cast<int>(2 + 3 * u(rng)));
      const double ang = 180 * u(rng);
      cv::Scalar col = palette[static_cast<int>(u(rng) * 5) % 5];
      col *= 0.8 + 0.4 * u(rng);
      for (int oy : {-n, 0, n}) {
        for (int ox : {-n, 0, n}) {
          const cv::Point p(static_cast<int>(c.x) + ox, static_cast<int>(c.y) + oy);
          cv::ellipse(tex, p, axes, ang, 0, 360, col, cv::FILLED, cv::LINE_AA);
          cv::ellipse(tex, p, axes, ang, 0, 360, col * 0.6, 1, cv::LINE_AA);
        }
      }
    }
  }
}

}  // namespace optinav::sim
