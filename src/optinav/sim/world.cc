#include "optinav/sim/world.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "optinav/geo/raster.h"
#include "optinav/geometry/angles.h"
#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

using Vec3 = Eigen::Vector3f;
using Vec2 = Eigen::Vector2f;

const Vec3 kSun = Vec3(0.45f, -0.35f, 0.82f).normalized();

class MeshBuilder {
 public:
  void Tri(const Vec3& a, const Vec3& b, const Vec3& c, const Vec2& ua, const Vec2& ub,
           const Vec2& uc, int tex, const Vec3& colour, bool two_sided = false) {
    WorldTriangle t;
    t.p[0] = a;
    t.p[1] = b;
    t.p[2] = c;
    t.uv[0] = ua;
    t.uv[1] = ub;
    t.uv[2] = uc;
    const Vec3 n = (b - a).cross(c - a);
    const float len = n.norm();
    if (len < 1e-9f) return;
    float d = n.dot(kSun) / len;
    d = two_sided ? std::abs(d) : std::max(0.0f, d);
    t.tint = colour * (0.5f + 0.55f * d);
    t.texture = static_cast<uint16_t>(tex);
    t.two_sided = two_sided;
    tris_.push_back(t);
  }
  // p0..p3 counter-clockwise seen from the front.
  void Quad(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, const Vec2& u0,
            const Vec2& u1, const Vec2& u2, const Vec2& u3, int tex, const Vec3& colour,
            bool two_sided = false) {
    Tri(p0, p1, p2, u0, u1, u2, tex, colour, two_sided);
    Tri(p0, p2, p3, u0, u2, u3, tex, colour, two_sided);
  }
  // A box standing on `base` (centre of its bottom face), rotated by yaw about z. Side
  // textures repeat every `side_repeat` metres (u along the wall, v down from the top).
  void Box(const Vec3& base, float length, float width, float height, float yaw, int side_tex,
           int top_tex, Vec2 side_repeat, const Vec3& colour, float top_repeat = 4,
           const std::array<Vec2, 4>* jitter = nullptr) {
    const float c = std::cos(yaw), s = std::sin(yaw);
    const Vec2 local[4] = {{-length / 2, -width / 2},
                           {length / 2, -width / 2},
                           {length / 2, width / 2},
                           {-length / 2, width / 2}};
    Vec3 b[4], t[4];
    for (int i = 0; i < 4; ++i) {
      const Vec2 l = local[i];
      b[i] = base + Vec3(c * l.x() - s * l.y(), s * l.x() + c * l.y(), 0);
      t[i] = b[i] + Vec3(0, 0, height);
      if (jitter) t[i] += Vec3((*jitter)[i].x(), (*jitter)[i].y(), 0);
    }
    float u = 0;
    for (int i = 0; i < 4; ++i) {
      const int j = (i + 1) % 4;
      const float len = (b[j] - b[i]).head<2>().norm();
      const float u0 = u / side_repeat.x(), u1 = (u + len) / side_repeat.x();
      const float vb = height / side_repeat.y();
      Quad(b[i], b[j], t[j], t[i], {u0, vb}, {u1, vb}, {u1, 0}, {u0, 0}, side_tex, colour);
      u += len;
    }
    Vec2 tu[4];
    for (int i = 0; i < 4; ++i) tu[i] = t[i].head<2>() / top_repeat;
    Quad(t[0], t[1], t[2], t[3], tu[0], tu[1], tu[2], tu[3], top_tex, colour);
  }
  void Tree(const Vec3& base, float height, float radius, int bark, int foliage, float yaw) {
    const float trunk = 0.35f * height;
    Box(base, 0.35f, 0.35f, trunk + 0.3f, yaw, bark, bark, {1.2f, 1.2f}, Vec3::Ones());
    const Vec3 bottom = base + Vec3(0, 0, trunk), top = base + Vec3(0, 0, height);
    const Vec3 mid = base + Vec3(0, 0, trunk + 0.4f * (height - trunk));
    constexpr int kSides = 6;
    Vec3 ring[kSides];
    for (int i = 0; i < kSides; ++i) {
      const float a = yaw + 2 * static_cast<float>(M_PI) * i / kSides;
      const float r = radius * (0.85f + 0.3f * ((i * 7 + static_cast<int>(yaw * 10)) % 5) / 4);
      ring[i] = mid + Vec3(r * std::cos(a), r * std::sin(a), 0);
    }
    for (int i = 0; i < kSides; ++i) {
      const int j = (i + 1) % kSides;
      const float u0 = i * radius / 1.5f, u1 = (i + 1) * radius / 1.5f;
      Tri(ring[i], ring[j], top, {u0, 1.5f}, {u1, 1.5f}, {(u0 + u1) / 2, 0}, foliage, Vec3::Ones());
      Tri(ring[j], ring[i], bottom, {u1, 1.5f}, {u0, 1.5f}, {(u0 + u1) / 2, 2.5f}, foliage,
          Vec3(0.8f, 0.8f, 0.8f));
    }
  }

