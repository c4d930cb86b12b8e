#include "optinav/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/format.h>
#include <opencv2/core/parallel/parallel_backend.hpp>
#include <opencv2/imgproc.hpp>

#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

constexpr float kNear = 0.05f;  // m
constexpr int kBandRows = 8;

struct ClipVertex {
  Eigen::Vector3f p;  // camera frame
  Eigen::Vector2f uv;
};

// One screen-space triangle ready for scan conversion.
struct Setup {
  // Plane equations a + bx * x + by * y of 1/z, u/z and v/z.
  double w0, wx, wy, u0, ux, uy, v0, vx, vy;
  // Edge functions: inside when e0 + ex * x + ey * y >= 0 for all three.
  double e0[3], ex[3], ey[3];
  int ymin, ymax, xmin, xmax;
  float tint[3];
  const Texture* texture;
  float tex_size;
};

inline float FastLog2(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, 4);
  return static_cast<float>(bits) * 1.1920928955e-7f - 126.94269504f;
}

// Clips a polygon against z >= kNear (Sutherland-Hodgman on one plane).
int ClipNear(const ClipVertex* in, int n, ClipVertex* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const ClipVertex& a = in[i];
    const ClipVertex& b = in[(i + 1) % n];
    const bool ain = a.p.z() >= kNear, bin = b.p.z() >= kNear;
    if (ain) out[m++] = a;
    if (ain != bin) {
      const float t = (kNear - a.p.z()) / (b.p.z() - a.p.z());
      out[m++] = {a.p + t * (b.p - a.p), a.uv + t * (b.uv - a.uv)};
    }
  }
  return m;
}

bool MakeSetup(const ClipVertex& a, const ClipVertex& b, const ClipVertex& c, double fx, double fy,
               double cx, double cy, int width, int height, Setup* s) {
  double x[3], y[3], w[3], u[3], v[3];
  const ClipVertex* vs[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    w[i] = 1.0 / vs[i]->p.z();
    x[i] = fx * vs[i]->p.x() * w[i] + cx;
    y[i] = fy * vs[i]->p.y() * w[i] + cy;
    u[i] = vs[i]->uv.x() * w[i];
    v[i] = vs[i]->uv.y() * w[i];
  }
  const double d = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
  if (std::abs(d) < 1e-9) return false;
  s->xmin = std::max(0, static_cast<int>(std::ceil(std::min({x[0], x[1], x[2]}))));
  s->xmax = std::min(width - 1, static_cast<int>(std::floor(std::max({x[0], x[1], x[2]}))));
  s->ymin = std::max(0, static_cast<int>(std::ceil(std::min({y[0], y[1], y[2]}))));
  s->ymax = std::min(height - 1, static_cast<int>(std::floor(std::max({y[0], y[1], y[2]}))));
  if (s->xmin > s->xmax || s->ymin > s->ymax) return false;
  auto plane = [&](const double* f, double* f0, double* fxo, double* fyo) {
    *fxo = ((f[1] - f[0]) * (y[2] - y[0]) - (f[2] - f[0]) * (y[1] - y[0])) / d;
    *fyo = ((f[2] - f[0]) * (x[1] - x[0]) - (f[1] - f[0]) * (x[2] - x[0])) / d;
    *f0 = f[0] - *fxo * x[0] - *fyo * y[0];
  };
  plane(w, &s->w0, &s->wx, &s->wy);
  plane(u, &s->u0, &s->ux, &s->uy);
  plane(v, &s->v0, &s->vx, &s->vy);
  const double sign = d > 0 ? 1.0 : -1.0;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    // E(x, y) = (x - xi)(yj - yi) - (y - yi)(xj - xi), positive inside for d > 0.
    s->ex[i] = -sign * (y[j] - y[i]);
    s->ey[i] = sign * (x[j] - x[i]);
    s->e0[i] = -(s->ex[i] * x[i] + s->ey[i] * y[i]);
  }
  return true;
}

}  // namespace

