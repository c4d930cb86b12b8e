#include "optinav/geo/geo.h"

#include <cmath>

#include <geodesic.h>
#include <proj.h>

namespace optinav::geo {
namespace {

constexpr double kWgs84A = 6378137.0;
constexpr double kWgs84F = 1.0 / 298.257223563;

const geod_geodesic& Wgs84() {
  static const geod_geodesic g = [] {
    geod_geodesic out;
    geod_init(&out, kWgs84A, kWgs84F);
    return out;
  }();
  return g;
}

std::string ProjError(PJ_CONTEXT* ctx) {
  // PROJ gives NULL when it failed without setting an error number (found by fuzz/geotiff: a
  // TIFF whose CRS PROJ cannot instantiate); a std::string from NULL would terminate.
  const char* text = proj_context_errno_string(ctx, proj_context_errno(ctx));
  return text != nullptr ? text : "no detail given";
}

}  // namespace

Eigen::Vector2d GeoTransform::PixelToCrs(const Eigen::Vector2d& p) const {
  return {c[0] + p.x() * c[1] + p.y() * c[2], c[3] + p.x() * c[4] + p.y() * c[5]};
}

Eigen::Vector2d GeoTransform::CrsToPixel(const Eigen::Vector2d& xy) const {
  const double det = c[1] * c[5] - c[2] * c[4];
  if (std::abs(det) < 1e-300) throw Error("singular geotransform");
  const double dx = xy.x() - c[0], dy = xy.y() - c[3];
  return {(c[5] * dx - c[2] * dy) / det, (-c[4] * dx + c[1] * dy) / det};
}

double GeoTransform::PixelDirectionToAzimuthDeg(const Eigen::Vector2d& d) const {
  const double east = c[1] * d.x() + c[2] * d.y();
  const double north = c[4] * d.x() + c[5] * d.y();
  const double h = std::atan2(east, north) * 180.0 / M_PI;
  return h < 0 ? h + 360.0 : h;
}

Eigen::Vector2d GeoTransform::AzimuthDegToPixelDirection(double azimuth_deg) const {
  const double a = azimuth_deg * M_PI / 180.0;
  const double east = std::sin(a), north = std::cos(a);
  const double det = c[1] * c[5] - c[2] * c[4];
  if (std::abs(det) < 1e-300) throw Error("singular geotransform");
  return Eigen::Vector2d((c[5] * east - c[2] * north) / det, (-c[4] * east + c[1] * north) / det)
      .normalized();
}

double GeoTransform::UnitsPerPixel() const {
  return std::sqrt(std::abs(c[1] * c[5] - c[2] * c[4]));
}

struct CrsTransform::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* pj = nullptr;  // crs -> EPSG:4326, normalised to (lon, lat) / (x, y) order
  ~Impl() {
    if (pj) proj_destroy(pj);
    if (ctx) proj_context_destroy(ctx);
  }
};

CrsTransform::CrsTransform(const std::string& crs) : impl_(std::make_unique<Impl>()) {
  impl_->ctx = proj_context_create();
  proj_log_level(impl_->ctx, PJ_LOG_NONE);
  PJ* src = proj_create(impl_->ctx, crs.c_str());
  if (!src) {
    throw Error("unknown CRS (PROJ: " + ProjError(impl_->ctx) + "): " + crs.substr(0, 80),
                {.field = "crs"});
  }
  const char* name = proj_get_name(src);
  name_ = name ? name : "?";
  const PJ_TYPE type = proj_get_type(src);
  geographic_ = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  PJ* dst = proj_create(impl_->ctx, "EPSG:4326");
  PJ* raw =
      src && dst ? proj_create_crs_to_crs_from_pj(impl_->ctx, src, dst, nullptr, nullptr) : nullptr;
  proj_destroy(src);
  proj_destroy(dst);
  if (!raw) {
    throw Error("no transformation from CRS '" + name_ +
                    "' to WGS 84 (PROJ: " + ProjError(impl_->ctx) + ")",
                {.field = "crs"});
  }
  // Axis order made explicit: input (easting, northing) or (lon, lat); output (lon, lat).
  impl_->pj = proj_normalize_for_visualization(impl_->ctx, raw);
  proj_destroy(raw);
  if (!impl_->pj) throw Error("cannot normalise axis order for CRS '" + name_ + "'");
}

CrsTransform::~CrsTransform() = default;
CrsTransform::CrsTransform(CrsTransform&&) noexcept = default;
CrsTransform& CrsTransform::operator=(CrsTransform&&) noexcept = default;

LatLon CrsTransform::ToLatLon(const Eigen::Vector2d& xy) const {
  const PJ_COORD out = proj_trans(impl_->pj, PJ_FWD, proj_coord(xy.x(), xy.y(), 0, 0));
  if (!std::isfinite(out.lp.lam) || !std::isfinite(out.lp.phi) || out.xy.x == HUGE_VAL) {
    throw Error("coordinate outside the domain of CRS '" + name_ + "'");
  }
  return {out.xy.y, out.xy.x};
}