  std::vector<WorldChunk> Chunks(float cell_m) const {
    std::map<std::pair<int, int>, WorldChunk> cells;
    for (const WorldTriangle& t : tris_) {
      const Vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3;
      WorldChunk& ch = cells[{static_cast<int>(std::floor(c.x() / cell_m)),
                              static_cast<int>(std::floor(c.y() / cell_m))}];
      for (const Vec3& p : t.p) ch.box.extend(p);
      ch.triangles.push_back(t);
    }
    std::vector<WorldChunk> out;
    for (auto& [key, ch] : cells) out.push_back(std::move(ch));
    return out;
  }

 private:
  std::vector<WorldTriangle> tris_;
};

class TextureSet {
 public:
  TextureSet(World* world, const WeatherSpec& weather, uint64_t seed)
      : world_(world), weather_(weather), seed_(seed) {}
  int Add(SurfaceKind kind, SurfaceRole role, uint64_t variant = 0) {
    const uint64_t s = seed_ * 1000003 + variant * 131 + static_cast<int>(kind);
    cv::Mat img = MakeSurfaceImage(kind, s);
    ApplySurfaceWeather(img, role, weather_, s);
    world_->textures.emplace_back(img);
    return static_cast<int>(world_->textures.size()) - 1;
  }
  // `count` variants of one surface that tile with each other along v (the image rows), and also
  // along u (the columns) when `both_axes`: each is the surface of seed variant 0 (as Add) at its
  // edges, blended within 6 % of the size into a surface of its own seed. A ribbon that picks a
  // variant per period of its v repeat, or a ground grid that picks one per cell, then shows no
  // exact repetition, and no seam.
  std::vector<int> AddVariants(SurfaceKind kind, SurfaceRole role, int count,
                               bool both_axes = false) {
    const uint64_t s0 = seed_ * 1000003 + static_cast<int>(kind);
    cv::Mat base = MakeSurfaceImage(kind, s0);
    ApplySurfaceWeather(base, role, weather_, s0);
    auto weight = [](int i, int n) {  // 0 at an edge, 1 from 6 % of n inwards
      const double edge = std::min(i + 0.5, n - i - 0.5) / n;
      const double t = std::clamp(edge / 0.06, 0.0, 1.0);
      return t * t * (3 - 2 * t);
    };
    std::vector<int> ids;
    for (int k = 0; k < count; ++k) {
      const uint64_t s = seed_ * 1000003 + (k + 1) * 7727 + static_cast<int>(kind);
      cv::Mat own = MakeSurfaceImage(kind, s);
      ApplySurfaceWeather(own, role, weather_, s);
      cv::Mat out = base.clone();
      const int n = out.rows;
      for (int y = 0; y < n; ++y) {
        const double wy = weight(y, n);
        if (!both_axes) {
          cv::addWeighted(base.row(y), 1 - wy, own.row(y), wy, 0, out.row(y));
          continue;
        }
        for (int x = 0; x < out.cols; ++x) {
          const double w = std::min(wy, weight(x, out.cols));
          const cv::Vec3b a = base.at<cv::Vec3b>(y, x), b = own.at<cv::Vec3b>(y, x);
          for (int c = 0; c < 3; ++c)
            out.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>((1 - w) * a[c] + w * b[c]);
        }
      }
      world_->textures.emplace_back(out);
      ids.push_back(static_cast<int>(world_->textures.size()) - 1);
    }
    return ids;
  }
  int AddImage(const cv::Mat& img, SurfaceRole role) {
    cv::Mat copy = img.clone();
    ApplySurfaceWeather(copy, role, weather_, seed_);
    world_->textures.emplace_back(copy);
    return static_cast<int>(world_->textures.size()) - 1;
  }

 private:
  World* world_;
  WeatherSpec weather_;
  uint64_t seed_;
};

