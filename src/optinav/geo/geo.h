// Georeferencing through GDAL and PROJ (no hand-rolled projections):
//  - GeoTransform: the GeoTIFF affine transform, rotation terms included, pixel <-> map CRS.
//    Pixel coordinates are continuous: (0, 0) is the top-left corner of the top-left pixel,
//    the centre of pixel (i, j) is (i + 0.5, j + 0.5), as in GDAL.
//  - CrsTransform: map CRS <-> WGS84 latitude/longitude in degrees, with explicit axis order
//    (the caller always passes and receives lat, lon; x = easting, y = northing).
//  - LocalEnu: WGS84 (lat, lon, ellipsoidal height) <-> east/north/up metres about an origin.
//  - Geodesic distance and azimuth on the WGS84 ellipsoid (PROJ's geodesic routines).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "optinav/util/error.h"

namespace optinav::geo {

struct LatLon {
  double lat_deg = 0, lon_deg = 0;
};

struct GeoTransform {
  // GDAL order: x = c[0] + px c[1] + py c[2]; y = c[3] + px c[4] + py c[5].
  std::array<double, 6> c{0, 1, 0, 0, 0, -1};

  Eigen::Vector2d PixelToCrs(const Eigen::Vector2d& px) const;
  // Throws Error if the transform is singular.
  Eigen::Vector2d CrsToPixel(const Eigen::Vector2d& xy) const;
  // Ground size of one pixel (sqrt of the area it covers), in CRS units.
  double UnitsPerPixel() const;
  bool IsNorthUp() const { return c[2] == 0 && c[4] == 0 && c[1] > 0 && c[5] < 0; }
  // Grid azimuth (deg clockwise from grid north, [0, 360)) of a direction in pixels, and the
  // unit pixel direction of a grid azimuth. Grid north differs from true north by the
  // meridian convergence of the projection (well under a degree near a UTM zone's centre).
  double PixelDirectionToAzimuthDeg(const Eigen::Vector2d& dir_px) const;
  Eigen::Vector2d AzimuthDegToPixelDirection(double azimuth_deg) const;
};

// Transforms between one CRS and WGS84 geographic coordinates. Not thread-safe: use one per
// thread (construction is cheap).
class CrsTransform {
 public:
  // `crs` may be WKT, "EPSG:n", or a PROJ string. Throws Error if PROJ does not know it.
  explicit CrsTransform(const std::string& crs);
  ~CrsTransform();
  CrsTransform(CrsTransform&&) noexcept;
  CrsTransform& operator=(CrsTransform&&) noexcept;

  LatLon ToLatLon(const Eigen::Vector2d& xy) const;
  Eigen::Vector2d FromLatLon(const LatLon& ll) const;
  // Name of the CRS as PROJ reports it, e.g. "WGS 84 / UTM zone 18N".
  const std::string& name() const { return name_; }
  // Metres per CRS unit along the axes (1 for projected metric CRSs; for geographic CRSs an
  // approximation at the given point).
  double MetresPerUnit(const Eigen::Vector2d& xy) const;
  bool is_geographic() const { return geographic_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string name_;
  bool geographic_ = false;
};

struct GeodesicResult {
  double distance_m = 0;
  double azimuth1_deg = 0;  // at the first point, clockwise from north
  double azimuth2_deg = 0;  // forward azimuth at the second point
};
GeodesicResult GeodesicInverse(const LatLon& a, const LatLon& b);
// The point at `distance_m` from `a` along `azimuth_deg`.
LatLon GeodesicDirect(const LatLon& a, double azimuth_deg, double distance_m);

// East-north-up frame about an origin on the WGS84 ellipsoid (via PROJ's geocentric CRS).
class LocalEnu {
 public:
  LocalEnu(const LatLon& origin, double height_m);
  ~LocalEnu();
  LocalEnu(LocalEnu&&) noexcept;
  Eigen::Vector3d ToEnu(const LatLon& ll, double height_m) const;
  // Returns lat/lon and writes the ellipsoidal height.
  LatLon FromEnu(const Eigen::Vector3d& enu, double* height_m = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace optinav::geo
