#include "optinav/geo/geo.h"

#include <cmath>

#include <gtest/gtest.h>

#include "optinav/util/testing.h"

namespace optinav::geo {
namespace {

// Degrees-minutes-seconds as gdalinfo prints them.
double Dms(int d, int m, double s) { return d + m / 60.0 + s / 3600.0; }

TEST(CrsTransform, UtmCornersMatchGdalinfo) {
  // gdalinfo ../shared/data/geo/RGB.byte.tif (WGS 84 / UTM 18N):
  //   Upper Left  (101985.000, 2826915.000) ( 78d57'31.14"W, 25d30'21.91"N)
  //   Lower Right (339315.000, 2611485.000) ( 76d34'29.73"W, 23d36'21.41"N)
  const CrsTransform t("EPSG:32618");
  EXPECT_EQ(t.name(), "WGS 84 / UTM zone 18N");
  const LatLon ul = t.ToLatLon({101985.0, 2826915.0});
  EXPECT_NEAR(ul.lat_deg, Dms(25, 30, 21.91), 0.01 / 3600);
  EXPECT_NEAR(ul.lon_deg, -Dms(78, 57, 31.14), 0.01 / 3600);
  const LatLon lr = t.ToLatLon({339315.0, 2611485.0});
  EXPECT_NEAR(lr.lat_deg, Dms(23, 36, 21.41), 0.01 / 3600);
  EXPECT_NEAR(lr.lon_deg, -Dms(76, 34, 29.73), 0.01 / 3600);
  const Eigen::Vector2d back = t.FromLatLon(lr);
  EXPECT_LT((back - Eigen::Vector2d(339315.0, 2611485.0)).norm(), 1e-6);
}

TEST(CrsTransform, WebMercatorAndGeographicAxisOrder) {
  // EPSG:3857: x = R lon, y = R ln(tan(pi/4 + lat/2)), R = 6378137.
  const CrsTransform m("EPSG:3857");
  const LatLon ll{47.0, -99.0};
  const Eigen::Vector2d xy = m.FromLatLon(ll);
  const double r = 6378137.0;
  EXPECT_NEAR(xy.x(), r * ll.lon_deg * M_PI / 180, 1e-6);
  EXPECT_NEAR(xy.y(), r * std::log(std::tan(M_PI / 4 + ll.lat_deg * M_PI / 360)), 1e-6);
  // EPSG:4326 declares lat, lon axis order; our x stays longitude after normalisation.
  const CrsTransform g("EPSG:4326");
  EXPECT_TRUE(g.is_geographic());
  const LatLon back = g.ToLatLon({7.5, 53.0});
  EXPECT_DOUBLE_EQ(back.lat_deg, 53.0);
  EXPECT_DOUBLE_EQ(back.lon_deg, 7.5);
  EXPECT_NEAR(g.MetresPerUnit({7.5, 53.0}), 111.3e3 * std::sqrt(std::cos(53.0 * M_PI / 180)), 600);
}

TEST(CrsTransform, UnknownCrsIsAnError) {
  EXPECT_ERROR(CrsTransform("EPSG:999999"), {.field = "crs"}, "unknown CRS (PROJ: ");
  EXPECT_ERROR(CrsTransform("not a crs"), {.field = "crs"}, "): not a crs");
}

TEST(GeoTransform, RotationTermsRoundTrip) {
  GeoTransform g;
  g.c = {500000, 0.5, 0.1, 5200000, 0.08, -0.5};
  const Eigen::Vector2d px(123.25, 456.5);
  const Eigen::Vector2d xy = g.PixelToCrs(px);
  EXPECT_DOUBLE_EQ(xy.x(), 500000 + 123.25 * 0.5 + 456.5 * 0.1);
  EXPECT_LT((g.CrsToPixel(xy) - px).norm(), 1e-7);
  EXPECT_FALSE(g.IsNorthUp());
  EXPECT_NEAR(g.UnitsPerPixel(), std::sqrt(0.25 + 0.008), 1e-12);
  // Azimuths: for a north-up map, pixel up (-y) is north, +x is east.
  GeoTransform up;
  up.c = {0, 1, 0, 0, 0, -1};
  EXPECT_NEAR(up.PixelDirectionToAzimuthDeg({0, -1}), 0.0, 1e-12);
  EXPECT_NEAR(up.PixelDirectionToAzimuthDeg({1, 0}), 90.0, 1e-12);
  EXPECT_NEAR(up.PixelDirectionToAzimuthDeg({-1, 0}), 270.0, 1e-12);
  // With rotation terms the two directions are inverses of each other.
  const Eigen::Vector2d dir = g.AzimuthDegToPixelDirection(35.0);
  EXPECT_NEAR(g.PixelDirectionToAzimuthDeg(dir), 35.0, 1e-9);
  EXPECT_NEAR(dir.norm(), 1.0, 1e-12);
  GeoTransform singular;
  singular.c = {0, 1, 1, 0, 1, 1};
  EXPECT_ERROR(singular.CrsToPixel({1, 1}), {}, "singular geotransform");
}

TEST(Geodesic, KnownDistanceAndRoundTrip) {
  // Along a meridian, 1 degree of latitude at 45 deg N is 111,132 m (WGS84).
  const GeodesicResult r = GeodesicInverse({44.5, 10.0}, {45.5, 10.0});
  EXPECT_NEAR(r.distance_m, 111132.0, 5.0);
  EXPECT_NEAR(r.azimuth1_deg, 0.0, 1e-9);
  const LatLon b = GeodesicDirect({47.0, -99.0}, 35.0, 1234.5);
  const GeodesicResult back = GeodesicInverse({47.0, -99.0}, b);
  EXPECT_NEAR(back.distance_m, 1234.5, 1e-6);
  EXPECT_NEAR(back.azimuth1_deg, 35.0, 1e-9);
}

TEST(LocalEnu, AxesAndRoundTrip) {
  const LatLon origin{47.0, -99.0};
  // Geodesic distances are measured on the ellipsoid, so compare at height 0.
  const LocalEnu enu(origin, 0.0);
  EXPECT_LT(enu.ToEnu(origin, 0.0).norm(), 1e-6);
  const LatLon north = GeodesicDirect(origin, 0.0, 100.0);
  const Eigen::Vector3d n = enu.ToEnu(north, 0.0);
  EXPECT_NEAR(n.y(), 100.0, 1e-3);
  EXPECT_NEAR(n.x(), 0.0, 1e-6);
  EXPECT_LT(n.z(), 0.0);  // the ellipsoid curves away below the tangent plane
  const LatLon east = GeodesicDirect(origin, 90.0, 100.0);
  EXPECT_NEAR(enu.ToEnu(east, 0.0).x(), 100.0, 1e-3);
  EXPECT_NEAR(enu.ToEnu(origin, 10.0).z(), 10.0, 1e-6);
  double h = 0;
  const LatLon back = enu.FromEnu({120.0, -45.0, 7.0}, &h);
  EXPECT_LT((enu.ToEnu(back, h) - Eigen::Vector3d(120.0, -45.0, 7.0)).norm(), 1e-6);
}

}  // namespace
}  // namespace optinav::geo
