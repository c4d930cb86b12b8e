// Paths and points for GIS tools: GeoJSON (RFC 7946: [longitude, latitude]) and KML 2.2.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "optinav/geo/geo.h"

namespace optinav::report {

struct GeoLine {
  std::string name;
  std::vector<geo::LatLon> points;
  std::string colour_hex = "#ff0000";             // "#rrggbb"
  std::map<std::string, std::string> properties;  // extra string properties
};

struct GeoPoint {
  std::string name;
  geo::LatLon point;
};

std::string ToGeoJson(const std::vector<GeoLine>& lines, const std::vector<GeoPoint>& points);
std::string ToKml(const std::string& document_name, const std::vector<GeoLine>& lines,
                  const std::vector<GeoPoint>& points);

}  // namespace optinav::report