void Renderer::RenderPinhole(const Pinhole& cam, const Rigid3d& cam_from_world, cv::Mat* bgr,
                             cv::Mat* inv_depth) const {
  const int width = cam.width, height = cam.height;
  bgr->create(height, width, CV_8UC3);
  inv_depth->create(height, width, CV_32F);
  const Eigen::Matrix3f r = cam_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = cam_from_world.translation.cast<float>();
  const Eigen::Vector3f centre = -(r.transpose() * t);  // camera centre in the world

  // Frustum planes in the camera frame: n . p <= 0 inside.
  const Eigen::Vector3f planes[5] = {
      {static_cast<float>(-cam.fx), 0, static_cast<float>(-(cam.cx + 1))},
      {static_cast<float>(cam.fx), 0, static_cast<float>(cam.cx - width)},
      {0, static_cast<float>(-cam.fy), static_cast<float>(-(cam.cy + 1))},
      {0, static_cast<float>(cam.fy), static_cast<float>(cam.cy - height)},
      {0, 0, -1}};
  const float plane_offset[5] = {0, 0, 0, 0, kNear};

  std::vector<Setup> setups;
  setups.reserve(20000);
  // Chunks front to back: the depth test then rejects most hidden pixels before they are
  // textured. The order depends on the pose only, so the output stays deterministic.
  std::vector<std::pair<float, const WorldChunk*>> order;
  order.reserve(world_.chunks.size());
  for (const WorldChunk& chunk : world_.chunks) {
    order.emplace_back(chunk.box.exteriorDistance(centre), &chunk);
  }
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [distance, chunk_ptr] : order) {
    const WorldChunk& chunk = *chunk_ptr;
    bool culled = false;
    for (int k = 0; k < 5 && !culled; ++k) {
      bool all_out = true;
      for (int corner = 0; corner < 8 && all_out; ++corner) {
        const Eigen::Vector3f p =
            r * chunk.box.corner(static_cast<Eigen::AlignedBox3f::CornerType>(corner)) + t;
        all_out = planes[k].dot(p) + plane_offset[k] > 0;
      }
      culled = all_out;
    }
    if (culled) continue;
    for (const WorldTriangle& tri : chunk.triangles) {
      if (!tri.two_sided) {
        const Eigen::Vector3f n = (tri.p[1] - tri.p[0]).cross(tri.p[2] - tri.p[0]);
        if (n.dot(centre - tri.p[0]) <= 0) continue;
      }
      ClipVertex in[3], clipped[4];
      int outside_near = 0;
      for (int i = 0; i < 3; ++i) {
        in[i] = {r * tri.p[i] + t, tri.uv[i]};
        outside_near += in[i].p.z() < kNear;
      }
      if (outside_near == 3) continue;
      bool out_side = false;
      for (int k = 0; k < 4 && !out_side; ++k) {
        out_side =
            planes[k].dot(in[0].p) > 0 && planes[k].dot(in[1].p) > 0 && planes[k].dot(in[2].p) > 0;
      }
      if (out_side) continue;
      const ClipVertex* poly = in;
      int n = 3;
      if (outside_near > 0) {
        n = ClipNear(in, 3, clipped);
        poly = clipped;
      }
      for (int i = 1; i + 1 < n; ++i) {
        Setup s;
        if (!MakeSetup(poly[0], poly[i], poly[i + 1], cam.fx, cam.fy, cam.cx, cam.cy, width, height,
                       &s)) {
          continue;
        }
        for (int c = 0; c < 3; ++c) s.tint[c] = tri.tint[c];
        s.texture = &world_.textures[tri.texture];
        s.tex_size = static_cast<float>(s.texture->size());
        setups.push_back(s);
      }
    }
  }
  // Bin by bands of rows; each bin keeps the scene order, so results do not depend on threads.
  const int bands = (height + kBandRows - 1) / kBandRows;
  std::vector<std::vector<uint32_t>> bins(bands);
  for (uint32_t i = 0; i < setups.size(); ++i) {
    for (int b = setups[i].ymin / kBandRows; b <= setups[i].ymax / kBandRows; ++b) {
      bins[b].push_back(i);
    }
  }
  // Sky: a gradient over the elevation of each pixel's ray.
  const Eigen::Matrix3f world_from_cam_r = r.transpose();
  const Eigen::Vector3f dx = world_from_cam_r.col(0) / static_cast<float>(cam.fx);
  const Eigen::Vector3f dy = world_from_cam_r.col(1) / static_cast<float>(cam.fy);
  const Eigen::Vector3f d0 =
      world_from_cam_r.col(2) - static_cast<float>(cam.cx) * dx - static_cast<float>(cam.cy) * dy;
  const Eigen::Vector3f sky_h = world_.sky_horizon, sky_z = world_.sky_zenith;

  cv::parallel_for_(cv::Range(0, bands), [&](const cv::Range& range) {
    for (int band = range.start; band < range.end; ++band) {
      const int y0 = band * kBandRows, y1 = std::min(height, y0 + kBandRows);
      for (int y = y0; y < y1; ++y) {
        std::fill_n(inv_depth->ptr<float>(y), width, 0.0f);
      }
      for (uint32_t idx : bins[band]) {
        const Setup& s = setups[idx];
        const int ya = std::max(s.ymin, y0), yb = std::min(s.ymax, y1 - 1);
        const float n2 = s.tex_size * s.tex_size;
        for (int y = ya; y <= yb; ++y) {
          // Span of x where all three edge functions are >= 0.
          double lo = s.xmin, hi = s.xmax;
          bool empty = false;
          for (int k = 0; k < 3; ++k) {
            const double base = s.e0[k] + s.ey[k] * y;
            if (s.ex[k] > 0) {
              lo = std::max(lo, -base / s.ex[k]);
            } else if (s.ex[k] < 0) {
              hi = std::min(hi, -base / s.ex[k]);
            } else if (base < 0) {
              empty = true;
            }
          }
          if (empty) continue;
          const int xa = static_cast<int>(std::ceil(lo)), xb = static_cast<int>(std::floor(hi));
          if (xa > xb) continue;
          auto* row = bgr->ptr<uint8_t>(y);
          auto* zrow = inv_depth->ptr<float>(y);
          double w = s.w0 + s.wx * xa + s.wy * y;
          double uw = s.u0 + s.ux * xa + s.uy * y;
          double vw = s.v0 + s.vx * xa + s.vy * y;
          for (int x = xa; x <= xb; ++x, w += s.wx, uw += s.ux, vw += s.vx) {
            if (w <= zrow[x]) continue;
            zrow[x] = static_cast<float>(w);
            const double z = 1.0 / w;
            const double u = uw * z, v = vw * z;
            // Texel footprint of the pixel: derivatives of u = U / W along x and y.
            const float dudx = static_cast<float>((s.ux - u * s.wx) * z);
            const float dvdx = static_cast<float>((s.vx - v * s.wx) * z);
            const float dudy = static_cast<float>((s.uy - u * s.wy) * z);
            const float dvdy = static_cast<float>((s.vy - v * s.wy) * z);
            const float rho2 = std::max(dudx * dudx + dvdx * dvdx, dudy * dudy + dvdy * dvdy) * n2;
            const float lod = rho2 > 1.0f ? 0.5f * FastLog2(rho2) : 0.0f;
            uint8_t texel[3];
            s.texture->Sample(u, v, lod, texel);
            for (int c = 0; c < 3; ++c) {
              const float value = texel[c] * s.tint[c];
              row[3 * x + c] = static_cast<uint8_t>(value >= 255.f ? 255.f : value);
            }
          }
        }
      }
      // Sky where no triangle was drawn.
      for (int y = y0; y < y1; ++y) {
        auto* row = bgr->ptr<uint8_t>(y);
        const float* zrow = inv_depth->ptr<float>(y);
        for (int x = 0; x < width; ++x) {
          if (zrow[x] > 0) continue;
          const Eigen::Vector3f d = d0 + static_cast<float>(x) * dx + static_cast<float>(y) * dy;
          const float e = std::clamp(d.z() / d.norm() * 2.5f, 0.0f, 1.0f);
          const Eigen::Vector3f c = sky_h + e * (sky_z - sky_h);
          row[3 * x] = static_cast<uint8_t>(c[0]);
          row[3 * x + 1] = static_cast<uint8_t>(c[1]);
          row[3 * x + 2] = static_cast<uint8_t>(c[2]);
        }
      }
    }
  });
}