struct RouteSample {
  Eigen::Vector2f p, left;  // position, unit left normal
  float s = 0;              // arc length
  float yaw = 0;
};

// The car route of a world, sampled about every 2 m.
std::vector<RouteSample> SampleRoute(const BodyTrajectory& traj) {
  std::vector<RouteSample> out;
  for (int64_t t = traj.start_ns(); t <= traj.end_ns(); t += 100'000'000) {
    const BodyState st = traj.At(t);
    const Eigen::Vector2f p = st.world_from_body.translation.head<2>().cast<float>();
    if (!out.empty() && (p - out.back().p).norm() < 2.0f) continue;
    const Eigen::Vector3d fwd = st.world_from_body.rotation * Eigen::Vector3d::UnitX();
    RouteSample r;
    r.p = p;
    r.yaw = static_cast<float>(std::atan2(fwd.y(), fwd.x()));
    r.left = Eigen::Vector2f(-std::sin(r.yaw), std::cos(r.yaw));
    r.s = out.empty() ? 0 : out.back().s + (p - out.back().p).norm();
    out.push_back(r);
  }
  return out;
}

// The first sample at or after arc length s (route.end() past the end).
std::vector<RouteSample>::const_iterator AtArcLength(const std::vector<RouteSample>& route,
                                                     float s) {
  return std::lower_bound(route.begin(), route.end(), s,
                          [](const RouteSample& r, float v) { return r.s < v; });
}

float DistanceToRoute(const std::vector<RouteSample>& route, const Eigen::Vector2f& p) {
  float best = 1e9f;
  for (size_t i = 1; i < route.size(); ++i) {
    const Eigen::Vector2f a = route[i - 1].p, b = route[i].p;
    const Eigen::Vector2f ab = b - a;
    const float t = std::clamp((p - a).dot(ab) / std::max(1e-6f, ab.squaredNorm()), 0.0f, 1.0f);
    best = std::min(best, (a + t * ab - p).norm());
  }
  return best;
}

Eigen::AlignedBox2f RouteBox(const std::vector<RouteSample>& route) {
  Eigen::AlignedBox2f box;
  for (const auto& r : route) box.extend(r.p);
  return box;
}

// A well-mixed hash of a seed and one or two integers (a texture variant per road period or
// ground cell).
uint64_t MixHash(uint64_t seed, int64_t a, int64_t b = 0) {
  uint64_t h = seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(a) * 0xBF58476D1CE4E5B9ull +
               static_cast<uint64_t>(b) * 0x94D049BB133111EBull;
  h ^= h >> 31;
  h *= 0x94D049BB133111EBull;
  h ^= h >> 29;
  return h;
}

// A ribbon between lateral offsets [a, b] (left positive) along the route, its texture repeating
// every `v_repeat` metres: with several `textures`, one per repeat, picked by a hash of `seed` and
// the repeat's index (quads are split where a repeat ends).
void Ribbon(MeshBuilder& mb, const std::vector<RouteSample>& route, float a, float b, float z,
            float v_repeat, const std::vector<int>& textures, uint64_t seed, const Vec3& colour) {
  if (textures.size() == 1) {  // one texture: whole quads between the route samples
    for (size_t i = 1; i < route.size(); ++i) {
      const RouteSample &r0 = route[i - 1], &r1 = route[i];
      auto at = [&](const RouteSample& r, float off) {
        const Eigen::Vector2f q = r.p + off * r.left;
        return Vec3(q.x(), q.y(), z);
      };
      const float v0 = r0.s / v_repeat, v1 = r1.s / v_repeat;
      // Right edge (offset a) to left edge (offset b); counter-clockwise seen from above.
      mb.Quad(at(r0, a), at(r1, a), at(r1, b), at(r0, b), {1, v0}, {1, v1}, {0, v1}, {0, v0},
              textures[0], colour);
    }
    return;
  }
  auto pick = [&](int64_t period) { return textures[MixHash(seed, period) % textures.size()]; };
  for (size_t i = 1; i < route.size(); ++i) {
    const RouteSample &r0 = route[i - 1], &r1 = route[i];
    const float v0 = r0.s / v_repeat, v1 = r1.s / v_repeat;
    if (!(v1 > v0)) continue;
    // The point at fraction f from r0 to r1, `off` to the left.
    auto at = [&](float f, float off) {
      const Eigen::Vector2f left = ((1 - f) * r0.left + f * r1.left).normalized();
      const Eigen::Vector2f q = (1 - f) * r0.p + f * r1.p + off * left;
      return Vec3(q.x(), q.y(), z);
    };
    for (float lo = v0; lo < v1;) {
      const float period = std::floor(lo);
      const float hi = std::min(v1, period + 1);
      const float fa = (lo - v0) / (v1 - v0), fb = (hi - v0) / (v1 - v0);
      const float ta = lo - period, tb = hi - period;
      // Right edge (offset a) to left edge (offset b); counter-clockwise seen from above.
      mb.Quad(at(fa, a), at(fb, a), at(fb, b), at(fa, b), {1, ta}, {1, tb}, {0, tb}, {0, ta},
              pick(static_cast<int64_t>(period)), colour);
      lo = hi;
    }
  }
}