Eigen::Vector2d CrsTransform::FromLatLon(const LatLon& ll) const {
  const PJ_COORD out = proj_trans(impl_->pj, PJ_INV, proj_coord(ll.lon_deg, ll.lat_deg, 0, 0));
  if (!std::isfinite(out.xy.x) || !std::isfinite(out.xy.y) || out.xy.x == HUGE_VAL) {
    throw Error("latitude/longitude outside the domain of CRS '" + name_ + "'");
  }
  return {out.xy.x, out.xy.y};
}

double CrsTransform::MetresPerUnit(const Eigen::Vector2d& xy) const {
  if (!geographic_) return 1.0;
  // One degree of latitude (y) in metres at this latitude; x scaled by cos(lat) is not a single
  // number, so the geometric mean of both axes is returned.
  const LatLon a{xy.y(), xy.x()};
  const double dn = GeodesicInverse(a, {a.lat_deg + 1e-3, a.lon_deg}).distance_m / 1e-3;
  const double de = GeodesicInverse(a, {a.lat_deg, a.lon_deg + 1e-3}).distance_m / 1e-3;
  return std::sqrt(dn * de);
}

GeodesicResult GeodesicInverse(const LatLon& a, const LatLon& b) {
  GeodesicResult r;
  geod_inverse(&Wgs84(), a.lat_deg, a.lon_deg, b.lat_deg, b.lon_deg, &r.distance_m, &r.azimuth1_deg,
               &r.azimuth2_deg);
  return r;
}

LatLon GeodesicDirect(const LatLon& a, double azimuth_deg, double distance_m) {
  LatLon out;
  geod_direct(&Wgs84(), a.lat_deg, a.lon_deg, azimuth_deg, distance_m, &out.lat_deg, &out.lon_deg,
              nullptr);
  return out;
}

struct LocalEnu::Impl {
  PJ_CONTEXT* ctx = nullptr;
  PJ* pj = nullptr;  // EPSG:4979 (lat, lon, h) -> EPSG:4978 (geocentric), normalised
  Eigen::Vector3d origin_ecef;
  Eigen::Matrix3d enu_from_ecef;
  ~Impl() {
    if (pj) proj_destroy(pj);
    if (ctx) proj_context_destroy(ctx);
  }
  Eigen::Vector3d ToEcef(const LatLon& ll, double h) const {
    const PJ_COORD c = proj_trans(pj, PJ_FWD, proj_coord(ll.lon_deg, ll.lat_deg, h, 0));
    return {c.xyz.x, c.xyz.y, c.xyz.z};
  }
};

LocalEnu::LocalEnu(const LatLon& origin, double height_m) : impl_(std::make_unique<Impl>()) {
  if (!(std::abs(origin.lat_deg) <= 90) || !(std::abs(origin.lon_deg) <= 360)) {
    throw Error("ENU origin outside valid latitude/longitude", {.field = "origin"});
  }
  impl_->ctx = proj_context_create();
  proj_log_level(impl_->ctx, PJ_LOG_NONE);
  PJ* raw = proj_create_crs_to_crs(impl_->ctx, "EPSG:4979", "EPSG:4978", nullptr);
  if (!raw) throw Error("PROJ cannot build WGS84 geodetic -> geocentric: " + ProjError(impl_->ctx));
  impl_->pj = proj_normalize_for_visualization(impl_->ctx, raw);
  proj_destroy(raw);
  impl_->origin_ecef = impl_->ToEcef(origin, height_m);
  const double lat = origin.lat_deg * M_PI / 180, lon = origin.lon_deg * M_PI / 180;
  // Rows: east, north, up unit vectors in ECEF.
  impl_->enu_from_ecef << -std::sin(lon), std::cos(lon), 0,                           //
      -std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat),  //
      std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat);
}

LocalEnu::~LocalEnu() = default;
LocalEnu::LocalEnu(LocalEnu&&) noexcept = default;

Eigen::Vector3d LocalEnu::ToEnu(const LatLon& ll, double h) const {
  return impl_->enu_from_ecef * (impl_->ToEcef(ll, h) - impl_->origin_ecef);
}

LatLon LocalEnu::FromEnu(const Eigen::Vector3d& enu, double* height_m) const {
  const Eigen::Vector3d ecef = impl_->origin_ecef + impl_->enu_from_ecef.transpose() * enu;
  const PJ_COORD c = proj_trans(impl_->pj, PJ_INV, proj_coord(ecef.x(), ecef.y(), ecef.z(), 0));
  if (height_m) *height_m = c.lpz.z;
  return {c.lpz.phi, c.lpz.lam};
}

}  // namespace optinav::geo