const Renderer::DistortionMaps& Renderer::MapsFor(const camera::PinholeCamera& cam) const {
  const std::string key = fmt::format(
      "{}x{} {} {} {} {} {} {} {} {} {}", cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy,
      static_cast<int>(cam.distortion), cam.coeffs[0], cam.coeffs[1], cam.coeffs[2], cam.coeffs[3]);
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = maps_.find(key);
  if (it != maps_.end()) return it->second;
  // Undistorted positions (same focal lengths) of the image border, to size the wider render.
  double xmin = 0, xmax = cam.width - 1, ymin = 0, ymax = cam.height - 1;
  auto undist = [&](double px, double py) {
    const Eigen::Vector2d n = cam.PixelToNormalized({px, py});
    return Eigen::Vector2d(cam.fx * n.x() + cam.cx, cam.fy * n.y() + cam.cy);
  };
  for (int i = 0; i <= 64; ++i) {
    for (const Eigen::Vector2d& b : {Eigen::Vector2d(i * (cam.width - 1) / 64.0, 0),
                                     Eigen::Vector2d(i * (cam.width - 1) / 64.0, cam.height - 1),
                                     Eigen::Vector2d(0, i * (cam.height - 1) / 64.0),
                                     Eigen::Vector2d(cam.width - 1, i * (cam.height - 1) / 64.0)}) {
      const Eigen::Vector2d q = undist(b.x(), b.y());
      xmin = std::min(xmin, q.x());
      xmax = std::max(xmax, q.x());
      ymin = std::min(ymin, q.y());
      ymax = std::max(ymax, q.y());
    }
  }
  // Cap the margin: strongly distorted lenses would otherwise ask for huge renders.
  const double cap = 1.0 * std::max(cam.width, cam.height);
  xmin = std::max(xmin, -cap);
  ymin = std::max(ymin, -cap);
  xmax = std::min(xmax, cam.width - 1 + cap);
  ymax = std::min(ymax, cam.height - 1 + cap);
  DistortionMaps m;
  m.render = {static_cast<int>(std::ceil(xmax - xmin)) + 3,
              static_cast<int>(std::ceil(ymax - ymin)) + 3,
              cam.fx,
              cam.fy,
              cam.cx - std::floor(xmin) + 1,
              cam.cy - std::floor(ymin) + 1};
  m.map_x.create(cam.height, cam.width, CV_32F);
  m.map_y.create(cam.height, cam.width, CV_32F);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector2d n = cam.PixelToNormalized({double(x), double(y)});
      m.map_x.at<float>(y, x) = static_cast<float>(cam.fx * n.x() + m.render.cx);
      m.map_y.at<float>(y, x) = static_cast<float>(cam.fy * n.y() + m.render.cy);
    }
  }
  return maps_.emplace(key, std::move(m)).first->second;
}

void Renderer::Render(const camera::PinholeCamera& camera, const Rigid3d& world_from_cam,
                      cv::Mat* bgr, cv::Mat* depth) const {
  camera.Validate();
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  cv::Mat inv_depth;
  if (camera.distortion == camera::DistortionModel::kNone) {
    RenderPinhole({camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy},
                  cam_from_world, bgr, &inv_depth);
  } else {
    const DistortionMaps& m = MapsFor(camera);
    cv::Mat wide, wide_inv;
    RenderPinhole(m.render, cam_from_world, &wide, &wide_inv);
    cv::remap(wide, *bgr, m.map_x, m.map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    if (depth)
      cv::remap(wide_inv, inv_depth, m.map_x, m.map_y, cv::INTER_NEAREST, cv::BORDER_REPLICATE);
  }
  if (depth) {
    depth->create(bgr->size(), CV_32F);
    for (int y = 0; y < depth->rows; ++y) {
      const float* in = inv_depth.ptr<float>(y);
      float* out = depth->ptr<float>(y);
      for (int x = 0; x < depth->cols; ++x) {
        out[x] = in[x] > 0 ? 1.0f / in[x] : std::numeric_limits<float>::infinity();
      }
    }
  }
}

}  // namespace optinav::sim