void GroundTiles(MeshBuilder& mb, const Eigen::AlignedBox2f& box, float tile, float repeat, int tex,
                 const HeightFunction& h) {
  for (float x = box.min().x(); x < box.max().x(); x += tile) {
    for (float y = box.min().y(); y < box.max().y(); y += tile) {
      auto p = [&](float px, float py) { return Vec3(px, py, static_cast<float>(h(px, py))); };
      auto uv = [&](float px, float py) { return Vec2(px / repeat, -py / repeat); };
      mb.Quad(p(x, y), p(x + tile, y), p(x + tile, y + tile), p(x, y + tile), uv(x, y),
              uv(x + tile, y), uv(x + tile, y + tile), uv(x, y + tile), tex, Vec3::Ones());
    }
  }
}

}  // namespace

bool ParseAsphalt(const std::string& text, const std::string& field) {
  if (text != "tiled" && text != "varied")
    throw Error(fmt::format("unknown asphalt '{}' (tiled or varied)", text), {.field = field});
  return text == "varied";
}

const char* AsphaltName(bool varied) { return varied ? "varied" : "tiled"; }

namespace {

World MakeUrban(const WorldOptions& o) {
  World w;
  w.kind = WorldKind::kUrban;
  w.ground_height = [](double, double) { return 0.0; };
  TextureSet tx(&w, o.weather, o.seed);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<float> u01(0, 1);
  auto uni = [&](float a, float b) { return a + (b - a) * u01(rng); };
  // WorldOptions::varied_asphalt: 8 variants, one per 8 m of road. With one texture the road
  // repeats exactly every 8 m, and where fog or dust leave only the road visible, loops verified
  // against the wrong period (6-13 m off; docs/VIO.md, 2026-12-06 night).
  const std::vector<int> asphalt =
      o.varied_asphalt ? tx.AddVariants(SurfaceKind::kAsphalt, SurfaceRole::kRoad, 8)
                       : std::vector<int>{tx.Add(SurfaceKind::kAsphalt, SurfaceRole::kRoad)};
  const int sidewalk = tx.Add(SurfaceKind::kSidewalk, SurfaceRole::kRoad);
  const int grass = tx.Add(SurfaceKind::kGrass, SurfaceRole::kGround);
  std::vector<int> facades, cars;
  for (int i = 0; i < 6; ++i)
    facades.push_back(tx.Add(SurfaceKind::kFacade, SurfaceRole::kOther, i));
  for (int i = 0; i < 5; ++i) cars.push_back(tx.Add(SurfaceKind::kCarBody, SurfaceRole::kOther, i));
  const int roof = tx.Add(SurfaceKind::kRoof, SurfaceRole::kRoof);
  const int bark = tx.Add(SurfaceKind::kBark, SurfaceRole::kOther);
  const int foliage[2] = {tx.Add(SurfaceKind::kFoliage, SurfaceRole::kOther, 0),
                          tx.Add(SurfaceKind::kFoliage, SurfaceRole::kOther, 1)};
  const int metal = tx.Add(SurfaceKind::kRock, SurfaceRole::kOther);

  const BodyTrajectory car = MakeCarTrajectory(CarRouteOptions::Urban(), w.ground_height, 0);
  const auto route = SampleRoute(car);
  const Eigen::AlignedBox2f rbox = RouteBox(route);
  MeshBuilder mb;
  // Road 14 m wide: the car drives in the right lane, 3 m right of the centre line.
  Ribbon(mb, route, -4, 10, 0.02f, 8, asphalt, o.seed, Vec3::Ones());
  Ribbon(mb, route, -7, -4, 0.15f, 4, {sidewalk}, o.seed, Vec3::Ones());
  Ribbon(mb, route, 10, 13, 0.15f, 4, {sidewalk}, o.seed, Vec3::Ones());
  const Eigen::AlignedBox2f gbox(rbox.min() - Eigen::Vector2f(160, 160),
                                 rbox.max() + Eigen::Vector2f(160, 160));
  GroundTiles(mb, gbox, 40, 6, grass, w.ground_height);

  // Buildings along both sides, clear of the road and sidewalks of every leg.
  struct Placed {
    Eigen::Vector2f c;
    float r;
  };
  std::vector<Placed> placed;
  auto free_at = [&](const Eigen::Vector2f& c, float r, float clearance) {
    if (DistanceToRoute(route, c) < clearance + r) return false;
    for (const Placed& p : placed) {
      if ((p.c - c).norm() < p.r + r + 1.0f) return false;
    }
    return true;
  };
  for (int side : {1, -1}) {
    for (float s = 5; s < route.back().s; s += uni(16, 26)) {
      const auto it = AtArcLength(route, s);
      if (it == route.end()) break;
      if (u01(rng) < 0.12f) continue;
      const float depth = uni(10, 16), width = uni(11, 18);
      const float height = 3.0f * static_cast<int>(uni(2, 5.99f));
      const float front = side > 0 ? 15.0f : 9.0f;
      const Eigen::Vector2f c = it->p + side * (front + depth / 2) * it->left;
      const float r = 0.5f * std::hypot(depth, width);
      const float clearance = side > 0 ? 13.5f : 7.5f;
      if (!free_at(c, r * 0.8f, clearance - r * 0.2f)) continue;
      // Keep the footprint corners off the sidewalks.
      bool ok = true;
      const float cy = std::cos(it->yaw), sy = std::sin(it->yaw);
      for (float a : {-0.5f, 0.5f}) {
        for (float b : {-0.5f, 0.5f}) {
          const Eigen::Vector2f corner =
              c + Eigen::Vector2f(cy * a * width - sy * b * depth, sy * a * width + cy * b * depth);
          ok &= DistanceToRoute(route, corner) > 13.5f;
        }
      }
      if (!ok) continue;
      placed.push_back({c, r});
      const int f = facades[static_cast<size_t>(uni(0, 5.99f))];
      mb.Box({c.x(), c.y(), 0}, width, depth, height, it->yaw, f, roof, {3, 3}, Vec3::Ones());
    }
  }
  // Parked cars, street lights and street trees.
  for (float s = 20; s < route.back().s - 10; s += uni(7, 16)) {
    const auto it = AtArcLength(route, s);
    const auto ahead = AtArcLength(route, s + 8);
    if (ahead == route.end()) break;
    if (std::abs(WrapRadPi(ahead->yaw - it->yaw)) > 0.05) continue;  // corner
    if (u01(rng) < 0.45f) continue;
    const float off = u01(rng) < 0.5f ? -2.95f : 9.0f;
    const Eigen::Vector2f c = it->p + off * it->left;
    if (DistanceToRoute(route, c) < 2.5f) continue;
    const int tex = cars[static_cast<size_t>(uni(0, 4.99f))];
    mb.Box({c.x(), c.y(), 0.02f}, 4.4f, 1.8f, 1.45f, it->yaw, tex, tex, {4.4f, 1.45f}, Vec3::Ones(),
           4.4f);
  }
  for (float s = 10; s < route.back().s; s += 30) {
    const auto it = AtArcLength(route, s);
    if (it == route.end()) break;
    for (float off : {-5.6f, 11.6f}) {
      const Eigen::Vector2f c = it->p + off * it->left;
      if (DistanceToRoute(route, c) < std::abs(off) - 0.5f) continue;
      mb.Box({c.x(), c.y(), 0.15f}, 0.18f, 0.18f, 6.0f, it->yaw, metal, metal, {1, 2},
             Vec3(0.7f, 0.7f, 0.75f));
      const Eigen::Vector2f arm = c - (off > 0 ? 1.0f : -1.0f) * 0.9f * it->left;
      mb.Box({arm.x(), arm.y(), 5.9f}, 0.5f, 1.9f, 0.25f, it->yaw, metal, metal, {1, 1},
             Vec3(0.5f, 0.5f, 0.55f));
    }
    const auto mid = AtArcLength(route, s + 15);
    if (mid != route.end()) {
      const Eigen::Vector2f t2 = mid->p - 6.0f * mid->left;
      if (DistanceToRoute(route, t2) > 5.5f && free_at(t2, 1.5f, 0)) {
        mb.Tree({t2.x(), t2.y(), 0.15f}, uni(5, 8), uni(1.5f, 2.5f), bark, foliage[0], uni(0, 3));
      }
    }
  }
  // A park inside the loop and a forest ring around the block.
  const Eigen::AlignedBox2f inner(rbox.min() + Eigen::Vector2f(18, 18),
                                  rbox.max() - Eigen::Vector2f(18, 18));
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector2f p(uni(inner.min().x(), inner.max().x()),
                            uni(inner.min().y(), inner.max().y()));
    if (!free_at(p, 2.5f, 15.0f)) continue;
    placed.push_back({p, 2.5f});
    mb.Tree({p.x(), p.y(), 0}, uni(6, 11), uni(2, 3.5f), bark, foliage[i % 2], uni(0, 3));
  }
  const Eigen::AlignedBox2f ring_in(rbox.min() - Eigen::Vector2f(45, 45),
                                    rbox.max() + Eigen::Vector2f(45, 45));
  const Eigen::AlignedBox2f ring_out(rbox.min() - Eigen::Vector2f(90, 90),
                                     rbox.max() + Eigen::Vector2f(90, 90));
  for (int i = 0; i < 1400; ++i) {
    const Eigen::Vector2f p(uni(ring_out.min().x(), ring_out.max().x()),
                            uni(ring_out.min().y(), ring_out.max().y()));
    if (ring_in.contains(p)) continue;
    mb.Tree({p.x(), p.y(), 0}, uni(9, 16), uni(2.5f, 4), bark, foliage[i % 2], uni(0, 3));
  }
  w.chunks = mb.Chunks(32);
  w.area_min = (rbox.min() - Eigen::Vector2f(20, 20)).cast<double>();
  w.area_max = (rbox.max() + Eigen::Vector2f(20, 20)).cast<double>();
  return w;
}

