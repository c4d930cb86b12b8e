#include "optinav/report/geo_export.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "optinav/report/svg.h"

namespace optinav::report {

std::string ToGeoJson(const std::vector<GeoLine>& lines, const std::vector<GeoPoint>& points) {
  nlohmann::json features = nlohmann::json::array();
  // 1e-8 deg is about 1 mm: more digits only add noise.
  auto round8 = [](double v) { return std::round(v * 1e8) / 1e8; };
  for (const GeoLine& l : lines) {
    nlohmann::json coords = nlohmann::json::array();
    for (const geo::LatLon& p : l.points) coords.push_back({round8(p.lon_deg), round8(p.lat_deg)});
    nlohmann::json props = {{"name", l.name}, {"stroke", l.colour_hex}};
    for (const auto& [k, v] : l.properties) props[k] = v;
    features.push_back({{"type", "Feature"},
                        {"properties", props},
                        {"geometry", {{"type", "LineString"}, {"coordinates", coords}}}});
  }
  for (const GeoPoint& p : points) {
    features.push_back({{"type", "Feature"},
                        {"properties", {{"name", p.name}}},
                        {"geometry",
                         {{"type", "Point"},
                          {"coordinates", {round8(p.point.lon_deg), round8(p.point.lat_deg)}}}}});
  }
  return nlohmann::json({{"type", "FeatureCollection"}, {"features", features}}).dump(1) + "\n";
}

std::string ToKml(const std::string& document_name, const std::vector<GeoLine>& lines,
                  const std::vector<GeoPoint>& points) {
  std::string k =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n";
  k += fmt::format("<name>{}</name>\n", XmlEscape(document_name));
  for (size_t i = 0; i < lines.size(); ++i) {
    const GeoLine& l = lines[i];
    // KML colours are aabbggrr.
    const std::string hex = l.colour_hex.size() == 7 ? l.colour_hex.substr(1) : "ff0000";
    k += fmt::format(
        "<Style id=\"line{}\"><LineStyle><color>ff{}{}{}</color><width>3</width></LineStyle>"
        "</Style>\n",
        i, hex.substr(4, 2), hex.substr(2, 2), hex.substr(0, 2));
  }
  for (size_t i = 0; i < lines.size(); ++i) {
    const GeoLine& l = lines[i];
    k +=
        fmt::format("<Placemark><name>{}</name><styleUrl>#line{}</styleUrl>", XmlEscape(l.name), i);
    k += "<LineString><tessellate>1</tessellate><coordinates>";
    for (const geo::LatLon& p : l.points)
      k += fmt::format("{:.8f},{:.8f},0 ", p.lon_deg, p.lat_deg);
    k += "</coordinates></LineString></Placemark>\n";
  }
  for (const GeoPoint& p : points) {
    k += fmt::format(
        "<Placemark><name>{}</name><Point><coordinates>{:.8f},{:.8f},0</coordinates></Point>"
        "</Placemark>\n",
        XmlEscape(p.name), p.point.lon_deg, p.point.lat_deg);
  }
  k += "</Document>\n</kml>\n";
  return k;
}

}  // namespace optinav::report