float SmoothStep(float a, float b, float x) {
  const float t = std::clamp((x - a) / (b - a), 0.0f, 1.0f);
  return t * t * (3 - 2 * t);
}

World MakeTerrain(const WorldOptions& o) {
  World w;
  w.kind = WorldKind::kTerrain;
  TextureSet tx(&w, o.weather, o.seed);
  std::mt19937_64 rng(o.seed + 17);
  std::uniform_real_distribution<float> u01(0, 1);
  auto uni = [&](float a, float b) { return a + (b - a) * u01(rng); };
  // The ground's grass and soil in 8 variants each, one per 5 m cell, picked by a hash (since
  // 2026-12-07; the rendering marker's "ground"). With one texture each the ground repeated
  // exactly every 5 m, and where dust left only the ground within 15-20 m in view, the end of the
  // route verified 36 loops against its start 50 m away, whole periods off (docs/VIO.md).
  const std::vector<int> grass =
      tx.AddVariants(SurfaceKind::kGrass, SurfaceRole::kGround, 8, /*both_axes=*/true);
  const std::vector<int> soil =
      tx.AddVariants(SurfaceKind::kSoil, SurfaceRole::kGround, 8, /*both_axes=*/true);
  const int rock = tx.Add(SurfaceKind::kRock, SurfaceRole::kOther);
  const int bark = tx.Add(SurfaceKind::kBark, SurfaceRole::kOther);
  const int foliage = tx.Add(SurfaceKind::kFoliage, SurfaceRole::kOther);
  // The route's footprint does not depend on the ground height (the controller is planar).
  const auto flat_route = SampleRoute(MakeCarTrajectory(
      CarRouteOptions::Terrain(), [](double, double) { return 0.0; }, 0));
  const Eigen::AlignedBox2f rbox = RouteBox(flat_route);
  struct Hill {
    float x, y, amp, sigma;
  };
  std::vector<Hill> hills;
  for (int i = 0; i < 30; ++i) {
    hills.push_back({uni(rbox.min().x() - 60, rbox.max().x() + 60),
                     uni(rbox.min().y() - 60, rbox.max().y() + 60), uni(-6, 9), uni(18, 55)});
  }
  const Eigen::AlignedBox2f core(rbox.min() - Eigen::Vector2f(60, 60),
                                 rbox.max() + Eigen::Vector2f(60, 60));
  const float phase = uni(0, 6);
  w.ground_height = [hills, core, phase](double xd, double yd) {
    const float x = static_cast<float>(xd), y = static_cast<float>(yd);
    float h = 0.6f * std::sin(x / 7.3f + phase) * std::cos(y / 5.9f) +
              0.3f * std::sin(x / 3.1f - y / 4.3f);
    for (const Hill& k : hills) {
      const float d2 = (x - k.x) * (x - k.x) + (y - k.y) * (y - k.y);
      h += k.amp * std::exp(-d2 / (2 * k.sigma * k.sigma));
    }
    const float dx = std::max({core.min().x() - x, 0.0f, x - core.max().x()});
    const float dy = std::max({core.min().y() - y, 0.0f, y - core.max().y()});
    const float d = std::hypot(dx, dy);
    h += 75 * SmoothStep(0, 90, d) * (0.8f + 0.2f * std::sin(x / 23 + y / 31));
    return static_cast<double>(h);
  };
  const auto& h = w.ground_height;
  MeshBuilder mb;
  const float cell = 5;
  const Eigen::AlignedBox2f gbox(rbox.min() - Eigen::Vector2f(170, 170),
                                 rbox.max() + Eigen::Vector2f(170, 170));
  auto pick = [&](const std::vector<int>& textures, int64_t ix, int64_t iy) {
    return textures[MixHash(o.seed, ix, iy) % textures.size()];
  };
  for (float x = gbox.min().x(); x < gbox.max().x(); x += cell) {
    for (float y = gbox.min().y(); y < gbox.max().y(); y += cell) {
      auto p = [&](float px, float py) { return Vec3(px, py, static_cast<float>(h(px, py))); };
      // One whole texture per cell, v down the world's y as before.
      auto uv = [&](float px, float py) { return Vec2((px - x) / cell, (y + cell - py) / cell); };
      const float patch = std::sin(x / 17 + 1.3f * std::sin(y / 11)) + std::cos(y / 13 - x / 29);
      const float z = static_cast<float>(h(x, y));
      const auto ix = static_cast<int64_t>(std::floor(x / cell)),
                 iy = static_cast<int64_t>(std::floor(y / cell));
      const int tex = z > 30 ? rock : pick(patch > 0.4f ? soil : grass, ix, iy);
      mb.Quad(p(x, y), p(x + cell, y), p(x + cell, y + cell), p(x, y + cell), uv(x, y),
              uv(x + cell, y), uv(x + cell, y + cell), uv(x, y + cell), tex, Vec3::Ones());
    }
  }
  for (int i = 0; i < 160; ++i) {
    const Eigen::Vector2f c(uni(core.min().x(), core.max().x()),
                            uni(core.min().y(), core.max().y()));
    if (DistanceToRoute(flat_route, c) < 6) continue;
    const float s = uni(0.4f, 2.5f);
    std::array<Vec2, 4> jitter;
    for (auto& j : jitter) j = Vec2(uni(-0.3f, 0.3f), uni(-0.3f, 0.3f)) * s;
    mb.Box({c.x(), c.y(), static_cast<float>(h(c.x(), c.y())) - 0.2f}, s * uni(0.8f, 1.6f), s,
           s * uni(0.5f, 1.0f), uni(0, 3), rock, rock, {2, 2}, Vec3::Ones(), 2, &jitter);
  }
  for (int i = 0; i < 45; ++i) {
    const Eigen::Vector2f c(uni(core.min().x(), core.max().x()),
                            uni(core.min().y(), core.max().y()));
    if (DistanceToRoute(flat_route, c) < 8) continue;
    mb.Tree({c.x(), c.y(), static_cast<float>(h(c.x(), c.y()))}, uni(6, 12), uni(2, 3.5f), bark,
            foliage, uni(0, 3));
  }
  w.chunks = mb.Chunks(40);
  w.area_min = (rbox.min() - Eigen::Vector2f(20, 20)).cast<double>();
  w.area_max = (rbox.max() + Eigen::Vector2f(20, 20)).cast<double>();
  return w;
}

World MakeOrtho(const WorldOptions& o) {
  if (o.weather.kind == WeatherKind::kRoadWetness || o.weather.kind == WeatherKind::kRoadSnow ||
      o.weather.kind == WeatherKind::kRoadLeaves) {
    throw Error("road weather needs the urban world", {.field = "weather"});
  }
  std::optional<geo::GeoRaster> raster;
  try {
    raster.emplace(geo::GeoRaster::Open(o.ortho_path));
  } catch (const Error& e) {
    throw Error("orthophoto is not a readable, georeferenced GeoTIFF: " + e.message(),
                {.file = o.ortho_path, .field = "world"});
  }
  const geo::CrsTransform crs(raster->crs_wkt());
  const geo::GeoTransform& gt = raster->transform();
  const Eigen::Vector2d centre_px(raster->width() / 2.0, raster->height() / 2.0);
  World w;
  w.kind = WorldKind::kOrtho;
  w.origin = crs.ToLatLon(gt.PixelToCrs(centre_px));
  w.ground_height = [](double, double) { return 0.0; };
  const geo::LocalEnu enu(*w.origin, 0.0);
  const int tex_size = std::min(o.ortho_max_texture, std::max(raster->width(), raster->height()));
  const cv::Mat gray =
      raster->ReadGray(0, 0, raster->width(), raster->height(), tex_size, tex_size);
  cv::Mat bgr;
  cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
  TextureSet tx(&w, o.weather, o.seed);
  const int tex = tx.AddImage(bgr, SurfaceRole::kGround);
  // A 32 x 32 grid of quads, each vertex placed through the GeoTIFF transform, the CRS and ENU.
  constexpr int kGrid = 32;
  std::vector<Vec3> verts((kGrid + 1) * (kGrid + 1));
  Eigen::AlignedBox2d box;
  for (int j = 0; j <= kGrid; ++j) {
    for (int i = 0; i <= kGrid; ++i) {
      const Eigen::Vector2d px(raster->width() * i / double(kGrid),
                               raster->height() * j / double(kGrid));
      const Eigen::Vector3d e = enu.ToEnu(crs.ToLatLon(gt.PixelToCrs(px)), 0.0);
      verts[j * (kGrid + 1) + i] = Vec3(e.x(), e.y(), 0);
      box.extend(e.head<2>());
    }
  }
  MeshBuilder mb;
  for (int j = 0; j < kGrid; ++j) {
    for (int i = 0; i < kGrid; ++i) {
      auto v = [&](int a, int b) { return verts[b * (kGrid + 1) + a]; };
      auto uv = [&](int a, int b) { return Vec2(a / float(kGrid), b / float(kGrid)); };
      // Image rows go south, so (i, j+1) -> (i+1, j+1) -> (i+1, j) -> (i, j) is counter-clockwise
      // seen from above for a north-up raster; draw both sides to accept any orientation.
      mb.Quad(v(i, j + 1), v(i + 1, j + 1), v(i + 1, j), v(i, j), uv(i, j + 1), uv(i + 1, j + 1),
              uv(i + 1, j), uv(i, j), tex, Vec3(1.25f, 1.25f, 1.25f), true);
    }
  }
  w.chunks = mb.Chunks(std::max(50.0, box.sizes().maxCoeff() / 16));
  const Eigen::Vector2d margin = 0.1 * box.sizes();
  w.area_min = box.min() + margin;
  w.area_max = box.max() - margin;
  return w;
}

}  // namespace

size_t World::TriangleCount() const {
  size_t n = 0;
  for (const auto& c : chunks) n += c.triangles.size();
  return n;
}

WorldOptions ParseWorld(const std::string& text) {
  WorldOptions o;
  if (text == "urban") {
    o.kind = WorldKind::kUrban;
  } else if (text == "terrain") {
    o.kind = WorldKind::kTerrain;
  } else if (text.rfind("ortho:", 0) == 0 && text.size() > 6) {
    o.kind = WorldKind::kOrtho;
    o.ortho_path = text.substr(6);
  } else if (text == "ortho") {
    throw Error("the ortho world needs its GeoTIFF: --world ortho:PATH.tif", {.field = "world"});
  } else {
    throw Error(fmt::format("unknown world '{}' (urban, terrain or ortho:PATH.tif)", text),
                {.field = "world"});
  }
  return o;
}

World MakeWorld(const WorldOptions& options) {
  const bool road = options.weather.kind == WeatherKind::kRoadWetness ||
                    options.weather.kind == WeatherKind::kRoadSnow ||
                    options.weather.kind == WeatherKind::kRoadLeaves;
  if (road && options.kind != WorldKind::kUrban) {
    throw Error(
        fmt::format("'{}' needs the urban world (only it has roads)", options.weather.ToString()),
        {.field = "weather"});
  }
  switch (options.kind) {
    case WorldKind::kUrban:
      return MakeUrban(options);
    case WorldKind::kTerrain:
      return MakeTerrain(options);
    case WorldKind::kOrtho:
      return MakeOrtho(options);
  }
  return {};
}

}  // namespace optinav::sim
